"""Aerodynamic database, motor and mass model."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diffpegasus as dp
from diffpegasus._vehicle._pegasus._aerodynamics import DERIVATIVE_NAMES


@pytest.fixture(scope="module")
def db():
    return dp.load_database()


def _grid_rows():
    import importlib.resources

    path = importlib.resources.files("diffpegasus") / "data" / "pegasus_aero.csv"
    return np.loadtxt(path, delimiter=",", skiprows=1)


def test_database_reproduces_its_grid(db):
    rows = _grid_rows()
    values = jax.vmap(lambda a, m: db.derivatives(a, m).as_array())(
        jnp.deg2rad(rows[:, 1]), jnp.asarray(rows[:, 0])
    )
    np.testing.assert_allclose(np.asarray(values), rows[:, 2:], rtol=1e-12, atol=1e-14)


def test_database_grid_is_the_thesis_grid(db):
    lo, hi = db.alpha_range
    assert np.rad2deg(lo) == pytest.approx(-1.84)
    assert np.rad2deg(hi) == pytest.approx(26.16)
    assert np.rad2deg(db.dalpha) == pytest.approx(2.0)
    assert db.mach_range == pytest.approx((0.3, 9.3))


@pytest.mark.parametrize("direction", ["alpha", "mach"])
def test_interpolant_is_c1_across_grid_lines(db, direction):
    # One-sided slopes on either side of a breakpoint agree (no kink), unlike
    # bilinear interpolation.
    a0, m0 = np.deg2rad(10.16), 2.3

    def f(x):
        a, m = (a0 + x, m0) if direction == "alpha" else (a0, m0 + x)
        return db.derivatives(a, m).as_array()

    h = 1e-5
    left = (f(0.0) - f(-h)) / h
    right = (f(h) - f(0.0)) / h
    scale = jnp.max(jnp.abs(left)) + 1e-12
    assert float(jnp.max(jnp.abs(left - right)) / scale) < 1e-3


def test_database_physics(db):
    alpha = np.deg2rad(4.0)
    d = {m: db.derivatives(alpha, m) for m in [1.5, 3.0, 6.0, 9.0]}
    cla = [float(d[m].CLa) for m in d]
    assert all(np.diff(cla) < 0), "supersonic lift slope falls"
    for m in d:
        assert float(d[m].CLa) > 0 and float(d[m].CLde) > 0
        assert float(d[m].CMa) < 0, "statically stable about the cp"
        assert float(d[m].CMde) < 0, "trailing-edge-down elevator pitches nose down"


def test_axis_round_trip():
    cl, cd, alpha = 0.7, 0.12, np.deg2rad(12.0)
    cx, cz = dp.body_axis(cl, cd, alpha)
    assert float(cz) < 0 and float(cx) > -cd
    back = dp.wind_axis(cx, cz, alpha)
    np.testing.assert_allclose(np.asarray(back), [cl, cd], rtol=1e-14)


def test_scaled_database(db):
    s = db.scaled(1.1, 0.9, 1.05)
    a, m = 0.1, 2.0
    base = db.derivatives(a, m).as_array()
    np.testing.assert_allclose(
        np.asarray(s.derivatives(a, m).as_array()),
        np.asarray(base) * np.array([1.1, 1.1, 0.9, 0.9, 1.05, 1.05]),
        rtol=1e-14,
    )


def test_bad_database_file(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("mach,alpha_deg,CLa,CLde,CDa,CDde,CMa,CMde\n0.3,0,1,1,1,1,1,1\n")
    with pytest.raises(ValueError, match="two breakpoints"):
        dp.load_database(p)
    p.write_text("mach,alpha,CLa\n0.3,0,1\n")
    with pytest.raises(ValueError, match="header"):
        dp.load_database(p)


def test_total_impulse_and_timing():
    motor = dp.SolidMotor()
    t = np.linspace(0.0, 90.0, 900_001)
    thrust = np.asarray(jax.vmap(motor.vacuum_thrust)(jnp.asarray(t)))
    impulse = np.sum(0.5 * (thrust[1:] + thrust[:-1]) * np.diff(t))
    assert impulse == pytest.approx(35.4e6, rel=1e-6)
    burning = t[thrust > 0]
    assert burning[0] == pytest.approx(5.0, abs=1e-3)
    assert burning[-1] == pytest.approx(80.3, abs=1e-3)
    average = impulse / 75.3
    assert 460e3 < average < 480e3
    isp = impulse / (12_453 * 9.80665)
    assert 285 < isp < 295


def test_net_thrust_pressure_correction():
    motor = dp.SolidMotor()
    t = 40.0
    vac = float(motor.vacuum_thrust(t))
    p = 5_000.0
    exit_area = np.pi * 1.42**2 / 4
    assert float(motor.net_thrust(t, p)) == pytest.approx(
        vac - exit_area * p, rel=1e-14
    )
    assert float(motor.net_thrust(t, 0.0)) == pytest.approx(vac, rel=1e-14)
    for t_off in [0.0, 4.9, 80.3, 85.0]:
        assert float(motor.net_thrust(t_off, 101_325.0)) == 0.0


def test_mass_bookkeeping():
    motor, model = dp.SolidMotor(), dp.MassModel()
    at = lambda t: model.at(t, motor)  # noqa: E731
    assert float(at(0.0).mass) == pytest.approx(18_505.0)
    assert float(at(5.0).mass) == pytest.approx(18_505.0)
    assert float(at(80.3).mass) == pytest.approx(18_505.0 - 12_453.0)
    assert float(at(90.0).mass) == pytest.approx(6_052.0)
    mid = (5.0 + 80.3) / 2
    assert float(at(mid).mass) == pytest.approx(18_505.0 - 12_453.0 / 2)
    # CG about 58% of the length at ignition, about 35% at burnout; Iyy about 2.9e5
    # falling to about 0.7e5 kg m^2 (SPEC section 2, engineering estimates).
    assert 0.55 < float(at(5.0).xcg) / 15 < 0.61
    assert 0.32 < float(at(80.3).xcg) / 15 < 0.37
    assert 2.5e5 < float(at(5.0).Iyy) < 3.1e5
    assert 0.6e5 < float(at(80.3).Iyy) < 0.8e5


def test_iyy_rate_matches_finite_difference():
    motor, model = dp.SolidMotor(), dp.MassModel()
    for t in [10.0, 40.0, 75.0]:
        h = 1e-4
        fd = (model.at(t + h, motor).Iyy - model.at(t - h, motor).Iyy) / (2 * h)
        assert float(model.at(t, motor).Iyy_dot) == pytest.approx(float(fd), rel=1e-7)


def test_perturbation_ranges_and_seed():
    p = dp.sample_perturbations(jax.random.key(3), 2000)
    bounds = {
        "lift": (0.9, 1.1),
        "drag": (0.9, 1.1),
        "moment": (0.9, 1.1),
        "mass": (0.95, 1.05),
        "thrust": (0.8, 1.2),
        "cg_shift": (-0.5, 0.5),
    }
    for name, (lo, hi) in bounds.items():
        x = np.asarray(getattr(p, name))
        assert lo <= x.min() and x.max() <= hi
        assert x.min() < lo + 0.02 * (hi - lo) and x.max() > hi - 0.02 * (hi - lo)
    again = dp.sample_perturbations(jax.random.key(3), 2000)
    np.testing.assert_array_equal(np.asarray(p.thrust), np.asarray(again.thrust))


def test_derivative_names():
    assert DERIVATIVE_NAMES == ("CLa", "CLde", "CDa", "CDde", "CMa", "CMde")


def test_pegasus_from_parts_is_the_simulator_and_identifies_its_database_scales():
    """The Pegasus parts behind the abstract interfaces (`FlightVehicle`) give the
    simulator's rates and channels, and the engine fitting that vehicle to a
    simulated flight of a perturbed stage recovers the perturbation."""
    from diffpegasus._vehicle._effects import make_effect
    from diffpegasus._vehicle._pegasus._dynamics import evaluate, FlightModel
    from diffpegasus._vehicle._pegasus._parts import pegasus_vehicle

    stage = dp.Vehicle().perturbed(lift=1.08, drag=0.95, moment=0.9, mass=1.02)
    parts = pegasus_vehicle(stage)
    effects = (make_effect("pitch_damping", -5.0),)
    unit = {"CL_scale": 1.0, "CD_scale": 1.0, "CM_scale": 1.0}
    rng = np.random.default_rng(0)
    for _ in range(5):
        t = rng.uniform(0.0, 75.0)
        u, w = rng.uniform(200.0, 2000.0), rng.uniform(-50.0, 50.0)
        q, theta, h = rng.uniform(-0.1, 0.1), rng.uniform(-0.3, 0.5), 3e4
        de = rng.uniform(-0.1, 0.1)
        sim = evaluate(
            t,
            jnp.array([u, w, q, theta, 0.0, h]),
            FlightModel(stage, dp.Step(np.degrees(de), -1.0), effects),
        )
        v, alpha = np.hypot(u, w), np.arctan2(w, u)
        rates, pp = parts.evaluate(
            t, jnp.array([v, alpha, theta, q, h]), jnp.array([de]), unit, effects
        )
        vdot = (u * sim.rates[0] + w * sim.rates[1]) / v
        np.testing.assert_allclose(rates[0], vdot, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(rates[3], sim.rates[2], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(rates[4], sim.rates[5], rtol=1e-12, atol=1e-12)
        for name in ("ax", "az", "qdot", "mach", "qbar", "thrust", "mass", "xcg"):
            np.testing.assert_allclose(
                pp.channels[name], sim.channels[name], rtol=1e-12, atol=1e-12
            )

    config = dp.PegasusConfig(vehicle=stage, t_final=30.0, sample_rate=50.0)
    log = dp.flight_to_log(dp.simulate(config, jax.random.key(3)))
    outputs = ("V", "alpha", "theta", "q", "qdot", "ax", "az", "h")
    # the mass is known (weighed); the database's scales are what the flight tells
    known = pegasus_vehicle(dp.Vehicle().perturbed(mass=1.02))
    model = dp.vehicle_model(known, outputs=outputs)
    ch = log.channels
    record = dp.Record(
        np.asarray(ch["t"]),
        np.asarray(ch["de"])[:, None],
        np.column_stack([np.asarray(ch[n]) for n in outputs]),
        x0=np.array([ch[n][0] for n in model.states]),
    )
    fit = dp.fit(model, [record], initial_state="estimated")
    assert fit.converged
    # measured: 1.08049 +/- 0.00013, 0.94983 +/- 0.00024, 0.90002 +/- 0.00006; the
    # model integrates at the 50 Hz log step with the elevator interpolated between
    # samples, the simulator at 5 ms, which leaves about 5e-4 on the lift scale
    for name, truth in (("CL_scale", 1.08), ("CD_scale", 0.95), ("CM_scale", 0.9)):
        assert abs(fit.estimates()[name] - truth) < 1e-3, (name, fit.estimates())
