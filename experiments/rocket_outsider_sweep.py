"""Flights written the way someone outside the project would write them, fitted and
diagnosed through the documented interface (docs/rockets/simulated.md, Flights
written another way).

Each flight is flown in RocketPy with its default `Environment` (the standard
atmosphere; a `custom_atmosphere` only to add wind) and written as a flight
computer or a user's script would write it, not in the fixtures' layout: the
barometric altitude taken as RocketPy's `z` less the pad's elevation (no pressure
conversion) on some, the static pressure in Pa or hPa on others, the accelerometer
in g on one; 10, 50, 100, 200 or 500 Hz; noise from 0.1 to 2 m; a clock that
starts on the pad seconds before ignition (the log's own pre-liftoff samples) on
most; the log going on 3 s past apogee. The `rocket.toml` of each is written from
the rockets guide's key table alone: no column map, no stated events, no
`[atmosphere]`; a team's pre-flight drag curve (the planted one 8% high) on some.
The truth goes to `truth.json` and `planted_drag.csv` beside it, which nothing of
ours reads.

The rocket is the fixtures' (scripts/make_rocket_fixtures.py: 104 mm, 8.2 kg
without its motor, a 75 mm L motor), one flight on a long-burn Cesaroni L395 from
RocketPy's motor collection (its RASP `.eng`, 12.5 s, written out below and read
by RocketPy from the file), one whose rocket is 0.4 kg heavier than its file says.

Run (RocketPy's environment for `fly`, ours for `run`; both with this
repository's src on PYTHONPATH):

    python experiments/rocket_outsider_sweep.py fly DIR [NAME ...]
    python experiments/rocket_outsider_sweep.py run DIR [NAME ...]
    python experiments/rocket_outsider_sweep.py burn-held DIR NAME ...
    python experiments/rocket_outsider_sweep.py table

`run` calls `diffpegasus rocket fit FOLDER/rocket.toml --out FOLDER-fit --json` and
`diffpegasus rocket diagnose FOLDER/rocket.toml --json` and adds each flight to
experiments/results/rocket_outsider_sweep.json: whether each ran (else its error
line), the planted CD against the fit's 95% band at the knots of `summary.json`'s
table up to the flight's top Mach, the reconstructed apogee against the log's and
RocketPy's, the altitude RMS, the times, what diagnose names. `burn-held`
diagnoses again with the burn's length held at the full fit's estimate instead of
the accelerometer's reading (experiments/results/rocket_outsider_sweep_burn.json).
`z-100hz-as-baro` and `z-100hz-buttons` are controls of `z-100hz` (the barometric
altitude instead of `z`; the rail buttons in the rocket file).
"""

import json
import pathlib
import sys

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "experiments" / "results" / "rocket_outsider_sweep.json"
sys.path.insert(0, str(ROOT / "scripts"))
sys.path.insert(0, str(ROOT / "experiments"))

import rocket_other_airframe as other_airframe  # noqa: E402


G0 = 9.80665

# the planted drag curve (Mach, CD): none of the fixtures' curves
CURVE = [(0.0, 0.52), (0.25, 0.47), (0.5, 0.45), (0.7, 0.47), (0.9, 0.60), (1.2, 0.74)]

# Cesaroni L395 (long burn), RocketPy's data/motors/cesaroni/Cesaroni_4937L395-P.eng:
# s, N; 2.218 kg of propellant, 5.706 kg loaded; 75 mm, 757 mm
L395 = [
    (0.04, 484.229),
    (0.129, 484.229),
    (0.209, 578.734),
    (0.547, 553.644),
    (2.043, 511.828),
    (7.329, 439.068),
    (8.632, 424.014),
    (9.573, 297.73),
    (11.399, 100.358),
    (12.445, 30.108),
    (12.501, 0.0),
]

SITE = dict(latitude=39.39, longitude=-8.29, elevation=150.0)
RAIL = dict(rail_length=12.0, inclination=84.0, heading=133.0)
HEADING = np.radians(RAIL["heading"])
# unit vectors (east, north) along and across the rail's heading
ALONG = np.array([np.sin(HEADING), np.cos(HEADING)])
ACROSS = np.array([np.cos(HEADING), -np.sin(HEADING)])

