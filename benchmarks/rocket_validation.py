"""Rocket identification on flights of an independent 6-DOF simulator (RocketPy,
committed under tests/data/rocket_sim by scripts/make_rocket_fixtures.py): is the
planted CD(Mach) inside its 95% band, and which effects does diagnose name?

Writes benchmarks/results/rocket_validation.json (or `--out NAME`.json). Run:
`python benchmarks/rocket_validation.py [--attitude] [--no-diagnose] [--flights DIR] [--free a,b]
[--out NAME]`: `--flights` a folder of such flights (`python
scripts/make_rocket_fixtures.py --validation DIR` writes more), `--free` the effects
estimated besides the drag and thrust (default the fit's, `default_free`).
"""

import json
import pathlib
import sys
import time
import tomllib
import types

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
SIM = ROOT / "tests" / "data" / "rocket_sim"


def sim_log(folder):
    a = np.loadtxt(folder / "log.csv", delimiter=",", skiprows=1)

    def channel(j):
        return types.SimpleNamespace(t=a[:, 0], values=a[:, j], filtered=False)

    return types.SimpleNamespace(
        channels={"altitude": channel(1), "accel_axial": channel(2)},
        events={
            "liftoff": types.SimpleNamespace(t=0.0),
            "apogee": types.SimpleNamespace(t=float(a[-1, 0])),
        },
        pad={},
    )


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
        result = dr.fit_rocket(problem, free=free, start=flat, throw=False)
        seconds = time.perf_counter() - t0
        mach_true, cd_true = rocket.team_drag_off
        top = float(np.max(result.mach))
        mach = np.linspace(0.15, 0.95 * top, 20)
        cd, sd = result.cd(mach)
        planted = np.interp(mach, mach_true, cd_true)
        inside = np.abs(cd - planted) <= 1.96 * sd
        row = {
            "fit_seconds": seconds,
            "converged": bool(result.fit.converged),
            "mach": mach.tolist(),
            "cd": cd.tolist(),
            "stderr": sd.tolist(),
            "planted": planted.tolist(),
            "inside_95": int(inside.sum()),
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
            {k: row[k] for k in ("inside_95", "points", "thrust_scale", "fit_seconds")},
            row.get("named"),
            flush=True,
        )
        # written after every flight: a run stopped early keeps what it measured
        write(out, option("--out", "rocket_validation"))
    print("coverage", out["coverage"])


def write(out, name):
    rows = [r for r in out.values() if isinstance(r, dict)]
    total = sum(r["inside_95"] for r in rows)
    points = sum(r["points"] for r in rows)
    out["coverage"] = total / points
    path = ROOT / "benchmarks" / "results" / f"{name}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
