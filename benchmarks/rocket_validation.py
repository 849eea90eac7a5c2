"""Rocket identification on flights of an independent 6-DOF simulator (RocketPy,
committed under tests/data/rocket_sim by scripts/make_rocket_fixtures.py): is the
planted CD(Mach) inside its 95% band, and which effects does diagnose name?

Writes benchmarks/results/rocket_validation.json (or `--out NAME`.json). Run:
`python benchmarks/rocket_validation.py [--attitude] [--no-diagnose] [--flights DIR] [--free a,b]
[--start-from JSON] [--out NAME]`: `--flights` a folder of such flights (`python
scripts/make_rocket_fixtures.py --validation DIR` writes more), `--free` the effects
estimated besides the drag and thrust (default the fit's, `default_free`),
`--start-from` an earlier run's JSON whose estimates start single shooting alone
(the optimum that run kept, reached again without its multiple-shooting tries).

Each flight is counted twice: `inside_95` with the band of the noise alone (the
coloured-residual standard errors), `inside_95_structural` with the between-sensor
variance added (`RocketFit.spread`); `half_width_pct` is the mean 95% half-width
over the points in % of the fitted CD, for each.
"""

import json
import pathlib
import sys
import time
import tomllib

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
SIM = ROOT / "tests" / "data" / "rocket_sim"


def sim_log(folder):
    """The flight's log read through its `rocket.toml` by the public reader, as the
    tests read it: the `[log]` column map and `[log.stated_events]` (RocketPy's
    time zero, the motor's ignition, is the log's liftoff; its last row the
    apogee)."""
    import diffpegasus as dp

    return dp.read_rocket_log(pathlib.Path(folder) / "rocket.toml")


def main():
    import diffpegasus.rocket as dr

    args = sys.argv[1:]

    def option(name, default):
        return args[args.index(name) + 1] if name in args else default

    do_diagnose = "--no-diagnose" not in args
    flights = pathlib.Path(option("--flights", SIM))
    free = option("--free", None)
    free = None if free is None else tuple(f for f in free.split(",") if f)
    out = {}
    for folder in sorted(p for p in flights.iterdir() if p.is_dir()):
        truth = tomllib.loads((folder / "rocket.toml").read_text())["truth"]
        rocket = dr.read_rocket(folder / "rocket.toml", attitude="--attitude" in args)
        log = sim_log(folder)
        t0 = time.perf_counter()
        problem = dr.prepare(rocket, log)
        # the start curve must not be the truth: a flat 0.5
        flat = {n: 0.5 for n in problem.flight.knots.names}
        before = option("--start-from", None)
        if before is None:
            result = dr.fit_rocket(
                problem, free=free, start=flat, throw=False, spread=True
            )
        else:
            kept = json.loads(pathlib.Path(before).read_text())[folder.name]
            warm = {n: v for n, (v, _) in kept["estimates"].items()}
            single = float(problem.record.t[-1] - problem.record.t[0]) + 1.0
            result = dr.fit_rocket(
                problem,
                free=free,
                start=warm,
                shooting_interval=single,
                throw=False,
                spread=True,
            )
        seconds = time.perf_counter() - t0
        mach_true, cd_true = rocket.team_drag_off
        top = float(np.max(result.mach))
        mach = np.linspace(0.15, 0.95 * top, 20)
        cd, sd = result.cd(mach, structural=False)
        _, sd_all = result.cd(mach)
        planted = np.interp(mach, mach_true, cd_true)
        inside = np.abs(cd - planted) <= 1.96 * sd
        inside_all = np.abs(cd - planted) <= 1.96 * sd_all
        spread = result.spread
        row = {
            "fit_seconds": seconds,
            "converged": bool(result.fit.converged),
            "mach": mach.tolist(),
            "cd": cd.tolist(),
            "stderr": sd.tolist(),
            "planted": planted.tolist(),
            "inside_95": int(inside.sum()),
            "inside_95_structural": int(inside_all.sum()),
            "stderr_structural": sd_all.tolist(),
            "half_width_pct": float(np.mean(196.0 * sd / cd)),
            "half_width_structural_pct": float(np.mean(196.0 * sd_all / cd)),
            "tau": None if spread is None else spread.tau.tolist(),
            "birge": None if spread is None else spread.birge,
            "sensor_fitted": None
            if spread is None or spread.fitted is None
            else dict(zip(spread.outputs, spread.fitted.tolist(), strict=True)),
            "sensor_converged": None
            if spread is None or spread.converged is None
            else spread.converged.tolist(),
            "sensor_knots": None
            if spread is None
            else dict(zip(spread.outputs, spread.knots.tolist(), strict=True)),
            "sensor_stderr": None
            if spread is None
            else dict(
                zip(
                    spread.outputs,
                    np.sqrt(np.diagonal(spread.covariances, axis1=1, axis2=2)).tolist(),
                    strict=True,
                )
            ),
            "knots_mach": list(result.knots.mach),
            # what any other rule for the band can be recomputed from
            "weights": result.knots.weights(mach).tolist(),
            "sensor_cov": None if spread is None else spread.covariances.tolist(),
            "joint_knots": knot_values(result).tolist(),
            "joint_cov": result.knot_covariance().tolist(),
            "points": len(mach),
            "thrust_scale": result.estimate("thrust_scale"),
            "thrust_scale_planted": truth["thrust_scale"],
            "estimates": {
                n: [float(v), float(e)]
                for n, v, e, f in zip(
                    result.fit.model.parameters,
                    result.fit.params,
                    result.fit.stderr_corrected,
                    result.fit.model.free,
                    strict=True,
                )
                if f
            },
            "cost": float(result.fit.cost),
            "apogee_reconstructed_m": result.apogee,
            "apogee_log_m": float(np.max(log.channels["altitude"].values)),
        }
        if do_diagnose:
            named, tests, _ = dr.diagnose(problem)
            row["named"] = named
            row["tests"] = tests
        row["planted_effects"] = {k: v for k, v in truth.items()}
        # the part of the planted wind a zero-angle-of-attack flight shows to first
        # order: along the rail's heading (see the model's wind_along)
        head = np.radians(rocket.heading)
        row["planted_effects"]["wind_along_m_s"] = truth.get(
            "wind_east_m_s", 0.0
        ) * np.sin(head) + truth.get("wind_north_m_s", 0.0) * np.cos(head)
        out[folder.name] = row
        print(
            folder.name,
            {
                k: row[k]
                for k in (
                    "inside_95",
                    "inside_95_structural",
                    "points",
                    "half_width_pct",
                    "half_width_structural_pct",
                    "birge",
                    "fit_seconds",
                )
            },
            row.get("named"),
            flush=True,
        )
        # written after every flight: a run stopped early keeps what it measured
        write(out, option("--out", "rocket_validation"))
    print(
        "coverage",
        out["coverage"],
        "with the sensors' spread",
        out["coverage_structural"],
    )


def knot_values(result):
    names = list(result.fit.model.parameters)
    scale = result.fit.params[names.index("cd_scale")]
    return (
        np.array([result.fit.params[names.index(k)] for k in result.knots.names])
        * scale
    )


def write(out, name):
    rows = [r for r in out.values() if isinstance(r, dict)]
    points = sum(r["points"] for r in rows)
    out["coverage"] = sum(r["inside_95"] for r in rows) / points
    out["coverage_structural"] = sum(r["inside_95_structural"] for r in rows) / points
    path = ROOT / "benchmarks" / "results" / f"{name}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
