"""Rockets unlike the fixtures' one, flown in RocketPy, fitted and diagnosed through
the command line as a user would (docs/rockets/simulated.md, Another airframe).

The airframe is RocketPy's documented example "Calisto" (its getting-started
rocket: 127 mm body, 14.426 kg without motor, von Karman nose, four trapezoidal fins
with 0.5 deg of cant, a boat tail, rail buttons at 45 deg) on a Cesaroni Pro75 M1670
(RocketPy's `SolidMotor` with the example's five grains), launched from Spaceport
America (1400 m) off a 5.2 m rail at 85 deg heading north. The numbers are written
out below from RocketPy's documentation; the drag curve is one planted here (shaped
like a subsonic rocket's: not RocketPy's file). The thrust curve is written for our
side as a RASP `.eng` file. `small-*` fly a second, smaller rocket (54 mm, a J
motor, a 3 m rail heading east). `*-smooth` are flights through the exact
standard-atmosphere pressure instead of RocketPy's table.

Each flight's folder (`rocket.toml`, `motor.eng`, `drag.csv`, `log.csv`) is written by
scripts/make_rocket_fixtures.py's `flight`, as the fixtures are.

Run (RocketPy's environment for `fly`, ours for the rest; both with this
repository's src on PYTHONPATH):

    python experiments/rocket_other_airframe.py fly DIR [NAME ...]
    python experiments/rocket_other_airframe.py run DIR [NAME ...]
    python experiments/rocket_other_airframe.py run DIR --diagnose-only NAME ...
    python experiments/rocket_other_airframe.py own FOLDER ... [--lag S] --out NAME
    python experiments/rocket_other_airframe.py table JSON ...

`run` calls `diffpegasus rocket fit FOLDER/rocket.toml --out ... --json` and
`diffpegasus rocket diagnose FOLDER/rocket.toml --json` on each flight and adds them
to experiments/results/rocket_other_airframe.json (`--out NAME` for another name):
the planted CD (drag.csv) against the fit's 95% band at each knot of `summary.json`'s
table inside the flight's Mach range (with the sensors' spread, and the noise's
alone), the reconstructed apogee against the log's, and what diagnose names. `own`
diagnoses the model's own flight of each FOLDER's rocket with its noise (optionally
the fixtures' barometer lag filter on it); `table` prints the page's table.
"""

import json
import pathlib
import subprocess
import sys
import time
import tomllib

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))

# Cesaroni Pro75 M1670 (RocketPy's data/motors/cesaroni/Cesaroni_M1670.eng as the
# documentation prints it): s, N
M1670 = np.array(
    [
        [0.055, 100.0],
        [0.092, 1500.0],
        [0.1, 2000.0],
        [0.15, 2200.0],
        [0.2, 1800.0],
        [0.5, 1950.0],
        [1.0, 2034.0],
        [1.5, 2000.0],
        [2.0, 1900.0],
        [2.5, 1760.0],
        [2.9, 1700.0],
        [3.0, 1650.0],
        [3.3, 530.0],
        [3.4, 350.0],
        [3.9, 0.0],
    ]
)
# the example's grains: 5 of 1815 kg/m^3, 33 mm outer and 15 mm inner radius, 120 mm
# long, 5 mm apart; their centre 0.397 m and the dry motor's 0.317 m from the nozzle
GRAINS = 5 * 1815 * np.pi * (0.033**2 - 0.015**2) * 0.120

# A smaller rocket: 54 mm body, 2.1 kg without motor, on a J motor of 1.9 s
# (a made-up but plausible curve of about 700 N s, 0.42 kg of propellant)
J_MOTOR = np.array(
    [
        [0.02, 200.0],
        [0.06, 520.0],
        [0.2, 470.0],
        [0.6, 420.0],
        [1.0, 380.0],
        [1.4, 320.0],
        [1.7, 200.0],
        [1.9, 0.0],
    ]
)

# planted drag curves (Mach, CD)
CALISTO_DRAG = [
    (0.0, 0.45),
    (0.2, 0.42),
    (0.5, 0.41),
    (0.7, 0.44),
    (0.85, 0.52),
    (1.0, 0.66),
    (1.2, 0.62),
]
SMALL_DRAG = [
    (0.0, 0.60),
    (0.25, 0.54),
    (0.5, 0.52),
    (0.7, 0.55),
    (0.9, 0.68),
    (1.2, 0.80),
]

