"""The motor's burn time (`burn_scale`): the thrust curve stretched in time at the
same impulse, on closed-form curves, its gradient against finite differences, and
the rule deciding when a fit estimates it; the bounds of the effects positive by
their meaning, which no start or step may cross, and a fit stopped against one."""

import dataclasses
import pathlib

import jax
import jax.numpy as jnp
import numpy as np

import diffpegasus as dp
from diffpegasus import read_rocket_log, rocket as dr
from diffpegasus._vehicle._rocket._motor import motor_at

from .helpers import rocket_parameters


SIM = pathlib.Path(__file__).parent / "data" / "rocket_sim"
G0 = 9.80665


def triangle():
    """A triangular motor: 0 to 1000 N over 1 s and back to 0 at 2 s (1000 N s)."""
    return dr.Motor(np.array([0.0, 1.0, 2.0]), np.array([0.0, 1000.0, 0.0]), 2.0)


def test_stretched_triangle_keeps_its_impulse_and_burns_longer():
    """Stretched by 1.25: burnout at 2.5 s, peak 800 N at 1.25 s, impulse 1000 N s
    (trapezoid on a grid holding the kinks: exact for a piecewise-linear curve),
    half the propellant burned at the peak and all of it at burnout."""
    s = 1.25
    tables = tuple(jnp.asarray(a) for a in triangle().tables())
    t = np.linspace(0.0, 3.0, 3001)  # 1 ms: 1.25 and 2.5 s are grid points
    f, b = jax.vmap(lambda x: motor_at(tables, x, s))(jnp.asarray(t))
    f, b = np.asarray(f), np.asarray(b)
    np.testing.assert_allclose(np.trapezoid(f, t), 1000.0, rtol=1e-12)
    assert t[f > 0][-1] < 2.5 <= t[f > 0][-1] + 1e-3 + 1e-12
    np.testing.assert_allclose(f[t == 1.25], 1000.0 / s, rtol=1e-12)
    np.testing.assert_allclose(
        f[(t > 0.0) & (t < 1.25)], 1000.0 * t[(t > 0) & (t < 1.25)] / s**2, rtol=1e-12
    )
    np.testing.assert_allclose(b[np.isclose(t, 1.25)], 0.5, rtol=1e-12)
    np.testing.assert_allclose(b[t >= 2.5], 1.0, rtol=1e-12)
    # unstretched: the curve itself
    f1, _ = motor_at(tables, 0.5)
    np.testing.assert_allclose(float(f1), 500.0, rtol=1e-12)


def test_stretch_gradient_against_finite_differences():
    """d(thrust)/d(stretch) on the rising ramp, thrust 1000 t / s^2 there: -2000 t /
    s^3 in closed form; the burned fraction (the table's, linear between its
    points: 0.5 t / s) -0.5 t / s^2; both against central differences (jax's
    gradient of the interpolation at the stretched time)."""
    tables = tuple(jnp.asarray(a) for a in triangle().tables())
    t, s, h = 0.9, 1.25, 1e-6
    df, db = jax.jacfwd(lambda x: jnp.stack(motor_at(tables, t, x)))(s)
    fd = (
        np.array(motor_at(tables, t, s + h)) - np.array(motor_at(tables, t, s - h))
    ) / (2 * h)
    np.testing.assert_allclose([df, db], fd, rtol=1e-7)
    np.testing.assert_allclose(
        [df, db], [-2000 * t / s**3, -0.5 * t / s**2], rtol=1e-12
    )


def flight():
    rocket = dr.read_rocket(SIM / "clean" / "rocket.toml")
    return dr.Flight(rocket, dr.DragKnots((0.1, 0.5, 0.9)), 101_325.0)


