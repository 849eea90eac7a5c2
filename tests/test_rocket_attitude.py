"""The rocket's attitude: Barrowman's normal-force slopes and centre of pressure
against closed form and RocketPy's own numbers, the restoring and damping moments
against their scalar formulas, and the weathercocking flight against RocketPy's."""

import pathlib
import tomllib

import jax
import jax.numpy as jnp
import numpy as np

import diffpegasus.rocket as dr
from diffpegasus import read_rocket_log
from diffpegasus._vehicle._rocket._barrowman import read_airframe

from .helpers import rocket_parameters


SIM = pathlib.Path(__file__).parent / "data" / "rocket_sim"


def test_barrowman_rectangular_fins_and_cone_in_closed_form():
    """Four rectangular fins (span = body diameter 0.1 m, chord 0.1 m, no sweep):
    Barrowman's `4 n (s/d)^2 / (1 + sqrt(1 + (2 l / (cr + ct))^2))` with `l` = span,
    `16 / (1 + sqrt 2)`, times the interference `1 + R/(s + R)` = 4/3, at the quarter
    chord; a conical nose's 2 at 2/3 of its length; incompressible (Mach 0)."""
    doc = {
        "coordinate_system": "nose_to_tail",
        "rocket": {"I11_kgm2": 1.0, "center_of_mass_without_motor_m": 0.6},
        "geometry": {
            "nose": {"kind": "conical", "length_m": 0.3, "position_m": 0.0},
            "fins": {
                "n": 4,
                "span_m": 0.1,
                "root_chord_m": 0.1,
                "tip_chord_m": 0.1,
                "sweep_length_m": 0.0,
                "position_m": 1.0,
            },
            "motor_center_of_mass_m": 0.9,
        },
    }
    frame = read_airframe(doc, "x.toml", 0.05)
    fins = 16 / (1 + np.sqrt(2)) * 4 / 3
    np.testing.assert_allclose(np.asarray(frame.cn_alpha(0.0)), [2.0, fins], rtol=1e-12)
    # nose_to_tail: metres forward are minus the positions
    np.testing.assert_allclose(frame.stations, [-0.2, -1.025], rtol=1e-12)
    cp = (2 * 0.2 + fins * 1.025) / (2 + fins)
    assert abs(frame.center_of_pressure(0.0) - -cp) < 1e-12
    # compressibility: only the fins' aspect-ratio term takes beta (Diederich)
    b = np.sqrt(1 - 0.6**2)
    aspect = 2.0  # 2 span^2 / area
    expected = 2 * np.pi * aspect * 0.01 / (np.pi * 0.05**2) * 2 * 4 / 3
    expected /= 2 + np.sqrt(4 + (b * aspect) ** 2)
    assert abs(float(frame.cn_alpha(0.6)[1]) - expected) < 1e-12


def test_barrowman_against_rocketpy_for_the_fixture_rocket():
    """The simulated flights' rocket (its rocket.toml [geometry]): RocketPy 1.13's
    `total_lift_coeff_der` and `cp_position` for the same geometry (printed by
    scripts/make_rocket_fixtures.py's `rocketpy_flight`: 10.504949, 10.924766,
    11.313050 per rad; 0.564755, 0.547628, 0.532919 m at Mach 0, 0.6, 0.8)."""
    # the attitude is asked for: by default the same file flies as a point mass
    assert dr.read_rocket(SIM / "clean" / "rocket.toml").airframe is None
    frame = dr.read_rocket(SIM / "clean" / "rocket.toml", attitude=True).airframe
    for mach, cna, cp in (
        (0.0, 10.504949, 0.564755),
        (0.6, 10.924766, 0.547628),
        (0.8, 11.313050, 0.532919),
    ):
        assert abs(float(jnp.sum(frame.cn_alpha(mach))) - cna) < 1e-5
        assert abs(frame.center_of_pressure(mach) - cp) < 1e-5