BASE = dict(
    drag=CALISTO_DRAG,
    scale=1.0,
    wind=(0.0, 0.0),
    lag=0.0,
    static=0.0,
    noise=(0.5, 0.3),
    airframe="calisto",
)
FLIGHTS = {
    "calisto-clean-s41": dict(BASE, seed=41),
    "calisto-clean-s42-20hz": dict(BASE, seed=42, rate=20.0),
    "calisto-thrust095-s43": dict(BASE, scale=0.95, seed=43),
    "calisto-lag01-s44": dict(BASE, lag=0.1, seed=44),
    # a head wind along the rail's heading (north)
    "calisto-wind6-s45": dict(BASE, wind=(0.0, -6.0), seed=45),
    "small-clean-s46": dict(BASE, drag=SMALL_DRAG, airframe="small", seed=46),
}
SMALL = dict(BASE, drag=SMALL_DRAG, airframe="small")
FLIGHTS.update(
    {
        "small-thrust095-s47-20hz": dict(SMALL, scale=0.95, seed=47, rate=20.0),
        "small-lag01-s48": dict(SMALL, lag=0.1, seed=48),
        # a cross wind from the north (the rail heads east)
        "small-wind6-s49": dict(SMALL, wind=(0.0, -6.0), seed=49),
    }
)
# the same flights, seeds and noise through the exact standard-atmosphere pressure
# instead of RocketPy's table (the fixtures' `smooth_pressure`): are the barometer's
# alarms on the clean flights the table's?
SMOOTH = {
    f"{name}-smooth": dict(FLIGHTS[name], smooth_pressure=True)
    for name in (
        "calisto-clean-s41",
        "calisto-clean-s42-20hz",
        "calisto-lag01-s44",
        "calisto-thrust095-s43",
    )
}
FLIGHTS.update(SMOOTH)

SITES = {
    "calisto": dict(
        latitude=32.990254,
        longitude=-106.974998,
        elevation=1400,
        rail_length=5.2,
        inclination=85,
        heading=0,
    ),
    "small": dict(
        latitude=32.990254,
        longitude=-106.974998,
        elevation=1400,
        rail_length=3.0,
        inclination=87,
        heading=90,
    ),
}


def environment(spec, site):
    from make_rocket_fixtures import _isa_pressure
    from rocketpy import Environment

    env = Environment(
        latitude=site["latitude"],
        longitude=site["longitude"],
        elevation=site["elevation"],
    )
    u, v = spec["wind"]
    pressure = None
    if spec.get("smooth_pressure"):
        # the exact troposphere every 10 m (RocketPy's own: a spline through points
        # 808 m apart)
        heights = np.arange(-100.0, 10000.0, 10.0)
        pressure = np.column_stack([heights, [_isa_pressure(h) for h in heights]])
    env.set_atmospheric_model(
        type="custom_atmosphere",
        pressure=pressure,
        temperature=None,
        wind_u=[(0, u), (10000, u)],
        wind_v=[(0, v), (10000, v)],
    )
    return env


def calisto_motor(scale=1.0):
    from rocketpy import SolidMotor

    thrust = np.vstack([[0.0, 0.0], M1670])
    thrust[:, 1] *= scale
    return SolidMotor(
        thrust_source=thrust,
        dry_mass=1.815,
        dry_inertia=(0.125, 0.125, 0.002),
        nozzle_radius=33 / 1000,
        grain_number=5,
        grain_density=1815,
        grain_outer_radius=33 / 1000,
        grain_initial_inner_radius=15 / 1000,
        grain_initial_height=120 / 1000,
        grain_separation=5 / 1000,
        grains_center_of_mass_position=0.397,
        center_of_dry_mass_position=0.317,
        nozzle_position=0,
        burn_time=3.9,
        throat_radius=11 / 1000,
        coordinate_system_orientation="nozzle_to_combustion_chamber",
    )


def small_motor(scale=1.0):
    from rocketpy import GenericMotor

    thrust = np.vstack([[0.0, 0.0], J_MOTOR])
    thrust[:, 1] *= scale
    return GenericMotor(
        thrust_source=thrust,
        burn_time=1.9,
        chamber_radius=0.019,
        chamber_height=0.25,
        chamber_position=0.15,
        propellant_initial_mass=0.42,
        nozzle_radius=0.015,
        dry_mass=0.35,
        dry_inertia=(0.004, 0.004, 0.0001),
        center_of_dry_mass_position=0.15,
    )


