"""Simulated rocket flights from RocketPy (an independent 6-DOF simulator) for the
rocket tests and the validation benchmark.

Each flight gets a folder under tests/data/rocket_sim/<name>/ with `rocket.toml` (the
facts, the planted truth under [truth]), `motor.csv`, `drag.csv` (the planted
power-off curve as RocketPy flies it: RocketPy turns a list of (Mach, CD) points into a
cubic spline, not straight lines between them, which runs up to 3.4% below the lines
between Mach 0.6 and 0.8 of the curves here; the file holds that spline every 0.01
Mach, so that straight lines between its points are the flown curve within 1.2e-4) and `log.csv` (time s, barometric altitude m above the pad as a
flight computer computes it from static pressure with the standard atmosphere,
axial specific force m/s^2 with gravity included), sampled at 50 Hz (or the flight's `rate`) to apogee; the `rocket.toml`'s `[log]` maps
its columns and states its time zero and its apogee (the last row) for the library's reader.

Planted effects per flight: a drag curve, a thrust scale (the motor file holds the
catalogue curve, RocketPy flies the scaled one), constant wind, barometer lag
(first-order), static-pressure error (per dynamic pressure) and white noise on both
channels. Run: `python scripts/make_rocket_fixtures.py` (RocketPy from PyPI); with
`--validation DIR` it writes the benchmark's further flights (`VALIDATION`) to DIR;
`--held-out DIR` three flights no choice of the drag band was tuned on (`HELD_OUT`),
`--held-out-2 DIR` two more, written before the sensor-by-sensor band was run
(`HELD_OUT_2`);
`--validation DIR --smooth` the committed two and those, each through the exact
standard-atmosphere pressure instead of RocketPy's table (`clean-smooth`'s option);
`--gyro DIR [NAME ...]` flights with a fourth column, the lateral body rate (rad/s)
two gyros across the axis read;
`--descent DIR [NAME ...]` flights that go on under a drogue (deployed at apogee) and a main
(at its altitude) for `duration` s after liftoff (`DESCENT`; the rocket.toml lists
the parachutes' CdS and the main's altitude, and the log the descent).
"""

import pathlib

import numpy as np


OUT = pathlib.Path(__file__).resolve().parents[1] / "tests" / "data" / "rocket_sim"
G0 = 9.80665

# catalogue thrust curve of a 75 mm L motor (rounded points of a public RASP file)
THRUST = np.array(
    [
        [0.0, 0.0],
        [0.02, 50],
        [0.05, 200],
        [0.09, 1110],
        [0.14, 1250],
        [0.25, 1211],
        [0.9, 1220],
        [1.2, 1280],
        [2.0, 1150],
        [2.6, 1000],
        [3.0, 900],
        [3.3, 700],
        [3.5, 300],
        [3.8, 0.0],
    ]
)

FLIGHTS = {
    # name: drag curve (Mach, CD), thrust scale, wind (u east, v north) m/s,
    # baro lag s, static-pressure error, noise (altitude m, accel m/s^2), seed
    "clean": dict(
        drag=[
            (0.0, 0.50),
            (0.3, 0.46),
            (0.6, 0.45),
            (0.8, 0.50),
            (0.9, 0.58),
            (1.2, 0.70),
        ],
        scale=1.0,
        wind=(0.0, 0.0),
        lag=0.0,
        static=0.0,
        noise=(0.5, 0.3),
        seed=1,
    ),
    "planted": dict(
        drag=[
            (0.0, 0.62),
            (0.3, 0.55),
            (0.6, 0.50),
            (0.8, 0.55),
            (0.9, 0.66),
            (1.2, 0.80),
        ],
        scale=0.94,
        wind=(6.0, -3.0),
        lag=0.15,
        static=0.04,
        noise=(1.0, 0.5),
        seed=2,
    ),
}