def test_model_thrust_follows_the_stretched_curve():
    """The model's acceleration along the rail at rest (no drag, no friction) while
    the motor burns: thrust scale times the stretched curve over the mass with the
    propellant burned along it, less gravity along the rail, from the motor's table
    in numpy; its gradient in `burn_scale` against central differences."""
    fl = flight()
    r = fl.rocket
    tc, fc, burned = r.motor.tables()
    p = rocket_parameters(fl, thrust_scale=0.96, burn_scale=1.19)
    x = jnp.asarray(fl.initial_state())
    u = jnp.zeros(3)
    t = 0.6 * tc[-1]  # inside the burn, stretched or not
    s = p["burn_scale"]

    def along(scale):
        q = {k: jnp.asarray(v, float) for k, v in p.items()}
        q["burn_scale"] = scale
        accel, *_ = fl.forces(t, x, u, q)
        return jnp.dot(accel, jnp.asarray(fl.rail_axis()))

    thrust = 0.96 * np.interp(t / s, tc, fc) / s
    mass = r.dry_mass + r.motor.propellant_mass * (1 - np.interp(t / s, tc, burned))
    sin = np.sin(np.radians(r.inclination))
    g = float(fl.gravity(0.0))
    np.testing.assert_allclose(float(along(s)), thrust / mass - g * sin, rtol=1e-10)
    h = 1e-6
    fd = (float(along(s + h)) - float(along(s - h))) / (2 * h)
    np.testing.assert_allclose(float(jax.grad(along)(s)), fd, rtol=1e-6)


def test_burn_time_estimated_where_the_accelerometer_spans_the_boost():
    """The rule: the accelerometer read from the motor's start to half a second past
    the catalogue's burnout (RocketPy's clean flight: yes); the same log with the
    accelerometer stopping inside the burn, or an altitude alone: no."""
    from diffpegasus import Record
    from diffpegasus._rocket._data import ascent_record
    from diffpegasus._rocket._identify import accel_covers_boost

    rocket = dr.read_rocket(SIM / "clean" / "rocket.toml")
    record, _ = ascent_record(read_rocket_log(SIM / "clean" / "rocket.toml"))
    assert accel_covers_boost(record, rocket, 0.0)
    inputs = record.inputs.copy()
    inputs[record.t > 0.8 * rocket.motor.burn_time, 2] = 0.0
    assert not accel_covers_boost(
        Record(record.t, inputs, record.measured), rocket, 0.0
    )
    alone = Record(record.t, record.inputs[:, :2], record.measured[:, :1])
    assert not accel_covers_boost(alone, rocket, 0.0)


def test_burn_scale_start_from_the_accelerometer():
    """The equation-error start: RocketPy's flights (an independent simulator, the
    catalogue's burn) read 1.00 (measured 1.00 on both: the search's step is
    0.01); the model's own flight of the clean rocket with its burn stretched by
    1.2 (noise-free, the rocket file's drag curve) reads 1.2 within a step
    (measured 1.20): the drag the search adds back is only sea-level-ish."""
    from diffpegasus import Record
    from diffpegasus._estimate._fit import simulate_outputs
    from diffpegasus._rocket._identify import altitude_only, measured_burn_scale

    for name in ("clean", "planted"):
        rocket = dr.read_rocket(SIM / name / "rocket.toml")
        problem = dr.prepare(rocket, read_rocket_log(SIM / name / "rocket.toml"))
        assert abs(problem.start["burn_scale"] - 1.0) < 0.011
    start = dict(problem.start, burn_scale=1.2, motor_time=0.0)
    model = dr.rocket_model(problem.flight, problem.outputs, start, ())
    rec = problem.record
    y = simulate_outputs(model, rec.t, rec.inputs, x0=problem.flight.initial_state())
    flown = Record(rec.t, rec.inputs, y, x0=rec.x0)
    assert abs(measured_burn_scale(flown, problem.rocket, 0.0) - 1.2) < 0.011
    # the barometer alone holds it at the catalogue's: what the accelerometer read
    # goes with it (NDRT 2020's prediction had held its 0.97)
    moved = dataclasses.replace(problem, start=start)
    assert altitude_only(moved).start["burn_scale"] == 1.0