BASE = dict(
    motor="fixture",
    scale=1.0,
    mass_error=0.0,
    wind=(0.0, 0.0),
    lag=0.0,
    static=0.0,
    noise=(0.5, 0.3),
    rate=50.0,
    altitude="z",
    accel="m/s^2",
    pad_s=2.0,
    team_drag=False,
    latitude=True,
    seed=0,
)
# header per channel kind: the names a logger or a user's script writes
FLIGHTS = {
    # the simplest: names without units, RocketPy's z, a clock from the pad
    "z-100hz": dict(
        BASE,
        rate=100.0,
        noise=(0.3, 0.2),
        seed=61,
        header=("time", "altitude", "acceleration"),
    ),
    # a barometer-only altimeter: pressure in Pa at 10 Hz, 2 m of noise
    "pa-10hz": dict(
        BASE,
        rate=10.0,
        altitude="Pa",
        accel=None,
        noise=(2.0, 0.0),
        pad_s=3.0,
        team_drag=True,
        seed=62,
        header=("Time (s)", "Pressure (Pa)"),
    ),
    # hPa and an accelerometer in g, 200 Hz
    "hpa-g-200hz": dict(
        BASE,
        rate=200.0,
        altitude="hPa",
        accel="g",
        seed=63,
        header=("Time (s)", "Pressure (hPa)", "Accel (g)"),
    ),
    # 500 Hz from ignition (no pad samples), 1 m of noise
    "z-500hz": dict(
        BASE,
        rate=500.0,
        noise=(1.0, 0.5),
        pad_s=0.0,
        latitude=False,
        seed=64,
        header=("Time [s]", "Altitude [m]", "Acceleration [m/s^2]"),
    ),
    # a long-burn motor from RocketPy's collection, its .eng as the thrust file
    "l395-eng-50hz": dict(
        BASE,
        motor="L395",
        altitude="Pa",
        team_drag=True,
        seed=65,
        header=("time_s", "pressure_pa", "accel_m_s2"),
    ),
    # tail wind, 9 m/s along the rail's heading
    "tailwind9-100hz": dict(
        BASE, rate=100.0, wind=tuple(9.0 * ALONG), seed=66, header=("t", "alt", "acc")
    ),
    # cross wind, 8 m/s across the heading; the fixtures' barometric conversion
    "crosswind8-50hz": dict(
        BASE,
        wind=tuple(8.0 * ACROSS),
        altitude="baro",
        noise=(0.8, 0.4),
        seed=67,
        header=("time", "baro_altitude", "accel_axial"),
    ),
    # thrust 4% over the catalogue, 0.1 m of noise, 200 Hz
    "thrust104-200hz": dict(
        BASE,
        rate=200.0,
        scale=1.04,
        noise=(0.1, 0.1),
        seed=68,
        header=("time", "altitude", "acceleration"),
    ),
    # a first-order barometer lag of 0.05 s on the pressure, 100 Hz
    "lag005-100hz": dict(
        BASE,
        rate=100.0,
        lag=0.05,
        altitude="Pa",
        seed=69,
        header=("Time (s)", "Pressure (Pa)", "Acceleration (m/s^2)"),
    ),
    # a static-pressure error of 0.03 of the dynamic pressure, hPa, 50 Hz
    "static003-50hz": dict(
        BASE,
        static=0.03,
        altitude="hPa",
        team_drag=True,
        seed=70,
        header=("Time (s)", "Pressure (hPa)", "Accel (m/s^2)"),
    ),
    # control: z-100hz's flight, seed and noise with the barometric altitude a
    # flight computer computes from the pressure (the fixtures' conversion)
    "z-100hz-as-baro": dict(
        BASE,
        rate=100.0,
        noise=(0.3, 0.2),
        altitude="baro",
        seed=61,
        header=("time", "altitude", "acceleration"),
    ),
    # control: z-100hz's log, its rocket file giving the rail buttons and the
    # nozzle (the rail left when the upper button does, as RocketPy's)
    "z-100hz-buttons": dict(
        BASE,
        rate=100.0,
        noise=(0.3, 0.2),
        seed=61,
        buttons=True,
        header=("time", "altitude", "acceleration"),
    ),
    # l395-eng-50hz's log, its rocket file with the fixtures' geometry for
    # `rocket fit --attitude` (fitted by hand, not by `run`)
    "l395-eng-50hz-geometry": dict(
        BASE,
        motor="L395",
        altitude="Pa",
        team_drag=True,
        seed=65,
        geometry=True,
        header=("time_s", "pressure_pa", "accel_m_s2"),
    ),
    # the rocket 0.4 kg heavier than its file says, 100 Hz
    "mass04-100hz": dict(
        BASE,
        rate=100.0,
        mass_error=0.4,
        noise=(0.5, 0.3),
        seed=71,
        header=("time", "altitude", "acceleration"),
    ),
}