# More flights for the validation benchmark (not committed; written where asked):
# other seeds and drag curves, each effect alone, and 20 Hz logs.
CURVE_B = [
    (0.0, 0.40),
    (0.25, 0.38),
    (0.5, 0.41),
    (0.7, 0.44),
    (0.85, 0.55),
    (1.2, 0.75),
]
CURVE_C = [
    (0.0, 0.70),
    (0.3, 0.58),
    (0.6, 0.52),
    (0.75, 0.53),
    (0.9, 0.62),
    (1.2, 0.78),
]
VALIDATION = {
    "clean-s3-20hz": dict(FLIGHTS["clean"], seed=3, rate=20.0),
    "clean-smooth": dict(FLIGHTS["clean"], smooth_pressure=True),
    "curve-b-s4": dict(FLIGHTS["clean"], drag=CURVE_B, seed=4),
    "curve-c-s5-20hz": dict(
        FLIGHTS["clean"], drag=CURVE_C, noise=(1.0, 0.5), seed=5, rate=20.0
    ),
    "wind-s6": dict(FLIGHTS["clean"], drag=CURVE_B, wind=(-5.0, 5.0), seed=6),
    "thrust-s7-20hz": dict(
        FLIGHTS["clean"], drag=CURVE_C, scale=1.05, seed=7, rate=20.0
    ),
    "sensors-s8": dict(
        FLIGHTS["clean"], lag=0.15, static=0.04, noise=(1.0, 0.5), seed=8
    ),
    "planted-s9-20hz": dict(FLIGHTS["planted"], seed=9, rate=20.0),
}

# Held out from every choice of the band (written once the band was fixed): other
# drag curves, seeds, winds, rates and noise than the flights above.
CURVE_D = [
    (0.0, 0.55),
    (0.2, 0.50),
    (0.45, 0.47),
    (0.65, 0.48),
    (0.85, 0.60),
    (1.2, 0.72),
]
HELD_OUT = {
    "heldout-d-s21-25hz": dict(
        FLIGHTS["clean"],
        drag=CURVE_D,
        wind=(3.0, 4.0),
        noise=(0.7, 0.4),
        seed=21,
        rate=25.0,
    ),
    "heldout-c-s22": dict(
        FLIGHTS["clean"], drag=CURVE_C, scale=0.97, wind=(0.0, -6.0), seed=22
    ),
    "heldout-b-s23-40hz": dict(
        FLIGHTS["clean"], drag=CURVE_B, lag=0.08, noise=(0.8, 0.6), seed=23, rate=40.0
    ),
}

# Held out from the sensor-by-sensor refit of the band (written before it was run on
# anything): another drag curve, seeds, winds, rates, thrust and sensor errors.
CURVE_E = [
    (0.0, 0.48),
    (0.35, 0.43),
    (0.55, 0.44),
    (0.75, 0.49),
    (0.95, 0.64),
    (1.2, 0.74),
]
HELD_OUT_2 = {
    "heldout-e-s31-30hz": dict(
        FLIGHTS["clean"],
        drag=CURVE_E,
        scale=1.03,
        wind=(-4.0, -3.0),
        noise=(0.6, 0.35),
        seed=31,
        rate=30.0,
    ),
    "heldout-e-s32-50hz": dict(
        FLIGHTS["clean"],
        drag=CURVE_E,
        wind=(2.0, 7.0),
        lag=0.1,
        static=0.03,
        noise=(0.9, 0.45),
        seed=32,
        rate=50.0,
    ),
}


# Under parachutes: RocketPy's drogue at apogee and main at 300 m, no deployment lag
# (drogue CdS 0.25 m^2: about 27 m/s near the ground; main 2.5 m^2: about 8.5 m/s),
# logged to 135 s (the main opens at 117 s, about 150 m above the pad at the end); the clean one's barometer reads
# RocketPy's standard-atmosphere table like `curve-c-s5-20hz`'s
CHUTES = ((0.25, "apogee"), (2.5, 300.0))
DESCENT = {
    # `curve-c-s5-20hz`'s seed: its barometer's noise over the ascent is that
    # flight's (the first draws); the accelerometer's differs
    "descent-c-s5-20hz": dict(
        VALIDATION["curve-c-s5-20hz"], chutes=CHUTES, duration=135.0
    ),
    "descent-lag-c-s42-20hz": dict(
        VALIDATION["curve-c-s5-20hz"],
        lag=0.15,
        seed=42,
        chutes=CHUTES,
        duration=135.0,
    ),
    # each canopy full a stated time after its event (RocketPy's `lag`): the drogue
    # 1 s after apogee, the main 2.5 s after it is triggered at 300 m, within the
    # 3 s the descent's fit leaves out after each event
    "descent-open-c-s9-20hz": dict(
        VALIDATION["curve-c-s5-20hz"],
        seed=9,
        chutes=((0.25, "apogee", 1.0), (2.5, 300.0, 2.5)),
        duration=135.0,
    ),
}