def calisto_build(spec):
    """RocketPy's environment, Calisto and its flight to apogee for `spec`."""
    from rocketpy import Rocket

    site = SITES["calisto"]
    env = environment(spec, site)
    drag = [tuple(p) for p in spec["drag"]]
    rocket = Rocket(
        radius=127 / 2000,
        mass=14.426,
        inertia=(6.321, 6.321, 0.034),
        power_off_drag=drag,
        power_on_drag=drag,
        center_of_mass_without_motor=0,
        coordinate_system_orientation="tail_to_nose",
    )
    rocket.set_rail_buttons(
        upper_button_position=0.0818,
        lower_button_position=-0.6182,
        angular_position=45,
    )
    rocket.add_motor(calisto_motor(spec["scale"]), position=-1.255)
    rocket.add_nose(length=0.55829, kind="vonKarman", position=1.278)
    rocket.add_trapezoidal_fins(
        n=4,
        root_chord=0.120,
        tip_chord=0.060,
        span=0.110,
        position=-1.04956,
        cant_angle=0.5,
    )
    rocket.add_tail(
        top_radius=0.0635, bottom_radius=0.0435, length=0.060, position=-1.194656
    )
    return env, rocket, to_apogee(rocket, env, site)


def to_apogee(rocket, env, site):
    """RocketPy's flight of `rocket` off the `site`'s rail to apogee."""
    from rocketpy import Flight

    return Flight(
        rocket=rocket,
        environment=env,
        rail_length=site["rail_length"],
        inclination=site["inclination"],
        heading=site["heading"],
        terminate_on_apogee=True,
        max_time_step=0.01,
    )


def small_build(spec):
    """RocketPy's environment, the small rocket and its flight to apogee."""
    from rocketpy import Rocket

    site = SITES["small"]
    env = environment(spec, site)
    drag = [tuple(p) for p in spec["drag"]]
    rocket = Rocket(
        radius=0.027,
        mass=2.1,
        inertia=(0.45, 0.45, 0.002),
        power_off_drag=drag,
        power_on_drag=drag,
        center_of_mass_without_motor=0.65,
        coordinate_system_orientation="tail_to_nose",
    )
    rocket.add_motor(small_motor(spec["scale"]), position=0.0)
    rocket.add_nose(length=0.27, kind="ogive", position=1.55)
    rocket.add_trapezoidal_fins(
        n=3, root_chord=0.11, tip_chord=0.05, span=0.07, position=0.13
    )
    rocket.set_rail_buttons(0.7, 0.2)
    return env, rocket, to_apogee(rocket, env, site)


def motor_writer(points, name, diameter_mm, length_mm, propellant, total):
    """A writer of the motor's catalogue curve as a RASP `motor.eng`."""

    def write(folder):
        lines = [
            "; written by experiments/rocket_other_airframe.py",
            f"{name} {diameter_mm} {length_mm} 0 {propellant:.4f} {total:.4f} CTI",
        ]
        lines += [f"   {t:g} {f:g}" for t, f in points]
        (folder / "motor.eng").write_text("\n".join(lines) + "\n")

    return write


def calisto_facts():
    """The rocket.toml's [rocket], [geometry] and [motor] for Calisto: the loaded
    motor's centre of mass and lateral inertia about it as RocketPy's motor has
    them at ignition."""
    motor = calisto_motor()
    # motor coordinates from the nozzle toward the chamber; the nozzle at -1.255 in
    # the rocket's tail-to-nose axis
    cm = -1.255 + float(motor.center_of_mass(0))
    inertia = float(motor.I_11(0))
    return f"""\
[rocket]
mass_without_motor_kg = 14.426
radius_m = 0.0635
I11_kgm2 = 6.321
center_of_mass_without_motor_m = 0.0
rail_buttons_m = [0.0818, -0.6182]

[geometry]
nose = {{ kind = "vonKarman", length_m = 0.55829, position_m = 1.278 }}
fins = {{ n = 4, span_m = 0.11, root_chord_m = 0.12, tip_chord_m = 0.06, position_m = -1.04956, cant_angle_deg = 0.5 }}
tail = {{ top_radius_m = 0.0635, bottom_radius_m = 0.0435, length_m = 0.06, position_m = -1.194656 }}
motor_center_of_mass_m = {cm:.4f}
nozzle_position_m = -1.255
motor_inertia_kgm2 = {inertia:.4f}

[motor]
thrust_file = "motor.eng"
propellant_initial_mass_kg = {GRAINS:.4f}
dry_mass_kg = 1.815
"""