def _environment(spec):
    from rocketpy import Environment

    env = Environment(**SITE)  # its standard atmosphere
    u, v = spec["wind"]
    if u or v:
        env.set_atmospheric_model(
            type="custom_atmosphere",
            wind_u=[(0, u), (10000, u)],
            wind_v=[(0, v), (10000, v)],
        )
    return env


def _motor(spec, folder):
    from make_rocket_fixtures import THRUST
    from rocketpy import GenericMotor

    common = dict(
        chamber_radius=0.0375,
        chamber_height=0.5,
        chamber_position=0.25,
        nozzle_radius=0.03,
        dry_inertia=(0.05, 0.05, 0.002),
        center_of_dry_mass_position=0.25,
    )
    if spec["motor"] == "L395":
        eng = folder / "L395.eng"
        lines = [
            "; Cesaroni L395 long burn (RocketPy's collection)",
            "L395 75 757 P 2.218 5.706 CTI",
        ]
        lines += [f"{t} {f}" for t, f in L395]
        eng.write_text("\n".join(lines) + "\n;\n")
        motor = GenericMotor.load_from_eng_file(
            str(eng), dry_mass=5.706 - 2.218, **common
        )
        return motor, dict(file="L395.eng", propellant=2.218, dry=5.706 - 2.218)
    flown = THRUST.copy()
    flown[:, 1] *= spec["scale"]
    np.savetxt(
        folder / "motor.csv",
        THRUST,
        delimiter=",",
        fmt="%.4f",
        header="time_s,thrust_N",
        comments="",
    )
    motor = GenericMotor(
        thrust_source=flown,
        burn_time=3.8,
        propellant_initial_mass=1.9,
        dry_mass=1.6,
        **common,
    )
    return motor, dict(file="motor.csv", propellant=1.9, dry=1.6)


