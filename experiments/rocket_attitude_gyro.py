"""The normal-force slope and pitch damping from the gyros: each simulated flight
with a gyro column (`scripts/make_rocket_fixtures.py --gyro DIR`) fitted with the
attitude, the CN-alpha and pitch-damping scales estimated (RocketPy flies
Barrowman's slopes, ours to 1e-5, and takes each surface's angle of attack with the
rotation, as the model does: both scales 1), once with the gyros and once without
(the same log, the gyro column dropped: the scales from the weathercocking the
altitude and the axial accelerometer show). Prints and writes JSON: each scale with
its 95% band (1.96 coloured-residual standard errors), whether it covers 1, the fit
time and the planted drag's coverage.

Run: `python experiments/rocket_attitude_gyro.py OUT.json FOLDER [FOLDER ...]`.
"""

import json
import pathlib
import sys
import time

import numpy as np


def sim_log(folder, gyro=True):
    """A simulated flight read through its `rocket.toml`'s `[log]` (as
    scripts/make_rocket_fixtures.py writes it), its lateral gyro dropped unless
    `gyro`."""
    import dataclasses

    from diffpegasus import read_rocket_log

    log = read_rocket_log(folder / "rocket.toml")
    if gyro:
        return log
    kept = {k: c for k, c in log.channels.items() if k != "gyro_lateral"}
    return dataclasses.replace(log, channels=kept)


def one(folder, gyro):
    import diffpegasus.rocket as dr
    from diffpegasus._rocket._identify import default_free, GYRO_FREE

    rocket = dr.read_rocket(folder / "rocket.toml", attitude=True)
    problem = dr.prepare(rocket, sim_log(folder, gyro))
    free = tuple(dict.fromkeys(default_free(problem) + GYRO_FREE))
    t0 = time.perf_counter()
    r = dr.fit_rocket(problem, free=free, throw=False)
    seconds = time.perf_counter() - t0
    out = {"outputs": list(problem.outputs), "seconds": seconds}
    out["converged"] = bool(r.fit.converged)
    out["iterations"] = int(r.fit.iterations)
    out["tries"] = {k: list(v) for k, v in r.tries.items()}
    for name in GYRO_FREE + ("wind_along", "thrust_scale"):
        v, s = r.estimate(name)
        out[name] = [v, 1.96 * s]
    for name in GYRO_FREE:
        v, b = out[name]
        out[name + "_covers_1"] = bool(abs(v - 1.0) <= b)
    m, cd = dr.read_drag_curve(folder / "drag.csv")
    grid = np.linspace(0.1, 0.9 * r.knots.mach[-1], 20)
    est, sd = r.cd(grid)
    z = (est - np.interp(grid, m, cd)) / sd
    out["cd_inside"] = int(np.sum(np.abs(z) <= 1.96))
    out["cd_worst_z"] = float(z[np.argmax(np.abs(z))])
    if "gyro" in problem.outputs:
        has = problem.record.inputs[:, 3] > 0
        e = problem.record.measured[has, 2] - r.fit.outputs[0][has, 2]
        out["gyro_rms"] = float(np.sqrt(np.mean(e**2)))
    return out


def main():
    path = pathlib.Path(sys.argv[1])
    results = json.loads(path.read_text()) if path.exists() else {}
    for folder in map(pathlib.Path, sys.argv[2:]):
        for gyro in (True, False):
            key = f"{folder.name} {'gyros' if gyro else 'no gyros'}"
            results[key] = one(folder, gyro)
            print(key, json.dumps(results[key]), flush=True)
            path.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
