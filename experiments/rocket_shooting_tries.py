"""Which of `fit_rocket`'s tries reaches the lowest det(R) on RocketPy flights, and
the CD(Mach) band coverage from each: the multiple-shooting continuation (nodes
every 2 s), single shooting from its best fit, and the single-shooting
continuation from the same flat start.

`python experiments/rocket_shooting_tries.py FOLDER [FOLDER ...]`: each FOLDER one
flight as `scripts/make_rocket_fixtures.py` writes it. Prints, per flight and try,
det(R), whether it converged, the planted CD inside the 95% band (of 20 Mach points
from 0.15 to 0.95 of the top, as benchmarks/rocket_validation.py counts them), the
wind along the rail and the try's seconds; writes
experiments/results/rocket_shooting_tries.json.
"""

import json
import pathlib
import sys
import time

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))


def main():
    from rocket_validation import sim_log

    import diffpegasus.rocket as dr
    from diffpegasus._rocket import _identify

    seen, seconds = {}, []
    tries, fit = _identify._tries, _identify.fit

    def timed_fit(*a, **k):
        t0 = time.perf_counter()
        out = fit(*a, **k)
        seconds.append(time.perf_counter() - t0)
        return out

    def kept_tries(*a, **k):
        seconds.clear()
        out = tries(*a, **k)
        (seen["tries"], seen["flown"]), seen["seconds"] = out, list(seconds)
        return out

    _identify._tries, _identify.fit = kept_tries, timed_fit
    path = ROOT / "experiments" / "results" / "rocket_shooting_tries.json"
    results = json.loads(path.read_text()) if path.exists() else {}
    for folder in map(pathlib.Path, sys.argv[1:]):
        rocket = dr.read_rocket(folder / "rocket.toml")
        problem = dr.prepare(rocket, sim_log(folder))
        flat = {n: 0.5 for n in problem.flight.knots.names}
        t0 = time.perf_counter()
        kept = dr.fit_rocket(problem, start=flat, throw=False)
        total = time.perf_counter() - t0
        mach_true, cd_true = rocket.team_drag_off
        rows = {}
        for label, f in seen["tries"].items():
            r = _identify.trajectory(
                problem.rocket, problem.flight, f, problem.record, problem.outputs
            )
            mach = np.linspace(0.15, 0.95 * float(np.max(r.mach)), 20)
            cd, sd = r.cd(mach)
            inside = int(
                np.sum(np.abs(cd - np.interp(mach, mach_true, cd_true)) <= 1.96 * sd)
            )
            rows[label] = {
                "cost": float(f.cost),
                # det(R) of its parameters flown from the pad: what the fit compares
                "flown_cost": float(seen["flown"][label]),
                "converged": bool(f.converged),
                "inside_95": inside,
                "half_width_pct": float(np.mean(1.96 * sd / cd) * 100),
                "wind_along": r.estimate("wind_along"),
                "kept": f is kept.fit,
            }
            print(
                f"{folder.name} {label}: det(R) {f.cost:.4g} converged "
                f"{f.converged} inside {inside} of 20, band +/-"
                f"{rows[label]['half_width_pct']:.1f}%, wind "
                f"{rows[label]['wind_along'][0]:+.1f} +/- "
                f"{rows[label]['wind_along'][1]:.1f}"
                + (" KEPT" if rows[label]["kept"] else ""),
                flush=True,
            )
        results[folder.name] = {
            "tries": rows,
            "fit_seconds": seen["seconds"],
            "total_seconds": total,
        }
        print(f"{folder.name}: {total:.0f} s, fits {np.round(seen['seconds'])}")
        path.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