def fly_one(name, spec, out):
    """Fly `spec` in RocketPy and write `out/name`: log.csv, rocket.toml, the motor's
    file, truth.json, planted_drag.csv (and team_drag.csv where the team has one)."""
    from make_rocket_fixtures import baro_altitude, first_order_lag, fixtures_rocket
    from rocketpy import Flight

    folder = out / name
    folder.mkdir(parents=True, exist_ok=True)
    env = _environment(spec)
    motor, motor_file = _motor(spec, folder)
    rocket = fixtures_rocket(motor, CURVE, mass=8.2 + spec["mass_error"])
    fl = Flight(
        rocket=rocket,
        environment=env,
        terminate_on_apogee=False,
        max_time=90.0,
        max_time_step=0.01,
        **RAIL,
    )
    mach = np.round(np.arange(0.0, 1.2001, 0.01), 2)
    cd = np.array([float(rocket.power_off_drag(m)) for m in mach])
    np.savetxt(
        folder / "planted_drag.csv",
        np.column_stack([mach, cd]),
        delimiter=",",
        fmt="%.5f",
    )
    if spec["team_drag"]:
        np.savetxt(
            folder / "team_drag.csv",
            np.column_stack([mach, 1.08 * cd]),
            delimiter=",",
            fmt="%.4f",
            header="mach,cd",
            comments="",
        )

    rate = spec["rate"]
    dt = 1.0 / rate
    apogee_t = float(fl.apogee_time)
    t = np.arange(0.0, min(apogee_t + 3.0, float(fl.t_final)), dt)
    rng = np.random.default_rng(spec["seed"])
    elev = SITE["elevation"]
    z = np.array([fl.z(s) for s in t])
    # the pad before ignition: the logger's own samples
    n_pad = int(round(spec["pad_s"] * rate))
    t_log = np.concatenate([np.arange(n_pad) * dt, n_pad * dt + t])
    z_all = np.concatenate([np.full(n_pad, z[0]), z])
    speed = np.array([fl.free_stream_speed(s) for s in t])
    rho = np.array([env.density(h) for h in z])
    q = np.concatenate([np.zeros(n_pad), 0.5 * rho * speed**2])
    kind = spec["altitude"]
    noise_m = spec["noise"][0]
    if kind == "z":
        alt = z_all - elev
        if spec["lag"]:
            alt = first_order_lag(alt, dt, spec["lag"])
        baro = alt + rng.normal(0, noise_m, len(alt))
    else:
        p = np.array([env.pressure(h) for h in z_all]) + spec["static"] * q
        if spec["lag"]:
            p = first_order_lag(p, dt, spec["lag"])
        if kind == "baro":
            h = baro_altitude(p) - baro_altitude(env.pressure(elev))
            baro = h + rng.normal(0, noise_m, len(h))
        else:
            # the altitude noise as pressure noise at the pad (dp/dh = -rho g)
            sd = noise_m * float(env.density(elev)) * G0
            p = p + rng.normal(0, sd, len(p))
            baro = p / 100.0 if kind == "hPa" else p
    columns = [t_log, baro]
    fmts = [
        "%.4f" if rate > 100 else "%.3f",
        {"z": "%.2f", "baro": "%.2f", "Pa": "%.1f", "hPa": "%.3f"}[kind],
    ]
    if spec["accel"]:
        acc = np.array([[fl.ax(s), fl.ay(s), fl.az(s)] for s in t])
        e0, e1, e2, e3 = (
            np.array([getattr(fl, f"e{i}")(s) for s in t]) for i in range(4)
        )
        axis = np.stack(
            [2 * (e1 * e3 + e0 * e2), 2 * (e2 * e3 - e0 * e1), 1 - 2 * (e1**2 + e2**2)],
            axis=1,
        )
        g = np.array([env.gravity(h) for h in z])
        f = np.einsum("ij,ij->i", acc, axis) + g * axis[:, 2]
        f_pad = np.full(n_pad, f[0])
        f = np.concatenate([f_pad, f]) + rng.normal(0, spec["noise"][1], n_pad + len(t))
        if spec["accel"] == "g":
            columns.append(f / G0)
            fmts.append("%.4f")
        else:
            columns.append(f)
            fmts.append("%.3f")
    np.savetxt(
        folder / "log.csv",
        np.column_stack(columns),
        delimiter=",",
        fmt=fmts,
        header=",".join(spec["header"]),
        comments="",
    )
    if spec.get("gnss"):
        write_gnss(folder / "log.csv", fl, t_log, n_pad, dt, spec, rng)

    aero = ""
    if spec["team_drag"]:
        aero = '\n[aero]\npower_off_drag_file = "team_drag.csv"\n'
    buttons = ""
    if spec.get("buttons"):
        buttons = "rail_buttons_m = [1.1, 0.3]\n\n[geometry]\nnozzle_position_m = 0.0\n"
    if spec.get("geometry"):
        # the fixtures' airframe; the L395 loaded at the chamber's centre, its
        # lateral inertia the casing's 0.05 and a propellant cylinder's
        buttons = (
            "I11_kgm2 = 4.4\ncenter_of_mass_without_motor_m = 1.2\n"
            "rail_buttons_m = [1.1, 0.3]\n\n[geometry]\n"
            'nose = { kind = "vonKarman", length_m = 0.52, position_m = 2.72 }\n'
            "fins = { n = 4, span_m = 0.1, root_chord_m = 0.2, tip_chord_m = 0.07, "
            "position_m = 0.21 }\nmotor_center_of_mass_m = 0.25\n"
            "nozzle_position_m = 0.0\nmotor_inertia_kgm2 = 0.097\n"
        )
    lat = f"latitude_deg = {SITE['latitude']}\n" if spec["latitude"] else ""
    (folder / "rocket.toml").write_text(f"""\
name = "{name}"

[rocket]
mass_without_motor_kg = 8.2
radius_m = 0.052
{buttons}
[motor]
thrust_file = "{motor_file["file"]}"
propellant_initial_mass_kg = {motor_file["propellant"]:.3f}
dry_mass_kg = {motor_file["dry"]:.3f}
{aero}
[launch]
elevation_m = {elev:g}
rail_length_m = {RAIL["rail_length"]:g}
inclination_deg = {RAIL["inclination"]:g}
heading_deg = {RAIL["heading"]:g}
{lat}
[log]
file = "log.csv"
""")
    truth = dict(
        spec,
        wind=list(spec["wind"]),
        apogee_time_s=apogee_t + spec["pad_s"],
        apogee_geometric_agl_m=float(fl.apogee) - elev,
        max_mach=float(fl.max_mach_number),
        ignition_s=spec["pad_s"],
    )
    (folder / "truth.json").write_text(json.dumps(truth, indent=1) + "\n")
    print(
        name,
        "apogee",
        round(fl.apogee - elev, 1),
        "at",
        round(apogee_t, 2),
        "max Mach",
        round(fl.max_mach_number, 3),
        flush=True,
    )


