"""The lower-tail scaling of least squares' degrees of freedom on the tests' Monte
Carlo regression (two regressors, first-order autoregressive noise correlated over
10 samples, 600 samples, 200 records) under short memories: the coverage of the
95% bands at the end of the record with the scaling and without it (the count
left at Satterthwaite's), per memory and seed.

Run: `python experiments/recursive_tail_toy.py`; prints one line per memory and
seed and the JSON summary last.
"""

import json
import pathlib
import sys

import jax
import jax.numpy as jnp
import numpy as np


sys.path.insert(0, str(pathlib.Path(__file__).parents[1] / "tests"))
import test_recursive as tr  # noqa: E402

import diffpegasus as dp  # noqa: E402
from diffpegasus._estimate import _recursive as rc  # noqa: E402


jax.config.update("jax_enable_x64", True)


def main(memories=(100.0, 150.0), seeds=(11, 12), flights=200, n=600):
    t = np.arange(n) * tr.DT
    hh = np.stack([np.sin(1.3 * t) + 0.3, np.cos(2.9 * t)], axis=1)
    truth = np.array([1.5, -0.7])
    scaled = rc.RecursiveLeastSquares._tail_ratio
    out = []
    for memory in memories:
        for seed in seeds:
            rng = np.random.default_rng(seed)
            y = hh @ truth + tr._ar1(rng, n, np.exp(-0.1), 0.1, flights)
            row = {"memory_samples": memory, "seed": seed}
            for label, tail in (("without", False), ("with", True)):
                rc.RecursiveLeastSquares._tail_ratio = (
                    scaled if tail else (lambda self, s, pm, j: jnp.ones_like(s.theta))
                )
                jax.clear_caches()  # the replay is compiled per estimator
                est = dp.RecursiveLeastSquares(
                    forgetting=float(np.exp(-1.0 / memory)),
                    derivative=(False,),
                    dt=tr.DT,
                    levels=8,
                )
                res = tr._replay_flights(est, hh, y)
                err = np.abs(np.asarray(res.theta[:, 0]) - truth)
                cover = np.mean(err <= np.asarray(res.halfwidth[:, 0]), axis=0)
                row[f"coverage_{label}_scaling"] = cover.tolist()
                row[f"dof_mean_{label}_scaling"] = (
                    np.asarray(res.dof[:, 0]).mean(0).tolist()
                )
            rc.RecursiveLeastSquares._tail_ratio = scaled
            print(row, flush=True)
            out.append(row)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
