"""GNSS position as an output of the rocket fit (docs/rockets/simulated.md, GNSS
position).

`fly`: RocketPy flights written as a user would (the outsider sweep's `fly_one`:
barometric altitude and axial accelerometer, no column map, no stated events) with
two more columns, a GNSS receiver's latitude and longitude (`write_gnss`: RocketPy's
own, with white noise, empty rows between fixes): clean and with a cross wind,
at 5 Hz with 2 m of noise and at 1 Hz with 3 m.

`run`: each flight (or real flight folder with a `rocket.toml`) fitted and
diagnosed without and with the GNSS position (`prepare(..., gnss=...)`): CD at
the knots with its band (against the planted curve on the simulated flights), the
apogee, the wind estimates, the fit's seconds, what diagnose names and the wind
candidates' statistics. Writes experiments/results/rocket_gnss_simulated.json
(`run`) and rocket_gnss_real.json (`real`).

    python experiments/rocket_gnss.py fly DIR [NAME ...]       # RocketPy's venv
    python experiments/rocket_gnss.py run DIR NAME ... [--no-diagnose] [--with]
    python experiments/rocket_gnss.py real NAME ...            # shared data
    python experiments/rocket_gnss.py table [real]
"""

import json
import pathlib
import sys
import time

import numpy as np
from _shared import shared_data


ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "experiments" / "results"
REAL = RESULTS / "rocket_gnss_real.json"
SIMULATED = RESULTS / "rocket_gnss_simulated.json"
sys.path.insert(0, str(ROOT / "scripts"))
sys.path.insert(0, str(ROOT / "experiments"))

import rocket_outsider_sweep as sweep  # noqa: E402


HEADER = ("time", "altitude", "acceleration")
FLIGHTS = {
    "gnss5-clean": dict(sweep.BASE, gnss=(5.0, 2.0), seed=81, header=HEADER),
    "gnss5-cross7": dict(
        sweep.BASE,
        gnss=(5.0, 2.0),
        wind=tuple(7.0 * sweep.ACROSS),
        seed=82,
        header=HEADER,
    ),
    "gnss1-clean": dict(
        sweep.BASE, rate=100.0, gnss=(1.0, 3.0), seed=83, header=HEADER
    ),
    "gnss1-cross5": dict(
        sweep.BASE,
        rate=100.0,
        gnss=(1.0, 3.0),
        wind=tuple(5.0 * sweep.ACROSS),
        seed=84,
        header=HEADER,
    ),
    # the 5 Hz pair with the fixes on the WGS84 ellipsoid, as a receiver's
    # (RocketPy's latitude and longitude are on a sphere)
    "gnss5-clean-wgs84": dict(
        sweep.BASE, gnss=(5.0, 2.0), gnss_wgs84=True, seed=81, header=HEADER
    ),
    "gnss5-cross7-wgs84": dict(
        sweep.BASE,
        gnss=(5.0, 2.0),
        gnss_wgs84=True,
        wind=tuple(7.0 * sweep.ACROSS),
        seed=82,
        header=HEADER,
    ),
}


def one(toml, gnss: bool, diagnose: bool, planted=None, top=None):
    """The fit (and diagnosis) of the flight at `toml` with or without its GNSS
    position; `planted` `(mach, cd)` arrays to score the band against."""
    import diffpegasus as dp
    import diffpegasus.rocket as dr

    t0 = time.perf_counter()
    rocket = dr.read_rocket(toml)
    problem = dr.prepare(rocket, dp.read_rocket_log(toml), gnss=gnss)
    r = dr.fit_rocket(problem, throw=False)
    seconds = time.perf_counter() - t0
    mach = np.array(problem.flight.knots.mach)
    cd, se = r.cd(mach)
    row = dict(
        outputs=list(problem.outputs),
        converged=bool(r.fit.converged),
        seconds=seconds,
        apogee=r.apogee,
        rms_altitude=r.rms(),
        mach=mach.tolist(),
        cd=cd.tolist(),
        cd_se=se.tolist(),
        estimates={
            k: list(r.estimate(k))
            for k, f in zip(r.fit.model.parameters, r.fit.free, strict=True)
            if f and k not in problem.flight.knots.names
        },
    )
    if planted is not None:
        inside = mach <= top
        truth = np.interp(mach, *planted)
        row["inside"] = int(np.sum((np.abs(cd - truth) <= 1.96 * se)[inside]))
        row["points"] = int(inside.sum())
    if diagnose:
        t0 = time.perf_counter()
        named, rows, _ = dr.diagnose(problem)
        row["named"] = named
        row["diagnose_seconds"] = time.perf_counter() - t0
        row["tests"] = [
            {
                k: q[k]
                for k in (
                    "round",
                    "candidate",
                    "statistic",
                    "threshold",
                    "cost_ratio",
                    "explains_enough",
                    "estimates",
                )
            }
            for q in rows
        ]
    return row