def _isa_pressure(h):
    """Pa, the standard atmosphere's troposphere at geometric height `h` m."""
    hg = 6_356_766.0 * h / (6_356_766.0 + h)
    return 101325.0 * (1 - 0.0065 * hg / 288.15) ** (9.80665 / (287.05287 * 0.0065))


def baro_altitude(p):
    """m, a flight computer's standard-atmosphere altitude of pressure `p` (Pa; any
    shape): the fixtures' barometer conversion."""
    return 44330.77 * (1 - (p / 101325.0) ** 0.190263)


def baro_pressure(h):
    """Pa, the inverse of `baro_altitude` at altitude `h` (m; any shape)."""
    return 101325.0 * (1 - h / 44330.77) ** (1 / 0.190263)


LOG_HEADER = "time_s,altitude_m,accel_axial_m_s2"  # the columns rocket.toml maps


def write_log(folder, t, altitude, accel, fmt="%.4f"):
    """`folder/log.csv` in the simulated flights' layout (the `[log]` map their
    rocket.toml carries): time (s), barometric altitude (m above the pad), axial
    specific force (m/s^2)."""
    np.savetxt(
        folder / "log.csv",
        np.column_stack([t, altitude, accel]),
        delimiter=",",
        header=LOG_HEADER,
        comments="",
        fmt=fmt,
    )


def first_order_lag(x, dt, tau):
    """`x` (shape (n,), sampled every `dt` s) through a first-order lag of time
    constant `tau` s, exact for a piecewise-constant input; a new array."""
    y = np.array(x, dtype=float)
    k = np.exp(-dt / tau)
    for i in range(1, len(y)):
        y[i] = k * y[i - 1] + (1 - k) * y[i]
    return y


def lagged_baro(baro, pad, dt, tau):
    """A barometric altitude (m above the pad, shape (n,), every `dt` s) read
    through the fixtures' barometer lag: its standard-atmosphere pressure (the pad
    at elevation `pad` m) through `first_order_lag` of `tau` s, and back to metres
    above the pad."""
    p = first_order_lag(baro_pressure(np.asarray(baro) + pad), dt, tau)
    return baro_altitude(p) - pad


# the loaded motor's lateral inertia about its centre of mass: the casing's 0.05
# and the propellant as RocketPy's GenericMotor takes it, a cylinder of the
# chamber's radius 0.0375 m and height 0.5 m
MOTOR_INERTIA = round(0.05 + 1.9 * (3 * 0.0375**2 + 0.5**2) / 12, 4)


def fixtures_rocket(motor, drag, mass=8.2):
    """RocketPy's `Rocket` of the fixtures' airframe (the rocket.toml's `FACTS`):
    `motor` at the tail, `drag` (Mach, CD) pairs power on and off, `mass` kg
    without the motor."""
    from rocketpy import Rocket

    rocket = Rocket(
        radius=0.052,
        mass=mass,
        inertia=(4.4, 4.4, 0.015),
        power_off_drag=drag,
        power_on_drag=drag,
        center_of_mass_without_motor=1.2,
        coordinate_system_orientation="tail_to_nose",
    )
    rocket.add_motor(motor, position=0.0)
    rocket.add_nose(length=0.52, kind="von karman", position=2.72)
    rocket.add_trapezoidal_fins(
        n=4, root_chord=0.2, tip_chord=0.07, span=0.1, position=0.21
    )
    rocket.set_rail_buttons(1.1, 0.3)
    return rocket