def test_no_start_or_step_where_the_rocket_is_unphysical():
    """A burn stretched by 0 divides the thrust by zero: before the bound, the
    clean flight simulated from a burn scale of 0 had a NaN apogee and 2701 of its
    2716 barometric altitudes NaN (a pad temperature of -5 K all of them, a drag
    scale of -1 1055). Through the public API every positive effect at 0 or
    below (and NaN), and a mass offset that leaves the airframe lighter than 0 kg
    (8.2 kg without its motor: the rocket file's), is refused in one line naming
    the value, by the simulation and the fit alike, before anything is compiled.
    A fit's step there finds the model's outputs NaN, a cost the engine's
    damping rejects (as any step that does not lower it); just inside, finite."""
    import pytest

    from diffpegasus import LogError

    rocket = dr.read_rocket(SIM / "clean" / "rocket.toml")
    problem = dr.prepare(rocket, read_rocket_log(SIM / "clean" / "rocket.toml"))
    bad = {
        "burn_scale": [0.0, -0.5, float("nan")],
        "thrust_scale": [0.0],
        "cd_scale": [-1.0],
        "power_on_ratio": [0.0],
        "accel_scale": [0.0],
        "temperature": [-5.0],
    }
    for name, values in bad.items():
        for value in values:
            for run in (dr.simulate_flight, dr.fit_rocket):
                with pytest.raises(LogError) as err:
                    run(problem, start={name: value})
                line = str(err.value)
                assert "\n" not in line and f"{name} = {value:g}:" in line
                assert "must be above 0" in line
    with pytest.raises(LogError, match=r"mass_offset = -8\.3 kg .* above -8\.2 kg"):
        dr.fit_rocket(problem, start={"mass_offset": -8.3})
    model = dr.rocket_model(problem.flight, problem.outputs, problem.start, ())
    x, u = jnp.asarray(problem.flight.initial_state()), jnp.ones(3)
    outputs = jax.jit(model.g)
    for stretch, finite in ((0.0, False), (-0.5, False), (1e-3, True), (1.0, True)):
        theta = np.asarray(model.start)
        theta[model.parameters.index("burn_scale")] = stretch
        y = np.asarray(outputs(0.5, x, u, jnp.asarray(theta)))
        assert np.all(np.isfinite(y)) if finite else np.all(np.isnan(y))


def test_a_fit_stopped_against_a_bound_is_reported_naming_the_effect():
    """The clean RocketPy flight's first 6 s (boost and early coast), its
    accelerometer's sign flipped: its scale's optimum is near -1, past the bound at
    0 that no step may cross. The fit (single shooting; the drag's scale, the
    thrust scale, the accelerometer's offset and scale estimated, the motor's
    start and burn and the day's air held) stops against the bound (measured at
    1.3e-8, the data taking it to -1.02) and is reported `nonfinite`, one line
    naming the effect. The same fit of the log as read is not flagged: it
    converges, its scale near 1 (measured 1.0156 +/- 0.0058)."""
    rocket = dr.read_rocket(SIM / "clean" / "rocket.toml")
    problem = dr.prepare(rocket, read_rocket_log(SIM / "clean" / "rocket.toml"))
    rec = problem.record
    m = rec.t <= 6.0

    def fitted(sign):
        measured = rec.measured[m].copy()
        measured[:, 1] *= sign
        short = type(rec)(rec.t[m], rec.inputs[m], measured, x0=rec.x0)
        return dr.fit_rocket(
            dataclasses.replace(problem, record=short),
            free=("accel_scale",),
            drag="scale",
            hold=("motor_time", "burn_scale"),
            hold_temperature=True,
            shooting_interval=10.0,  # one segment: the record is 6.3 s long
            spread=False,
            throw=False,
        )

    flipped = fitted(-1.0)
    assert flipped.fit.result == dp.RESULTS.nonfinite and not flipped.fit.converged
    line = flipped.fit.reason
    assert "\n" not in line and line.startswith("accel_scale stopped against its bound")
    assert "accel_scale = -" in line and "must be above 0" in line
    value, _ = flipped.estimate("accel_scale")
    assert 0.0 < value < 1e-3
    ordinary = fitted(1.0)
    assert ordinary.fit.converged and ordinary.fit.reason == ""
    value, stderr = ordinary.estimate("accel_scale")
    assert abs(value - 1.0) < 0.03 and stderr < 0.01  # measured 1.0156 +/- 0.0058
