"""One RocketPy flight fitted as benchmarks/rocket_validation.py fits it with
`--start-from` (single shooting from an earlier run's estimates, the sensors'
spread on), read two ways and with the burn's length free or held at 1: which of
the changes since that run moves the fit, the reader or the burn scale?

`python experiments/rocket_reread_start.py FOLDER WAY[,WAY ...] [START_JSON
[START_WAY]]`: FOLDER one flight as `scripts/make_rocket_fixtures.py` writes it;
each WAY `toml` (read through its `rocket.toml` by the public reader: the stated
liftoff and apogee, as the benchmark reads it now) or `csv` (its `log.csv` alone,
the events searched for in the data, as the benchmark read it before), then
`-free` (the burn's length estimated, as the fit does now) or `-held` (held at 1:
the fit without the burn scale). The start is the flight's estimates in
benchmarks/results/rocket_validation_table.json, or in START_JSON: a run of the
benchmark (the flight's estimates; NAME then ends in the JSON's name) or this
script's output (START_WAY's estimates; NAME then ends `_from_START_WAY`), the
burn's length left out. Prints per way the
record's span, the planted CD inside the noise's 95% band and the band with the
sensors' spread (of 20 Mach points from 0.15 to 0.95 of the top, as the benchmark
counts them), each band's mean half-width in % of CD, det(R), the wind's
correlations and the estimates; writes experiments/results/rocket_reread_NAME.json
(NAME the flight's folder, then `_` and START_JSON's name or `_from_START_WAY`
as above). A flight not in the table (a held-out one) needs START_JSON.
"""

import json
import pathlib
import sys
import time

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]


def main():
    import diffpegasus as dp
    import diffpegasus.rocket as dr
    from diffpegasus._log._rocketlogs import read_rocket_log

    folder = pathlib.Path(sys.argv[1])
    ways = sys.argv[2].split(",")
    name = folder.name
    if len(sys.argv) <= 3:
        table = ROOT / "benchmarks" / "results" / "rocket_validation_table.json"
        kept = json.loads(table.read_text()).get(folder.name)
        if kept is None:
            sys.exit(f"{folder.name} is not in {table.name}: give START_JSON")
        start = {n: v for n, (v, _) in kept["estimates"].items()}
    else:
        earlier = json.loads(pathlib.Path(sys.argv[3]).read_text())
        way = sys.argv[4] if len(sys.argv) > 4 else folder.name
        start = {
            n: v for n, (v, _) in earlier[way]["estimates"].items() if n != "burn_scale"
        }
        name += f"_{pathlib.Path(sys.argv[3]).stem}" if way == folder.name else ""
        name += f"_from_{way}" if way != folder.name else ""
    rocket = dr.read_rocket(folder / "rocket.toml")
    mach_true, cd_true = rocket.team_drag_off
    out = {}
    for way in ways:
        reader, burn = way.split("-")
        if reader == "toml":
            log = dp.read_rocket_log(folder / "rocket.toml")
        else:
            log = read_rocket_log(folder / "log.csv")
        problem = dr.prepare(rocket, log)
        hold = ("burn_scale",) if burn == "held" else ()
        values = dict(start, burn_scale=1.0) if hold else dict(start)
        single = float(problem.record.t[-1] - problem.record.t[0]) + 1.0
        t0 = time.perf_counter()
        r = dr.fit_rocket(
            problem,
            start=values,
            shooting_interval=single,
            hold=hold,
            throw=False,
            spread=True,
        )
        seconds = time.perf_counter() - t0
        mach = np.linspace(0.15, 0.95 * float(np.max(r.mach)), 20)
        cd, sd = r.cd(mach, structural=False)
        _, sd_all = r.cd(mach)
        planted = np.interp(mach, mach_true, cd_true)
        names = list(r.fit.model.parameters)
        free = [n for n, f in zip(names, r.fit.model.free, strict=True) if f]
        i = names.index("wind_along")
        order = np.argsort(-np.abs(r.fit.correlation[i]))
        row = {
            "record_s": [float(problem.record.t[0]), float(problem.record.t[-1])],
            "samples": len(problem.record.t),
            "inside_95": int((np.abs(cd - planted) <= 1.96 * sd).sum()),
            "inside_95_structural": int((np.abs(cd - planted) <= 1.96 * sd_all).sum()),
            "half_width_pct": float(np.mean(196.0 * sd / cd)),
            "half_width_structural_pct": float(np.mean(196.0 * sd_all / cd)),
            "cost": float(r.fit.cost),
            "converged": bool(r.fit.converged),
            "iterations": int(r.fit.iterations),
            "fit_seconds": seconds,
            "wind_correlation": {
                names[j]: float(r.fit.correlation[i, j])
                for j in order[1:7]
                if names[j] in free
            },
            "estimates": {
                n: [float(v), float(e)]
                for n, v, e, f in zip(
                    names,
                    r.fit.params,
                    r.fit.stderr_corrected,
                    r.fit.model.free,
                    strict=True,
                )
                if f
            },
        }
        out[way] = row
        shown = {k: v for k, v in row.items() if k not in ("estimates",)}
        print(way, shown, flush=True)
        print(
            "   ",
            {
                k: f"{v:+.4g} +/- {e:.3g}"
                for k, (v, e) in row["estimates"].items()
                if not k.startswith("cd_")
            },
            flush=True,
        )
        path = ROOT / "experiments" / "results" / f"rocket_reread_{name}.json"
        path.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