def rocketpy_flight(spec):
    """RocketPy's environment, rocket and flight (to apogee) for a flight `spec`
    of `FLIGHTS`: the fixtures' rocket, motor, rail and site."""
    from rocketpy import Environment, Flight, GenericMotor

    flown = THRUST.copy()
    flown[:, 1] *= spec["scale"]
    env = Environment(
        latitude=SITE["latitude"], longitude=-8.29, elevation=SITE["elevation"]
    )
    u, v = spec["wind"]
    pressure = None
    if spec.get("smooth_pressure"):
        # RocketPy's standard-atmosphere pressure is a spline through 100 points
        # over 0-80 km (808 m apart): up to 3 m of barometric altitude off the
        # hydrostatic profile between them; the exact profile every 10 m instead
        heights = np.arange(-100.0, 8000.0, 10.0)
        pressure = np.column_stack([heights, [_isa_pressure(h) for h in heights]])
    env.set_atmospheric_model(
        type="custom_atmosphere",
        pressure=pressure,
        temperature=None,
        wind_u=[(0, u), (8000, u)],
        wind_v=[(0, v), (8000, v)],
    )
    motor = GenericMotor(
        thrust_source=flown,
        burn_time=3.8,
        chamber_radius=0.0375,
        chamber_height=0.5,
        chamber_position=0.25,
        propellant_initial_mass=1.9,
        nozzle_radius=0.03,
        dry_mass=1.6,
        dry_inertia=(0.05, 0.05, 0.002),
        center_of_dry_mass_position=0.25,
    )
    rocket = fixtures_rocket(motor, [tuple(p) for p in spec["drag"]])
    for k, (cds, trigger, *lag) in enumerate(spec.get("chutes", ())):
        rocket.add_parachute(f"chute{k}", cd_s=cds, trigger=trigger, lag=sum(lag))
    fl = Flight(
        rocket=rocket,
        environment=env,
        rail_length=SITE["rail_length"],
        inclination=SITE["inclination"],
        heading=SITE["heading"],
        terminate_on_apogee="chutes" not in spec,
        max_time=spec.get("duration", 600.0),
        # with overshooting time steps RocketPy 1.13 never checks a second
        # parachute once the first is out (the main stayed packed)
        time_overshoot="chutes" not in spec,
        max_time_step=0.01,
    )
    return env, rocket, fl


# the fixtures' pad (RocketPy's site and rail in `rocketpy_flight`, the rocket.toml's
# [launch]) and its facts for the rocket.toml ([rocket], [geometry], [motor])
SITE = dict(latitude=39.39, elevation=150, rail_length=12, inclination=84, heading=133)
FACTS = f"""\
[rocket]
mass_without_motor_kg = 8.2
radius_m = 0.052
I11_kgm2 = 4.4
center_of_mass_without_motor_m = 1.2
rail_buttons_m = [1.1, 0.3]

[geometry]
nose = {{ kind = "vonKarman", length_m = 0.52, position_m = 2.72 }}
fins = {{ n = 4, span_m = 0.1, root_chord_m = 0.2, tip_chord_m = 0.07, position_m = 0.21 }}
motor_center_of_mass_m = 0.25
nozzle_position_m = 0.0
motor_inertia_kgm2 = {MOTOR_INERTIA}

[motor]
thrust_file = "motor.csv"
propellant_initial_mass_kg = 1.9
dry_mass_kg = 1.6
"""


def write_motor(folder):
    """The fixtures' catalogue thrust curve as `motor.csv` (s, N)."""
    np.savetxt(folder / "motor.csv", THRUST, delimiter=",", fmt="%.4f")


