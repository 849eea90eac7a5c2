"""A fit whose optimum lies past a bound: RocketPy's clean flight with its
accelerometer's sign flipped and the accelerometer's scale estimated (its optimum
near -1, past the bound at 0), single shooting from the problem's start, the day's
air held. Prints where the fit stopped, its result (`nonfinite`, the line saying
which effect stopped against its bound) and the estimates.

`python experiments/rocket_bound_stop.py`
"""

import dataclasses
import pathlib
import time

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]


def main():
    import diffpegasus as dp
    import diffpegasus.rocket as dr

    toml = ROOT / "tests/data/rocket_sim/clean/rocket.toml"
    problem = dr.prepare(dr.read_rocket(toml), dp.read_rocket_log(toml))
    rec = problem.record
    measured = rec.measured.copy()
    measured[:, 1] *= -1
    flipped = dataclasses.replace(
        problem,
        record=type(rec)(rec.t, rec.inputs, measured, x0=rec.x0, name=rec.name),
    )
    t0 = time.perf_counter()
    r = dr.fit_rocket(
        flipped,
        free=dr.default_free(flipped) + ("accel_scale",),
        shooting_interval=float(rec.t[-1] - rec.t[0]) + 1.0,
        spread=False,
        throw=False,
        hold_temperature=True,
    )
    print(f"{time.perf_counter() - t0:.0f} s")
    print(f"converged {r.fit.converged} ({r.fit.reason!r}), det(R) {r.fit.cost:.4g}")
    for name in ("accel_scale", "thrust_scale", "burn_scale", "accel_bias"):
        value, stderr = r.estimate(name)
        print(f"{name} {value:.3g} +/- {stderr:.2g}")
    finite = all(np.all(np.isfinite(o)) for o in r.fit.outputs)
    print(f"outputs finite {finite}, apogee {r.apogee:.1f} m")


if __name__ == "__main__":
    main()
