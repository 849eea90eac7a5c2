"""The descent under parachutes in the rocket fit: each stage's drag area and
whether the record past apogee tells a barometer lag from a barometer error that
depends on height.

Per flight: the fit with the descent (`prepare(..., descent=True)`), its CdS per
stage with standard errors against the rocket file's, the fall rates, and the
diagnosis's first round (every candidate against the log's own bootstrap
threshold) with and without the descent: the barometer lag's statistic,
threshold and estimate.

`python experiments/rocket_descent.py FOLDER_OR_TOML [...] [--no-diagnose]`: a
folder holds a simulated flight (rocket.toml, log.csv with time, barometric
altitude, axial specific force; scripts/make_rocket_fixtures.py --descent), a
rocket.toml path a real flight (/work/shared/data/rockets layout). Writes
experiments/results/rocket_descent.json (merged by flight) and a figure per
flight in experiments/results/rocket_descent/.
"""

import json
import pathlib
import sys
import time
import types

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / "experiments" / "results"


def simulated_log(folder):
    """A simulated flight's log.csv as a rocket log (no events but liftoff: the
    apogee is the barometer's highest sample)."""
    a = np.loadtxt(folder / "log.csv", delimiter=",", skiprows=1)

    def channel(j):
        return types.SimpleNamespace(t=a[:, 0], values=a[:, j], filtered=False)

    return types.SimpleNamespace(
        channels={"altitude": channel(1), "accel_axial": channel(2)},
        events={"liftoff": types.SimpleNamespace(t=0.0)},
        pad={},
    )


def load(arg):
    import diffpegasus.rocket as dr
    from diffpegasus._log._rocketlogs import read_rocket_log

    path = pathlib.Path(arg)
    if path.is_dir():
        return path.name, dr.read_rocket(path / "rocket.toml"), simulated_log(path)
    return path.parent.name, dr.read_rocket(path), read_rocket_log(path)


def lag_row(rows):
    r = next(q for q in rows if q["candidate"] == "barometer lag")
    return {
        "statistic": r["statistic"],
        "threshold": r["threshold"],
        "estimate_s": r["estimates"]["baro_lag"],
    }


def main():
    import diffpegasus.rocket as dr
    from diffpegasus._rocket._descent import descent_figure, descent_table

    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    path = OUT / "rocket_descent.json"
    out = json.loads(path.read_text()) if path.exists() else {}
    figs = OUT / "rocket_descent"
    figs.mkdir(exist_ok=True)
    for arg in args:
        name, rocket, log = load(arg)
        row = {}
        t0 = time.process_time()
        problem = dr.prepare(rocket, log, descent=True)
        fit = dr.fit_rocket(problem, throw=False, spread=False)
        row["fit_cpu_s"] = time.process_time() - t0
        row["converged"] = bool(fit.fit.converged)
        row["stages"] = descent_table(problem, fit)
        row["record_s"] = float(problem.record.t[-1])
        row["free"] = list(dr.default_free(problem))
        row["baro_lag_fit_s"] = list(fit.estimate("baro_lag"))
        descent_figure(problem, fit, figs / f"{name}.png")
        print(name, json.dumps(row["stages"], indent=0), flush=True)
        if "--no-diagnose" not in sys.argv:
            for label, desc in (("ascent", False), ("descent", True)):
                t0 = time.process_time()
                p = dr.prepare(rocket, log, descent=desc)
                named, rows, _ = dr.diagnose(p, rounds=1)
                row[f"diagnose_{label}"] = {
                    "named": named,
                    "barometer_lag": lag_row(rows),
                    "rows": rows,
                    "cpu_s": time.process_time() - t0,
                }
                print(name, label, named, lag_row(rows), flush=True)
        out[name] = row
        path.write_text(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