def flight(
    name,
    spec,
    out=OUT,
    build=rocketpy_flight,
    facts=FACTS,
    motor=write_motor,
    site=SITE,
    source="scripts/make_rocket_fixtures.py",
):
    """Fly `spec` in RocketPy and write its folder `out/name` (`rocket.toml`, the
    motor's file, `drag.csv`, `log.csv`). By default the fixtures' rocket; another
    airframe gives `build(spec) -> (env, rocket, flight)`, its rocket.toml sections
    `facts` ([rocket], [geometry], [motor]), `motor(folder)` writing the motor's
    file, its pad `site` (latitude deg, elevation m, rail length m, inclination and
    heading deg, as `build` flies them) and the script named in the file's header."""
    folder = out / name
    folder.mkdir(parents=True, exist_ok=True)
    motor(folder)
    env, rocket, fl = build(spec)
    elevation = site["elevation"]
    u, v = spec["wind"]
    mach = np.round(np.arange(0.0, 1.2001, 0.01), 2)
    flown_cd = np.array([float(rocket.power_off_drag(m)) for m in mach])
    np.savetxt(
        folder / "drag.csv",
        np.column_stack([mach, flown_cd]),
        delimiter=",",
        fmt="%.5f",
    )
    dt = 1.0 / spec.get("rate", 50.0)
    end = fl.t_final if "chutes" in spec else fl.apogee_time
    t = np.arange(0.0, float(end), dt)
    rng = np.random.default_rng(spec["seed"])
    # static pressure at the rocket, the ports' error, then the flight computer's
    # standard-atmosphere altitude above the pad's reading
    z = np.array([fl.z(s) for s in t])
    p = np.array([env.pressure(h) for h in z])
    speed = np.array([fl.free_stream_speed(s) for s in t])
    rho = np.array([env.density(h) for h in z])
    p_read = p + spec["static"] * 0.5 * rho * speed**2
    if spec["lag"] > 0:
        p_read = first_order_lag(p_read, dt, spec["lag"])
    h_std = baro_altitude(p_read)
    pad = baro_altitude(env.pressure(elevation))
    alt = h_std - pad + rng.normal(0, spec["noise"][0], len(t))
    # specific force along the body axis: body z from the attitude quaternion
    acc = np.array([[fl.ax(s), fl.ay(s), fl.az(s)] for s in t])
    e0, e1, e2, e3 = (np.array([getattr(fl, f"e{i}")(s) for s in t]) for i in range(4))
    axis = np.stack(
        [2 * (e1 * e3 + e0 * e2), 2 * (e2 * e3 - e0 * e1), 1 - 2 * (e1**2 + e2**2)],
        axis=1,
    )
    g = np.array([env.gravity(h) for h in z])
    f = np.einsum("ij,ij->i", acc, axis) + g * axis[:, 2]
    f += rng.normal(0, spec["noise"][1], len(t))
    columns, header = [t, alt, f], LOG_HEADER
    if spec.get("gyro"):
        # two gyros across the axis (RocketPy's body rates w1, w2), each with white
        # noise of `gyro` rad/s, read as the lateral rate sqrt(w1^2 + w2^2); drawn
        # after the other channels' noise, which stays as without gyros
        w1, w2 = (np.array([getattr(fl, f"w{i}")(s) for s in t]) for i in (1, 2))
        w1 = w1 + rng.normal(0, spec["gyro"], len(t))
        w2 = w2 + rng.normal(0, spec["gyro"], len(t))
        columns.append(np.hypot(w1, w2))
        header += ",gyro_lateral_rad_s"
    fmt = "%.5f" if spec.get("gyro") else "%.3f"
    np.savetxt(
        folder / "log.csv",
        np.column_stack(columns),
        delimiter=",",
        fmt=fmt,
        header=header,
        comments="",
    )
    gyro_map = (
        'gyro_lateral = { column = "gyro_lateral_rad_s", unit = "rad/s" }\n'
        if spec.get("gyro")
        else ""
    )
    chutes = "".join(
        f'\n[[parachutes]]\nname = "chute{k}"\ncd_s_m2 = {cds}\n'
        + (
            f'trigger = "{trig}"\n'
            if isinstance(trig, str)
            else f"trigger_altitude_agl_m = {trig}\n"
        )
        + (f"lag_s = {lag[0]}\n" if lag else "")
        for k, (cds, trig, *lag) in enumerate(spec.get("chutes", ()))
    )
    if "chutes" in spec:
        # RocketPy's apogee and each parachute's trigger (its canopy full `lag_s`
        # later); the log goes on past them
        ends = "sampled through the descent to the flight's end"
        stated = f"apogee_s = {float(fl.apogee_time):.3f}\n" + "".join(
            f"{name}_s = {float(when):.3f}\n"
            for name, (when, _) in zip(
                ("drogue", "main"), fl.parachute_events, strict=True
            )
        )
    else:
        ends = "sampled to its apogee (the last row)"
        stated = f"apogee_s = {fmt % t[-1]}\n"
    (folder / "rocket.toml").write_text(f"""\
# A flight simulated by RocketPy {__import__("importlib.metadata").metadata.version("rocketpy")} ({source})
name = "sim-{name}"
coordinate_system = "tail_to_nose"

{facts}
[aero]
power_off_drag_file = "drag.csv"
power_on_drag_file = "drag.csv"

[launch]
latitude_deg = {site["latitude"]}
elevation_m = {elevation}
rail_length_m = {site["rail_length"]}
inclination_deg = {site["inclination"]}
heading_deg = {site["heading"]}

[atmosphere]
surface_temperature_K = {float(env.temperature(elevation)):.3f}

[log]
# RocketPy's export: its time from its start (the motor's ignition, which the fit's
# motor time places), {ends}
file = "log.csv"

[log.column_map]
time = {{ column = "time_s", unit = "s" }}
altitude = {{ column = "altitude_m", unit = "m" }}
accel_axial = {{ column = "accel_axial_m_s2", unit = "m/s^2", gravity = "included" }}
{gyro_map}
[log.stated_events]
liftoff_s = 0.0
{stated}
[results]
recorded_apogee_agl_m = {float(fl.apogee) - elevation:.2f}

[truth]
thrust_scale = {spec["scale"]}
wind_east_m_s = {u}
wind_north_m_s = {v}
baro_lag_s = {spec["lag"]}
static_error = {spec["static"]}
noise_altitude_m = {spec["noise"][0]}
noise_accel_m_s2 = {spec["noise"][1]}
apogee_geometric_agl_m = {float(fl.apogee) - elevation:.3f}
max_mach = {float(fl.max_mach_number):.4f}
{chutes}""")
    print(name, "apogee", fl.apogee - elevation, "max Mach", fl.max_mach_number)