def small_facts():
    motor = small_motor()
    cm = float(motor.center_of_mass(0))
    inertia = float(motor.I_11(0))
    return f"""\
[rocket]
mass_without_motor_kg = 2.1
radius_m = 0.027
I11_kgm2 = 0.45
center_of_mass_without_motor_m = 0.65
rail_buttons_m = [0.7, 0.2]

[geometry]
nose = {{ kind = "ogive", length_m = 0.27, position_m = 1.55 }}
fins = {{ n = 3, span_m = 0.07, root_chord_m = 0.11, tip_chord_m = 0.05, position_m = 0.13 }}
motor_center_of_mass_m = {cm:.4f}
nozzle_position_m = 0.0
motor_inertia_kgm2 = {inertia:.4f}

[motor]
thrust_file = "motor.eng"
propellant_initial_mass_kg = 0.42
dry_mass_kg = 0.35
"""


def fly(out, names):
    from make_rocket_fixtures import flight

    airframes = {
        "calisto": dict(
            build=calisto_build,
            facts=calisto_facts(),
            motor=motor_writer(M1670, "M1670-BS", 75, 757, 3.101, 5.231),
            site=SITES["calisto"],
        ),
        "small": dict(
            build=small_build,
            facts=small_facts(),
            motor=motor_writer(J_MOTOR, "J700-SM", 38, 250, 0.42, 0.77),
            site=SITES["small"],
        ),
    }
    for name in names:
        spec = FLIGHTS[name]
        flight(
            name,
            spec,
            out,
            source="experiments/rocket_other_airframe.py",
            **airframes[spec["airframe"]],
        )


def cli(*args, nice: bool = False):
    """`diffpegasus ARGS --json` in this interpreter's environment (under `nice -n
    10` with `nice`): its JSON, or the failure's exit code and last lines."""
    t0 = time.perf_counter()
    prefix = ["nice", "-n", "10"] if nice else []
    proc = subprocess.run(
        [*prefix, sys.executable, "-m", "diffpegasus", *args, "--json"],
        capture_output=True,
        text=True,
    )
    seconds = time.perf_counter() - t0
    if proc.returncode != 0 and not (proc.returncode == 3 and "{" in proc.stdout):
        return dict(
            error=proc.returncode,
            stderr=proc.stderr[-3000:],
            stdout=proc.stdout[-2000:],
            seconds=seconds,
        )
    text = proc.stdout
    return dict(json.loads(text[text.index("{") :]), seconds=seconds)


def coverage(summary, folder, top, drag="drag.csv"):
    """Each knot of the fit's CD table inside the flight's Mach range (up to its
    top `top`): the planted CD there (`folder / drag`, Mach and CD) and whether it
    is inside the 95% band, with the sensors' spread (`stderr`) and with the
    noise's alone (`stderr_noise`)."""
    mach_true, cd_true = np.loadtxt(folder / drag, delimiter=",").T
    rows = []
    for row in summary["cd_table"]:
        if row["mach"] > top:
            continue
        planted = float(np.interp(row["mach"], mach_true, cd_true))
        off = abs(row["cd"] - planted)
        rows.append(
            dict(
                mach=row["mach"],
                cd=row["cd"],
                planted=planted,
                stderr=row["stderr"],
                stderr_noise=row["stderr_noise"],
                inside=bool(off <= 1.96 * row["stderr"]),
                inside_noise=bool(off <= 1.96 * row["stderr_noise"]),
            )
        )
    return rows


