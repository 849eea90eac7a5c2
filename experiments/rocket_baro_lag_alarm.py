"""What the barometer lag diagnose names on a clean simulated flight absorbs: the
first round of `diagnose` (its base fit, every candidate scored against the log's
own bootstrap threshold) on variants of one RocketPy flight that change one thing
each: the exact standard-atmosphere pressure instead of RocketPy's table, 50 Hz
instead of 20 Hz, half the noise.

`python experiments/rocket_baro_lag_alarm.py FOLDER [FOLDER ...]`: each FOLDER one
flight as `scripts/make_rocket_fixtures.py` writes it (the variants: its `flight`
function with the spec changed). Prints per flight the barometer lag's and the
static-pressure error's statistic, the threshold, the one-step estimates, and the
base fit's altitude residual; writes experiments/results/rocket_baro_lag_alarm.json.
"""

import json
import pathlib
import sys
import time

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))


def first_round(problem, **options):
    """The diagnosis's first round on `problem`: the base fit (single shooting, the
    thrust scale held at 1, nothing else freed; `options` passed to `fit_rocket`)
    and the candidates it holds, `(base, held parameter names)`."""
    import diffpegasus.rocket as dr
    from diffpegasus._rocket import _diagnose

    single = float(problem.record.t[-1] - problem.record.t[0]) + 1.0
    base = dr.fit_rocket(
        problem,
        free=(),
        hold=("thrust_scale",),
        start={"thrust_scale": 1.0},
        shooting_interval=single,
        throw=False,
        **options,
    )
    pool = [_diagnose.THRUST] + _diagnose.candidates(problem, float(np.max(base.mach)))
    model = base.fit.model
    held = [
        c.parameters[0]
        for c in pool
        if not model.free[model.parameters.index(c.parameters[0])]
    ]
    return base, held


def main():
    from rocket_validation import sim_log

    import diffpegasus.rocket as dr
    from diffpegasus._diagnose._candidates import score_candidates

    path = ROOT / "experiments" / "results" / "rocket_baro_lag_alarm.json"
    results = json.loads(path.read_text()) if path.exists() else {}
    for folder in map(pathlib.Path, sys.argv[1:]):
        t0 = time.perf_counter()
        problem = dr.prepare(dr.read_rocket(folder / "rocket.toml"), sim_log(folder))
        base, held = first_round(problem)
        ranking = score_candidates(base.fit, held, 0.01)
        rows = {
            r["parameter"]: {
                "statistic": float(r["statistic"]),
                "threshold": float(r["threshold"]),
                "estimate": float(r["estimate"]),
                "significant": bool(r["significant"]),
            }
            for r in ranking
        }
        has = problem.record.inputs[:, 1] > 0
        resid = problem.record.measured[has, 0] - base.fit.outputs[0][has, 0]
        results[folder.name] = {
            "det_r": float(base.fit.cost),
            "altitude_rms_m": float(np.sqrt(np.mean(resid**2))),
            "candidates": rows,
            "seconds": time.perf_counter() - t0,
        }
        for name in ("baro_lag", "static_error"):
            r = rows[name]
            print(
                f"{folder.name} {name}: {r['statistic']:.1f} / {r['threshold']:.1f} "
                f"estimate {r['estimate']:+.4g}"
                + (" NAMED" if r["significant"] else ""),
                flush=True,
            )
        print(
            f"{folder.name}: det(R) {base.fit.cost:.4g}, altitude RMS "
            f"{results[folder.name]['altitude_rms_m']:.2f} m "
            f"({results[folder.name]['seconds']:.0f} s)",
            flush=True,
        )
        path.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