CALISTO = """\
coordinate_system = "tail_to_nose"

[rocket]
mass_without_motor_kg = 14.426
radius_m = 0.0635
I11_kgm2 = 6.321
center_of_mass_without_motor_m = 0.0

[geometry]
nose = { kind = "vonKarman", length_m = 0.55829, position_m = 1.278 }
fins = { n = 4, span_m = 0.11, root_chord_m = 0.12, tip_chord_m = 0.06, position_m = -1.04956 }
tail = { top_radius_m = 0.0635, bottom_radius_m = 0.0435, length_m = 0.06, position_m = -1.194656 }
motor_center_of_mass_m = -0.8884

[motor]
thrust_file = "motor.eng"
propellant_initial_mass_kg = 2.9559
dry_mass_kg = 1.815

[launch]
elevation_m = 1400
rail_length_m = 5.2
inclination_deg = 85
heading_deg = 0
"""


def test_barrowman_against_rocketpy_for_calisto(tmp_path):
    """RocketPy's documented example rocket (Calisto: another body, nose and fins
    than the fixtures', below the rocket's centre of mass without motor, and a boat
    tail): RocketPy 1.13's `total_lift_coeff_der` and `cp_position` for that
    geometry, 7.211108, 7.703326, 8.206127 per rad; -0.499426, -0.537773, -0.572194
    m at Mach 0, 0.6, 0.8. The rocket file is copied by hand from the geometry
    experiments/rocket_other_airframe.py writes, not its whole file: no cant, rail
    buttons, nozzle position or motor inertia, and the motor's centre of mass
    written as a number; the lift slope and centre of pressure depend on none of
    them."""
    (tmp_path / "motor.eng").write_text(
        "M1670 75 757 0 3.101 5.231 CTI\n0.1 2000\n3.0 1650\n3.9 0\n"
    )
    (tmp_path / "rocket.toml").write_text(CALISTO)
    frame = dr.read_rocket(tmp_path / "rocket.toml", attitude=True).airframe
    for mach, cna, cp in (
        (0.0, 7.211108, -0.499426),
        (0.6, 7.703326, -0.537773),
        (0.8, 8.206127, -0.572194),
    ):
        # the references are rounded to 1e-6; measured within 4.4e-7 and 5.0e-7 m
        assert abs(float(jnp.sum(frame.cn_alpha(mach))) - cna) < 1e-6
        assert abs(frame.center_of_pressure(mach) - cp) < 1e-6


def test_restoring_and_damping_moments_against_their_scalar_formulas():
    """Off the rail at 200 m/s, burned out, the axis 2 deg off the velocity: the
    angular acceleration is `q S sum(CNa_i l_i) sin(a) / I` turning the axis towards
    the velocity (`l_i` the station's distance ahead of the centre of mass: negative
    behind it); the axis along the velocity and turning at 0.5 rad/s: `-(rho V S / 2)
    sum(CNa_i l_i^2) w / I` (the pitch damping), both with the burned-out centre of
    mass and inertia by the parallel-axis theorem."""
    rocket = dr.read_rocket(SIM / "clean" / "rocket.toml", attitude=True)
    frame = rocket.airframe
    knots = dr.DragKnots((0.1, 0.5, 0.9))
    flight = dr.Flight(rocket, knots, 101325.0)
    p = rocket_parameters(flight, motor_time=-100.0)  # long burned out
    p = {k: jnp.asarray(v) for k, v in p.items()}
    m_r, m_m = rocket.dry_mass - rocket.motor.dry_mass, rocket.motor.dry_mass
    cg = (m_r * frame.cg_rocket + m_m * frame.motor_cg) / (m_r + m_m)
    inertia = (
        frame.inertia
        + m_r * (frame.cg_rocket - cg) ** 2
        + frame.motor_inertia
        + m_m * (frame.motor_cg - cg) ** 2
    )
    arm = np.asarray(frame.stations) - cg
    a = np.radians(2.0)
    v = 200.0
    x = np.zeros(12)
    x[:3] = [0.0, 0.0, 1000.0]
    x[3:6] = [0.0, 0.0, v]
    x[6:9] = [np.sin(a), 0.0, np.cos(a)]  # tilted east of the velocity
    forces = jax.jit(lambda x, p: flight.forces(0.0, x, jnp.zeros(3), p))
    _, _, air = forces(jnp.asarray(x), p)
    q, rho, _, mach = (float(air[i]) for i in range(4))
    spin = np.asarray(air[-1])
    cna = np.asarray(frame.cn_alpha(mach))
    restoring = q * rocket.area * np.sum(cna * arm) * np.sin(a) / inertia
    # turning towards the velocity: about north, negative (east-to-up rotation)
    np.testing.assert_allclose(spin, [0.0, restoring, 0.0], atol=1e-9 * abs(restoring))
    assert restoring < 0
    x[6:9] = [0.0, 0.0, 1.0]
    x[9:12] = [0.0, 0.5, 0.0]
    _, _, air = forces(jnp.asarray(x), p)
    damping = -0.5 * rho * v * rocket.area * np.sum(cna * arm**2) * 0.5 / inertia
    np.testing.assert_allclose(np.asarray(air[-1]), [0.0, damping, 0.0], rtol=1e-6)