def run(flights, names, out_name, fit_too=True):
    results = {}
    path = ROOT / "experiments" / "results" / f"{out_name}.json"
    if path.exists():
        results = json.loads(path.read_text())
    for name in names:
        folder = flights / name
        doc = tomllib.loads((folder / "rocket.toml").read_text())
        truth = doc["truth"]
        figures = flights / f"{name}-fit"
        fit = (
            cli("rocket", "fit", str(folder / "rocket.toml"), "--out", str(figures))
            if fit_too
            else dict(error="not run", seconds=0.0)
        )
        diag = cli("rocket", "diagnose", str(folder / "rocket.toml"))
        row = dict(planted=truth, fit_cli=fit, diagnose_cli=diag)
        summary_path = figures / "summary.json"
        if "error" not in fit and summary_path.exists():
            summary = json.loads(summary_path.read_text())
            knots = coverage(summary, folder, truth["max_mach"])
            row["knots"] = knots
            row["inside"] = sum(k["inside"] for k in knots)
            row["inside_noise"] = sum(k["inside_noise"] for k in knots)
            row["points"] = len(knots)
            row["apogee_logged_m"] = summary["apogee_logged_m"]
            row["apogee_reconstructed_m"] = summary["apogee_reconstructed_m"]
            row["apogee_error_m"] = (
                summary["apogee_reconstructed_m"] - summary["apogee_logged_m"]
            )
            row["apogee_true_m"] = truth["apogee_geometric_agl_m"]
            row["converged"] = summary["converged"]
            row["estimates"] = summary["estimates"]
            # the whole summary is `fit_cli` (the CLI's --json, with its seconds)
        results[name] = row
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(results, indent=1, default=str) + "\n")
        print(
            name,
            "inside",
            row.get("inside"),
            "of",
            row.get("points"),
            "apogee error",
            row.get("apogee_error_m"),
            "fit s",
            round(fit["seconds"]),
            "diagnose s",
            round(diag["seconds"]),
            "diagnose error" if "error" in diag else "",
            flush=True,
        )


def planted_text(truth):
    """The planted effects of a flight's `[truth]` in words."""
    parts = []
    if truth["thrust_scale"] != 1.0:
        parts.append(f"thrust scale {truth['thrust_scale']}")
    if truth["baro_lag_s"]:
        parts.append(f"barometer lag {truth['baro_lag_s']} s")
    if truth["static_error"]:
        parts.append(f"static-pressure error {truth['static_error']}")
    u, v = truth["wind_east_m_s"], truth["wind_north_m_s"]
    if u or v:
        # the direction it blows from, as a compass point
        frm = np.degrees(np.arctan2(-u, -v)) % 360
        point = ("N", "NE", "E", "SE", "S", "SW", "W", "NW")[round(frm / 45) % 8]
        parts.append(f"wind {np.hypot(u, v):g} m/s from {point}")
    return ", ".join(parts) or "nothing"


def right(truth, named):
    """Is diagnose's answer right: every planted effect named, nothing else?"""
    expected = []
    if truth["thrust_scale"] != 1.0:
        expected.append("thrust scale")
    if truth["baro_lag_s"]:
        expected.append("barometer lag")
    if truth["static_error"]:
        expected.append("static-pressure error")
    if truth["wind_east_m_s"] or truth["wind_north_m_s"]:
        expected.append("wind")
    found = [e for e in expected if any(e in n for n in named)]
    extra = [n for n in named if not any(e in n for e in expected)]
    if found == expected and not extra:
        return "yes"
    if found:
        return "partly: also " + ", ".join(extra) if extra else "partly"
    return "no"


def judged(diag):
    """`(named, text)` of a stored diagnosis judged by the rule as it stands (a
    finding's statistic passes and a sensor's own effect explains `SHARE` of the
    misfit): the stored
    rounds up to the first that names nothing now are the same; that round's
    strongest significant candidate is shown with the share it would explain."""
    from diffpegasus._rocket._diagnose import explains_enough

    if diag.get("named") is None:
        return None, "error"
    named, cells, tests = [], [], diag.get("tests", [])
    for r, stored in enumerate(diag["named"], start=1):
        row = [t for t in tests if t["round"] == r and t["significant"]]
        enough = row and row[0].get(
            "explains_enough",
            explains_enough(*row[0]["estimates"], row[0]["cost_ratio"]),
        )
        if not enough:
            break
        named.append(stored)
        cells.append(f"{stored}: {row[0]['statistic']:.0f} ({row[0]['threshold']:.1f})")
    stop = [t for t in tests if t["round"] == len(named) + 1 and t["significant"]]
    text = "; ".join(cells) or "nothing"
    if stop:
        t = stop[0]
        share = 1 - t["cost_ratio"]
        text += (
            f" ({'then ' if named else ''}{t['candidate']} {t['statistic']:.0f} "
            f"({t['threshold']:.1f}), explains "
            f"{f'{share:.1%}' if share < 0.095 else f'{share:.0%}'})"
        )
    return named, text