def wgs84_of(east, north, up):
    """Latitude and longitude (deg) on the WGS84 ellipsoid of points `east`,
    `north`, `up` m in the frame tangent to it at the pad (`SITE`), as a receiver
    reports them (RocketPy's own `latitude`, `longitude` are on a sphere): the
    points' Earth-centred coordinates, then Bowring's latitude, iterated."""
    a, f = 6_378_137.0, 1 / 298.257223563
    e2 = f * (2 - f)
    lat0, lon0 = np.radians(SITE["latitude"]), np.radians(SITE["longitude"])
    n0 = a / np.sqrt(1 - e2 * np.sin(lat0) ** 2)
    h0 = SITE["elevation"]
    origin = np.array(
        [
            (n0 + h0) * np.cos(lat0) * np.cos(lon0),
            (n0 + h0) * np.cos(lat0) * np.sin(lon0),
            (n0 * (1 - e2) + h0) * np.sin(lat0),
        ]
    )
    sl, cl, so, co = np.sin(lat0), np.cos(lat0), np.sin(lon0), np.cos(lon0)
    x = origin[0] - so * east - sl * co * north + cl * co * up
    y = origin[1] + co * east - sl * so * north + cl * so * up
    z = origin[2] + cl * north + sl * up
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1 - e2))
    for _ in range(10):
        n = a / np.sqrt(1 - e2 * np.sin(lat) ** 2)
        h = p / np.cos(lat) - n
        lat = np.arctan2(z, p * (1 - e2 * n / (n + h)))
    return np.degrees(lat), np.degrees(np.arctan2(y, x))


def write_gnss(path, fl, t_log, n_pad, dt, spec, rng):
    """Two columns `latitude`, `longitude` (deg) added to the log at `path`: a
    GNSS receiver's fixes every `1 / rate` s (`spec["gnss"] = (rate Hz, noise m)`)
    of RocketPy's own latitude and longitude (with `spec["gnss_wgs84"]`, its `x`,
    `y`, `z` on the WGS84 ellipsoid instead: `wgs84_of`), each with white noise of
    `noise` m
    per axis (turned into degrees on a sphere of 6371 km), the rows between fixes
    empty, as a flight computer writes a slower channel. On the pad before
    ignition the pad's fix. Drawn after every other channel's noise, so that the
    other channels are those of the flight without GNSS."""
    rate, noise = spec["gnss"]
    every = max(1, int(round(1.0 / (rate * dt))))
    rows = np.arange(0, len(t_log), every)
    flown = np.clip(t_log[rows] - n_pad * dt, 0.0, None)  # RocketPy's time
    if spec.get("gnss_wgs84"):
        lat, lon = wgs84_of(
            np.array([fl.x(s) for s in flown]),
            np.array([fl.y(s) for s in flown]),
            np.array([fl.z(s) for s in flown]) - SITE["elevation"],
        )
    else:
        lat = np.array([float(fl.latitude(s)) for s in flown])
        lon = np.array([float(fl.longitude(s)) for s in flown])
    radius = 6_371_000.0
    lat = lat + np.degrees(rng.normal(0, noise, len(rows)) / radius)
    lon = lon + np.degrees(
        rng.normal(0, noise, len(rows)) / (radius * np.cos(np.radians(lat)))
    )
    cells = [",,"] * len(t_log)
    for i, a, b in zip(rows, lat, lon, strict=True):
        cells[i] = f",{a:.8f},{b:.8f}"
    lines = path.read_text().splitlines()
    out = [lines[0] + ",latitude,longitude"]
    out += [line + c for line, c in zip(lines[1:], cells, strict=True)]
    path.write_text("\n".join(out) + "\n")


def cli(*args):
    """`diffpegasus ARGS --json` under `nice -n 10` (the other-airframe
    experiment's)."""
    return other_airframe.cli(*args, nice=True)