def run(folders, path, diagnose=True, variants=(False, True)):
    for folder in folders:
        toml = folder / "rocket.toml"
        truth_file = folder / "truth.json"
        planted, top, truth = None, None, None
        if truth_file.exists():
            truth = json.loads(truth_file.read_text())
            planted = np.loadtxt(folder / "planted_drag.csv", delimiter=",").T
            top = truth["max_mach"]
        results = json.loads(path.read_text()) if path.exists() else {}
        row = dict(results.get(folder.name, {}), truth=truth)
        for gnss in variants:
            key = "with" if gnss else "without"
            row[key] = one(toml, gnss, diagnose, planted, top)
            w = row[key]["estimates"]
            print(
                folder.name,
                key,
                f"{row[key]['seconds']:.0f} s apogee {row[key]['apogee']:.1f}",
                {k: [round(v, 2) for v in w[k]] for k in w if k.startswith("wind")},
                "inside",
                row[key].get("inside"),
                "named",
                row[key].get("named"),
                flush=True,
            )
        results = json.loads(path.read_text()) if path.exists() else {}
        results[folder.name] = row
        path.write_text(json.dumps(results, indent=1, default=float) + "\n")


def table(path):
    results = json.loads(path.read_text())
    print(
        "| flight | GNSS | CD inside 95% | apogee m | wind east, north, along m/s "
        "| named | fit s |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, row in results.items():
        for key in ("without", "with"):
            r = row[key]
            est = r["estimates"]
            wind = ", ".join(
                f"{est[k][0]:.1f} ± {est[k][1]:.1f}" if k in est else "-"
                for k in ("wind_east", "wind_north", "wind_along")
            )
            inside = f"{r['inside']}/{r['points']}" if "inside" in r else "-"
            named = ", ".join(r["named"]) if r.get("named") else "nothing"
            if "named" not in r:
                named = "-"
            print(
                f"| {name} | {key} | {inside} | {r['apogee']:.1f} | {wind} | {named} "
                f"| {r['seconds']:.0f} |"
            )


def main():
    cmd = sys.argv[1]
    if cmd == "table":
        return table(REAL if sys.argv[2:] == ["real"] else SIMULATED)
    if cmd == "real":
        names = sys.argv[2:]
        return run([shared_data("rockets") / n for n in names], REAL, diagnose=False)
    out = pathlib.Path(sys.argv[2])
    names = [n for n in sys.argv[3:] if not n.startswith("--")] or list(FLIGHTS)
    if cmd == "fly":
        from make_rocket_fixtures import MOTOR_INERTIA

        for name in names:
            # the fixtures' airframe in the rocket file, for the attitude's fits
            sweep.fly_one(name, dict(FLIGHTS[name], geometry=True), out)
            toml = out / name / "rocket.toml"
            text = toml.read_text().replace(
                "motor_inertia_kgm2 = 0.097", f"motor_inertia_kgm2 = {MOTOR_INERTIA}"
            )
            toml.write_text(text)
    elif cmd == "run":
        run(
            [out / n for n in names],
            SIMULATED,
            diagnose="--no-diagnose" not in sys.argv,
            # --with: the GNSS fit alone (the other kept from an earlier run)
            variants=(True,) if "--with" in sys.argv else (False, True),
        )


if __name__ == "__main__":
    main()