def table(paths):
    """The markdown table of one or more `run` JSONs."""
    rows = [
        "| flight | planted | named: score (threshold) | right? | CD knots inside the 95% band "
        "(noise's band alone) | apogee: reconstructed - log's (- geometric) m |",
        "|---|---|---|---|---|---|",
    ]
    for path in paths:
        for name, r in json.loads(pathlib.Path(path).read_text()).items():
            truth = r["planted"]
            diag = r["diagnose_cli"]
            named, named_text = judged(diag)
            if "knots" in r:
                inside = f"{r['inside']} of {r['points']} ({r['inside_noise']})"
                apogee = (
                    f"{r['apogee_error_m']:+.1f} "
                    f"({r['apogee_reconstructed_m'] - r['apogee_true_m']:+.1f})"
                )
            else:
                inside = apogee = "-"
            rows.append(
                f"| {name} | {planted_text(truth)} | {named_text} | "
                f"{'-' if named is None else right(truth, named)} | {inside} | "
                f"{apogee} |"
            )
    print("\n".join(rows))


def own(folders, out_name, lag=0.0):
    """The model's own flight of each flight's rocket (its planted drag curve, the
    catalogue thrust, the log's times; no wind, no sensor effect) with the log's
    noise levels (its `[truth]`, seed 11), written as its log and diagnosed: does
    the model's barometer alone make an alarm on this airframe? With `lag` (s) its
    barometer's pressure goes through the fixtures' first-order lag (the same
    discrete filter as scripts/make_rocket_fixtures.py's `flight`)."""
    import shutil

    from make_rocket_fixtures import lagged_baro, write_log

    import diffpegasus.rocket as dr
    from diffpegasus import read_rocket_log

    path = ROOT / "experiments" / "results" / f"{out_name}.json"
    results = json.loads(path.read_text()) if path.exists() else {}
    for folder in map(pathlib.Path, folders):
        toml = folder / "rocket.toml"
        truth = tomllib.loads(toml.read_text())["truth"]
        problem = dr.prepare(dr.read_rocket(toml), read_rocket_log(toml))
        flown = dr.simulate_flight(
            problem, start={"thrust_scale": 1.0, "motor_time": 0.0}
        )
        n = len(problem.record.t)
        rng = np.random.default_rng(11)
        baro = np.array(flown.baro[:n])
        if lag > 0:
            # standard-atmosphere pressure of the reading (the pad at its elevation),
            # filtered as the fixtures' barometer is, and back to altitude
            pad = tomllib.loads(toml.read_text())["launch"]["elevation_m"]
            baro = lagged_baro(baro, pad, float(problem.record.dt), lag)
        baro = baro + rng.normal(0.0, truth["noise_altitude_m"], n)
        accel = flown.accel[:n] + rng.normal(0.0, truth["noise_accel_m_s2"], n)
        copy = folder.parent / (f"{folder.name}-own" + (f"-lag{lag:g}" if lag else ""))
        shutil.copytree(folder, copy, dirs_exist_ok=True)
        write_log(copy, problem.record.t, baro, accel)
        results[copy.name] = dict(
            planted=dict(
                truth,
                baro_lag_s=lag,
                static_error=0.0,
                thrust_scale=1.0,
                wind_east_m_s=0.0,
                wind_north_m_s=0.0,
            ),
            diagnose_cli=cli("rocket", "diagnose", str(copy / "rocket.toml")),
        )
        print(copy.name, results[copy.name]["diagnose_cli"].get("named"), flush=True)
    path.write_text(json.dumps(results, indent=1, default=str) + "\n")


def main():
    args = sys.argv[1:]
    if args[:1] == ["table"]:
        table(args[1:])
        return
    out_name = "rocket_other_airframe"
    if "--out" in args:
        i = args.index("--out")
        out_name = args[i + 1]
        del args[i : i + 2]
    fit_too = "--diagnose-only" not in args
    args = [a for a in args if a != "--diagnose-only"]
    lag = 0.0
    if "--lag" in args:
        i = args.index("--lag")
        lag = float(args[i + 1])
        del args[i : i + 2]
    mode, folder, *names = args
    if mode == "own":
        own([folder, *names], out_name, lag)
        return
    names = names or list(FLIGHTS)
    if mode == "fly":
        fly(pathlib.Path(folder), names)
    elif mode == "run":
        run(pathlib.Path(folder), names, out_name, fit_too)
    else:
        raise SystemExit(f"unknown mode {mode!r}: fly or run")


if __name__ == "__main__":
    main()