def coverage(summary, folder, top):
    """The planted CD against the fit's band at each knot of its table up to `top`
    (the other-airframe experiment's, from `planted_drag.csv`)."""
    return other_airframe.coverage(summary, folder, top, drag="planted_drag.csv")


def expected(truth):
    """The effects diagnose should name on this flight (words its names contain)."""
    out = []
    if truth["scale"] != 1.0:
        out.append("thrust scale")
    if truth["mass_error"]:
        out.append("mass error")
    if truth["lag"]:
        out.append("barometer lag")
    if truth["static"]:
        out.append("static-pressure error")
    u, v = truth["wind"]
    if abs(np.dot([u, v], ALONG)) > 1.0:
        out.append("wind")  # a cross wind is not nameable from these channels
    return out


def verdict(truth, named):
    exp = expected(truth)
    found = [e for e in exp if any(e in n for n in named)]
    extra = [n for n in named if not any(e in n for e in exp)]
    if found == exp and not extra:
        return "yes"
    if found:
        return "partly: also " + ", ".join(extra) if extra else "partly"
    return "no" + (": " + ", ".join(extra) if extra else ": nothing named")


def run(flights, names):
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    for name in names:
        folder = flights / name
        truth = json.loads((folder / "truth.json").read_text())
        figures = flights / f"{name}-fit"
        toml = str(folder / "rocket.toml")
        fit = cli("rocket", "fit", toml, "--out", str(figures))
        diag = cli("rocket", "diagnose", toml)
        row = dict(planted=truth, fit_cli=fit, diagnose_cli=diag)
        path = figures / "summary.json"
        if "error" not in fit and path.exists():
            summary = json.loads(path.read_text())
            knots = coverage(summary, folder, truth["max_mach"])
            row.update(
                knots=knots,
                inside=sum(k["inside"] for k in knots),
                inside_noise=sum(k["inside_noise"] for k in knots),
                points=len(knots),
                apogee_logged_m=summary["apogee_logged_m"],
                apogee_reconstructed_m=summary["apogee_reconstructed_m"],
                apogee_error_m=summary["apogee_reconstructed_m"]
                - summary["apogee_logged_m"],
                apogee_true_m=truth["apogee_geometric_agl_m"],
                altitude_rms_m=summary["altitude_rms_m"],
                altitude_rms_pct=summary["altitude_rms_pct_of_apogee"],
                converged=summary["converged"],
                estimates=summary.get("estimates"),
            )
        if "error" not in diag:
            row["named"] = diag.get("named")
            row["right"] = verdict(truth, diag.get("named") or [])
        results[name] = row
        RESULTS.parent.mkdir(parents=True, exist_ok=True)
        RESULTS.write_text(json.dumps(results, indent=1, default=str) + "\n")
        print(
            name,
            "fit",
            "error" if "error" in fit else "ok",
            round(fit["seconds"]),
            "s; inside",
            row.get("inside"),
            "of",
            row.get("points"),
            "apogee error",
            row.get("apogee_error_m"),
            "; diagnose",
            row.get("named", "error"),
            round(diag["seconds"]),
            "s",
            row.get("right"),
            flush=True,
        )


def planted(truth):
    """The planted effects of a flight in words."""
    out = []
    if truth["scale"] != 1.0:
        out.append(f"thrust scale {truth['scale']:g}")
    if truth["mass_error"]:
        out.append(f"{truth['mass_error']:+g} kg of mass")
    if truth["lag"]:
        out.append(f"barometer lag {truth['lag']:g} s")
    if truth["static"]:
        out.append(f"static-pressure error {truth['static']:g}")
    u, v = truth["wind"]
    if u or v:
        along = float(np.dot([u, v], ALONG))
        kind = "tail" if along > 1.0 else "cross"
        out.append(f"{kind} wind {np.hypot(u, v):g} m/s")
    return ", ".join(out) or "nothing"