def test_weathercocking_flies_rocketpys_windy_flight():
    """RocketPy's planted flight (a 6.4 m/s tail wind along the rail) flown by the
    model at every planted value (the flown drag every 0.05 Mach, thrust scale,
    wind, barometer lag and static error): the geometric apogee against RocketPy's
    2661.27 m. Measured with the attitude -0.50 m (drag every 0.01 Mach); pointing
    along the air-relative velocity at once (no airframe) -7.63 m
    (experiments/rocket_weathercock_truth.py; on the validation flight `wind-s6`, a
    7.1 m/s head wind: +13.0 m and -80.1 m). Both leave the rail when its upper
    button does (10.9 m of the 12 m rail)."""
    folder = SIM / "planted"
    truth = tomllib.loads((folder / "rocket.toml").read_text())["truth"]
    rocket = dr.read_rocket(folder / "rocket.toml", attitude=True)
    m, cd = dr.read_drag_curve(folder / "drag.csv")
    knots = dr.DragKnots(tuple(float(v) for v in m[(m >= 0.05) & (m <= 0.85)][::5]))
    problem = dr.prepare(rocket, read_rocket_log(folder / "rocket.toml"), knots=knots)
    start = dict(zip(knots.names, np.interp(knots.mach, m, cd), strict=True))
    start.update(
        thrust_scale=truth["thrust_scale"],
        motor_time=0.0,
        wind_east=truth["wind_east_m_s"],
        wind_north=truth["wind_north_m_s"],
        baro_lag=truth["baro_lag_s"],
        static_error=truth["static_error"],
    )
    flown = dr.simulate_flight(problem, start)
    gap = float(flown.states[:, 2].max()) - truth["apogee_geometric_agl_m"]
    assert abs(gap) < 1.5


def test_geodesic_acceleration_reaches_the_closed_form_optimum_in_fewer_steps():
    """The engine's geodesic acceleration (the option the attitude's fit sets) on a
    bent valley with a closed-form optimum: outputs `a sin t` (noise 1) and
    `30 (b - a^2) cos t` (noise 0.1), so det(R) is least at each channel's own
    least-squares fit, `a = sum y1 sin / sum sin^2`, `b = a^2 + sum y2 cos / (30 sum
    cos^2)`; from `a = b = 0` the valley `b = a^2 + const` bends. Both steps reach
    that optimum (to 2e-6, measured 1e-8 accelerated, 4e-7 plain on 400 samples,
    stopping at the engine's det(R) tolerance); the accelerated one in under 60%
    of the plain one's steps (measured 103 against 224)."""
    import diffpegasus as dp

    def rates(t, x, u, p):
        return jnp.zeros(1)

    def outputs(t, x, u, p):
        return jnp.stack(
            [p["a"] * jnp.sin(t), 30.0 * (p["b"] - p["a"] ** 2) * jnp.cos(t)]
        )

    rng = np.random.default_rng(1)
    t = np.arange(0, 20, 0.05)
    y = np.column_stack([2.0 * np.sin(t), 30 * 0.5 * np.cos(t)])
    y = y + rng.normal(0, [1.0, 0.1], (len(t), 2))
    a = np.sum(y[:, 0] * np.sin(t)) / np.sum(np.sin(t) ** 2)
    b = a**2 + np.sum(y[:, 1] * np.cos(t)) / (30 * np.sum(np.cos(t) ** 2))
    record = dp.Record(t, np.zeros((len(t), 1)), y, x0=np.zeros(1))
    model = dp.Model(("x",), ("u",), ("y1", "y2"), {"a": 0.0, "b": 0.0}, rates, outputs)
    plain = dp.fit(model, record)
    fast = dp.fit(model, record, acceleration=True)
    for f in (plain, fast):
        np.testing.assert_allclose(f.params, [a, b], atol=2e-6)
    assert fast.iterations < 0.6 * plain.iterations
