"""Each flight's fit as `rocket fit` runs it (`fit_rocket`'s defaults, the sensors'
spread), written to a JSON to compare code versions on: the estimates, their
coloured-residual standard errors, det(R), the result, power-off CD and its band at
seven Mach numbers from 0.1 to the flight's top, the apogee and the tries.

`python experiments/rocket_fit_estimates.py OUT.json [ROCKET_TOML ...]`: by default
the six real flights (shared data) and the two committed RocketPy flights.
`--compare A.json B.json`: which flights are the same to the bit in both, and how
far each positive effect's estimate lies from 0 in standard errors.
"""

import json
import pathlib
import sys
import time

import numpy as np
from _shared import shared_data


ROOT = pathlib.Path(__file__).resolve().parents[1]
REAL = ("camoes", "hedy", "prometheus_2022", "ndrt_2020", "andromeda", "cavour")
POSITIVE = ("burn_scale", "thrust_scale", "cd_scale", "accel_scale", "temperature")


def one(toml):
    import diffpegasus as dp
    import diffpegasus.rocket as dr

    t0 = time.perf_counter()
    rocket = dr.read_rocket(toml)
    problem = dr.prepare(rocket, dp.read_rocket_log(toml))
    r = dr.fit_rocket(problem, throw=False)
    mach = np.linspace(0.1, float(np.max(r.mach)), 7)
    cd, se = r.cd(mach)
    return dict(
        names=list(r.fit.model.parameters),
        params=r.fit.params.tolist(),
        stderr=r.fit.stderr_corrected.tolist(),
        cost=float(r.fit.cost),
        converged=bool(r.fit.converged),
        reason=r.fit.reason,
        cd=cd.tolist(),
        cd_se=se.tolist(),
        apogee=r.apogee,
        tries={k: list(v) for k, v in r.tries.items()},
        seconds=time.perf_counter() - t0,
    )


def compare(a, b):
    for name, x in a.items():
        y = b.get(name)
        if y is None:
            continue
        keys = ("params", "stderr", "cd", "cd_se", "cost")
        same = all(np.array_equal(x[k], y[k]) for k in keys)
        print(f"{name}: {'the same to the bit' if same else 'different'}")
        for k in POSITIVE:
            i = x["names"].index(k)
            v, s = x["params"][i], x["stderr"][i]
            if s > 0:
                print(f"  {k} {v:.4g} +/- {s:.2g}: {v / s:.0f} standard errors from 0")


def main():
    args = sys.argv[1:]
    if args[0] == "--compare":
        a, b = (json.loads(pathlib.Path(p).read_text()) for p in args[1:3])
        compare(a, b)
        return
    out = pathlib.Path(args[0])
    tomls = args[1:] or [
        *(shared_data(f"rockets/{n}") / "rocket.toml" for n in REAL),
        *(
            ROOT / "tests/data/rocket_sim" / n / "rocket.toml"
            for n in ("clean", "planted")
        ),
    ]
    res = {}
    for toml in map(pathlib.Path, tomls):
        res[toml.parent.name] = one(toml)
        print(toml.parent.name, f"{res[toml.parent.name]['seconds']:.0f} s", flush=True)
        out.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
