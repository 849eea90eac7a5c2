"""How far the barometer's and the accelerometer's own estimates of a simulated
flight's parameters disagree, beyond their coloured-residual covariances: the
measures a structural-error band could be built from, at the fit
`benchmarks/rocket_validation.py --start-from` reaches.

Run: `python experiments/rocket_sensor_spread.py JSON FOLDER [FOLDER ...]` (JSON an
earlier run of that benchmark whose estimates start the fit). Prints, per flight,
the Birge ratio of the two sensors over the drag knots and over every free
parameter, and the Hausman statistic of the joint fit against the accelerometer's.
"""

import json
import pathlib
import sys

import numpy as np


sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))
from rocket_validation import sim_log  # noqa: E402


def main():
    import diffpegasus.rocket as dr
    from diffpegasus._rocket._spread import sensor_estimates

    before = json.loads(pathlib.Path(sys.argv[1]).read_text())
    for folder in map(pathlib.Path, sys.argv[2:]):
        rocket = dr.read_rocket(folder / "rocket.toml")
        problem = dr.prepare(rocket, sim_log(folder))
        warm = {n: v for n, (v, _) in before[folder.name]["estimates"].items()}
        single = float(problem.record.t[-1] - problem.record.t[0]) + 1.0
        res = dr.fit_rocket(
            problem, start=warm, shooting_interval=single, throw=False, spread=False
        )
        fit = res.fit
        names = [n for n, f in zip(fit.model.parameters, fit.free, strict=True) if f]
        x, c = sensor_estimates(fit, tuple(names))
        joint = np.array([fit.params[fit.model.parameters.index(n)] for n in names])
        cj = fit.covariance_of(names)
        k = [names.index(n) for n in res.knots.names]
        d = x[0] - x[1]
        v = c[0] + c[1]
        vi = np.linalg.pinv(v, rcond=1e-10, hermitian=True)
        rank = np.linalg.matrix_rank(v, tol=1e-10 * np.abs(v).max())
        print(folder.name, "full-vector chi2", float(d @ vi @ d), "rank", rank)
        dk = d[k]
        vk = v[np.ix_(k, k)]
        print(" knots chi2", float(dk @ np.linalg.pinv(vk) @ dk), "of", len(k))
        # Hausman: joint (efficient) against the accelerometer alone
        h = joint - x[1]
        vh = c[1] - cj
        w, u = np.linalg.eigh(vh[np.ix_(k, k)])
        keep = w > 1e-12 * w.max()
        proj = u[:, keep].T @ h[k]
        print(" hausman knots", float(np.sum(proj**2 / w[keep])), "dof", keep.sum())
        for n, a, b, j, s, sa, sb in zip(
            names,
            x[0],
            x[1],
            joint,
            np.sqrt(np.diag(cj)),
            np.sqrt(np.diag(c[0])),
            np.sqrt(np.diag(c[1])),
            strict=True,
        ):
            print(
                f"  {n:16s} joint {j:+.4g}±{s:.2g}  baro {a:+.4g}±{sa:.2g}  accel {b:+.4g}±{sb:.2g}"
            )


if __name__ == "__main__":
    main()