if __name__ == "__main__":
    import sys

    if len(sys.argv) > 2 and sys.argv[1] == "--gyro":
        # the committed two, the head wind and a held-out one, with gyros
        # (0.003 rad/s of noise per axis, a MEMS gyro's at 50 Hz)
        every = {**FLIGHTS, **VALIDATION, **HELD_OUT}
        names = sys.argv[3:] or ["clean", "planted", "wind-s6", "heldout-c-s22"]
        for name in names:
            flight(name, dict(every[name], gyro=0.003), pathlib.Path(sys.argv[2]))
    elif len(sys.argv) > 2 and sys.argv[1] == "--descent":
        for name in sys.argv[3:] or DESCENT:
            flight(name, DESCENT[name], pathlib.Path(sys.argv[2]))
    elif len(sys.argv) > 2 and sys.argv[1] in ("--held-out", "--held-out-2"):
        held = HELD_OUT if sys.argv[1] == "--held-out" else HELD_OUT_2
        for name, spec in held.items():
            flight(name, spec, pathlib.Path(sys.argv[2]))
    elif len(sys.argv) > 2 and sys.argv[1] == "--validation":
        # `--smooth`: every flight (the committed two too) through the exact
        # standard-atmosphere pressure instead of RocketPy's table
        flights = VALIDATION
        if "--smooth" in sys.argv:
            flights = {
                name: dict(spec, smooth_pressure=True)
                for name, spec in {**FLIGHTS, **VALIDATION}.items()
                if name != "clean-smooth"  # `clean` is that flight here
            }
        for name, spec in flights.items():
            flight(name, spec, pathlib.Path(sys.argv[2]))
    else:
        for name, spec in FLIGHTS.items():
            flight(name, spec)