def table():
    """The page's table: every flight of the results, and where `burn-held` ran,
    what diagnose names with the burn's length held at the full fit's estimate."""
    burn_path = RESULTS.with_name("rocket_outsider_sweep_burn.json")
    burn = json.loads(burn_path.read_text()) if burn_path.exists() else {}
    # the diagnosis as it stands: `rocket diagnose FOLDER/rocket.toml --json` again
    now_path = RESULTS.with_name("rocket_outsider_sweep_diagnose.json")
    now = json.loads(now_path.read_text()) if now_path.exists() else {}
    rows = [
        "| flight | written as | planted | CD knots inside the 95% band "
        "(noise's band alone) | apogee: fit - log's (- RocketPy's) m | altitude RMS "
        "m | fit / diagnose s | named: statistic (threshold), as the diagnosis "
        "stands | right? | as first run: the burn's start; named with the fit's "
        "burn held |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in json.loads(RESULTS.read_text()).items():
        t = r["planted"]
        unit = {"z": "z (m)", "baro": "baro altitude (m)"}.get(t["altitude"])
        written = unit or f"pressure ({t['altitude']})"
        written += f", accel ({t['accel']})" if t["accel"] else ""
        written += f", {t['rate']:g} Hz, noise {t['noise'][0]:g} m"
        written += f", {t['pad_s']:g} s of pad" if t["pad_s"] else ", from ignition"
        if t["motor"] != "fixture":
            written += f", {t['motor']} .eng"
        if t["team_drag"]:
            written += ", team's CD"
        if t.get("buttons"):
            written += ", rail buttons"
        fit, diag = r["fit_cli"], r["diagnose_cli"]
        if "knots" in r:
            inside = f"{r['inside']} of {r['points']} ({r['inside_noise']})"
            apo = (
                f"{r['apogee_error_m']:+.1f} "
                f"({r['apogee_reconstructed_m'] - r['apogee_true_m']:+.1f})"
            )
            rms = f"{r['altitude_rms_m']:.2f}"
        else:
            inside = apo = rms = "error" if "error" in fit else "-"
        if name in now:
            named, named_text = other_airframe.judged(now[name])
            right = verdict(t, named)
        else:
            named, right = r.get("named"), "-"
            named_text = "not re-run"
        held = "-"
        if name in burn:
            b = burn[name]
            held = (
                f"{b['start']['burn_scale']:.2f}; "
                + ("; ".join(b["fit"]["named"]) or "nothing")
                + f" (thrust {b['fit']['thrust_statistic']:.1f} against "
                f"{b['fit']['thrust_threshold']:.1f})"
            )
        rows.append(
            f"| {name} | {written} | {planted(t)} | {inside} | {apo} | {rms} | "
            f"{fit['seconds']:.0f} / {diag['seconds']:.0f} | {named_text} | "
            f"{right} | {held} |"
        )
    print("\n".join(rows))


def burn_held(flights, names):
    """Diagnose each flight as `rocket diagnose` does, and again with the burn's
    length held at the full fit's estimate (`FOLDER-fit/summary.json`) instead of
    the accelerometer's equation-error reading (the problem's start, on a grid of
    0.01): is that start what names a thrust scale on the clean flights? Into
    experiments/results/rocket_outsider_sweep_burn.json."""
    import diffpegasus as dp
    import diffpegasus.rocket as dr
    from diffpegasus._rocket._diagnose import diagnose

    path = RESULTS.with_name("rocket_outsider_sweep_burn.json")
    results = json.loads(path.read_text()) if path.exists() else {}
    for name in names:
        toml = flights / name / "rocket.toml"
        problem = dr.prepare(dr.read_rocket(toml), dp.read_rocket_log(toml))
        summary = json.loads((flights / f"{name}-fit" / "summary.json").read_text())
        row = {}
        for label, burn in (
            ("start", problem.start["burn_scale"]),
            ("fit", summary["estimates"]["burn_scale"][0]),
        ):
            problem.start["burn_scale"] = burn
            named, rows, _ = diagnose(problem)
            thrust = next(r for r in rows if r["candidate"].startswith("thrust"))
            row[label] = dict(
                burn_scale=burn,
                named=named,
                thrust_statistic=thrust["statistic"],
                thrust_threshold=thrust["threshold"],
            )
            print(
                name,
                label,
                round(burn, 5),
                named,
                round(thrust["statistic"], 1),
                round(thrust["threshold"], 1),
                flush=True,
            )
        results[name] = row
        path.write_text(json.dumps(results, indent=1, default=str) + "\n")


def main():
    cmd = sys.argv[1]
    if cmd == "table":
        return table()
    out = pathlib.Path(sys.argv[2])
    names = sys.argv[3:] or list(FLIGHTS)
    if cmd == "fly":
        for name in names:
            fly_one(name, FLIGHTS[name], out)
    elif cmd == "run":
        run(out, names)
    elif cmd == "burn-held":
        burn_held(out, names)


if __name__ == "__main__":
    main()
