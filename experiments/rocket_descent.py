"""The descent under parachutes in the rocket fit: each stage's drag area and
whether the record past apogee tells a barometer lag from a barometer error that
depends on height.

Per flight: the fit with the descent (`prepare(..., descent=True)`), its CdS per
stage with standard errors against the rocket file's, the fall rates, and the
diagnosis's first round (every candidate against the log's own bootstrap
threshold) with and without the descent: the barometer lag's statistic,
threshold and estimate.

`python experiments/rocket_descent.py FOLDER_OR_TOML [...] [--no-diagnose]
[--hold-open] [--free-open-drogue]`: a folder holds a simulated flight (rocket.toml whose `[log]` names
log.csv with time, barometric altitude, axial specific force, and states
RocketPy's events; scripts/make_rocket_fixtures.py --descent), a rocket.toml path
a real flight (the shared rockets layout), and
`table:FOLDER:LAG` the model's own flight of a folder's rocket read through
RocketPy's atmosphere-table error by height with a lag of LAG s
([`table_flight`][]). Writes
experiments/results/rocket_descent.json (or `--out=PATH`; merged by flight) and a figure per
flight in docs/rockets/descent/ (the docs show three).
"""

import json
import pathlib
import sys
import time
import types

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / "experiments" / "results"


def load(arg):
    import diffpegasus as dp
    import diffpegasus.rocket as dr

    path = pathlib.Path(arg)
    toml = path / "rocket.toml" if path.is_dir() else path
    return toml.parent.name, dr.read_rocket(toml), dp.read_rocket_log(toml)


def lag_row(rows):
    r = next(q for q in rows if q["candidate"] == "barometer lag")
    return {
        "statistic": r["statistic"],
        "threshold": r["threshold"],
        "estimate_s": r["estimates"]["baro_lag"],
    }


def table_flight(folder, lag=0.0, seed=11):
    """The model's own flight of `folder`'s rocket (its drag curve, catalogue
    thrust; no wind, no sensor effect but `lag` s) through the descent under the
    rocket file's parachutes, its barometer reading RocketPy's atmosphere-table
    error by height (tests/data/rocket_baro/table_error.csv, as
    tests/test_rocket_baro.py's ascent), 1 m of noise on it and 0.5 m/s^2 on the
    accelerometer (ascent only): `(rocket, log)`."""
    import jax
    import jax.numpy as jnp

    import diffpegasus.rocket as dr
    from diffpegasus._estimate._fit import simulate
    from diffpegasus._vehicle._rocket._model import observe

    _, rocket, log = load(folder)
    problem = dr.prepare(rocket, log, descent=True)
    start = dict(problem.start, thrust_scale=1.0, motor_time=0.0, baro_lag=lag)
    model = dr.rocket_model(problem.flight, problem.outputs, start, ())
    rec = problem.record
    x = np.asarray(simulate(model, rec))
    y = np.asarray(
        jax.vmap(lambda t, xi: observe(problem.flight, t, xi, jnp.ones(3), start))(
            rec.t, jnp.asarray(x)
        )
    )
    table = np.loadtxt(
        ROOT / "tests" / "data" / "rocket_baro" / "table_error.csv",
        delimiter=",",
        skiprows=1,
    )
    rng = np.random.default_rng(seed)
    keep = rec.t >= 0.0
    n = int(keep.sum())
    baro = y[keep, 0] + np.interp(x[keep, 2], table[:, 0], table[:, 1])
    baro = baro + rng.normal(0.0, 1.0, n)
    accel = y[keep, 1] + rng.normal(0.0, 0.5, n)
    t = rec.t[keep]

    def channel(v):
        return types.SimpleNamespace(t=t, values=v, filtered=False)

    ev = {
        "liftoff": types.SimpleNamespace(t=0.0),
        "drogue": types.SimpleNamespace(t=problem.flight.descent.deploy[0]),
    }
    if len(problem.flight.descent.deploy) > 1:
        ev["main"] = types.SimpleNamespace(t=problem.flight.descent.deploy[1])
    return rocket, types.SimpleNamespace(
        channels={"altitude": channel(baro), "accel_axial": channel(accel)},
        events=ev,
        pad={},
    )


def main():
    import diffpegasus.rocket as dr
    from diffpegasus._rocket._descent_report import descent_figure, descent_table

    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    outs = [a.removeprefix("--out=") for a in sys.argv if a.startswith("--out=")]
    path = pathlib.Path(outs[0]) if outs else OUT / "rocket_descent.json"
    out = json.loads(path.read_text()) if path.exists() else {}
    figs = ROOT / "docs" / "rockets" / "descent"
    figs.mkdir(exist_ok=True)
    for arg in args:
        if arg.startswith("table:"):  # table:FOLDER:LAG
            _, folder, lag = arg.split(":")
            rocket, log = table_flight(pathlib.Path(folder), float(lag))
            name = f"table-{pathlib.Path(folder).name}-lag{lag}"
        else:
            name, rocket, log = load(arg)
        name += "-held" if "--hold-open" in sys.argv else ""
        name += "-drogue-free" if "--free-open-drogue" in sys.argv else ""
        row = {}
        t0 = time.process_time()
        problem = dr.prepare(rocket, log, descent=True)
        hold = ("open_main",) if "--hold-open" in sys.argv else ()
        free = dr.default_free(problem)
        if "--free-open-drogue" in sys.argv:
            free += ("open_drogue",)
        fit = dr.fit_rocket(problem, free=free, throw=False, spread=False, hold=hold)
        row["fit_cpu_s"] = time.process_time() - t0
        row["converged"] = bool(fit.fit.converged)
        row["stages"] = descent_table(problem, fit)
        row["record_s"] = float(problem.record.t[-1])
        row["free"] = list(dr.default_free(problem))
        row["baro_lag_fit_s"] = list(fit.estimate("baro_lag"))
        if "open_drogue" in free:
            row["open_drogue_fit_s"] = list(fit.estimate("open_drogue"))
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
        if "--no-diagnose" in sys.argv:  # an earlier run's diagnosis kept, marked
            earlier = {k: v for k, v in out.get(name, {}).items() if "diagnose" in k}
            if earlier:
                row.update(earlier, diagnose_from_an_earlier_run=True)
        out[name] = row
        path.write_text(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
