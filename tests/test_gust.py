"""The coloured gust state of the filter-error method against a Kalman filter
written here in numpy/scipy on the same linear short-period model with a
first-order gust on alpha, augmented by hand: the transition and the input's
effect exact (matrix exponentials), the process-noise covariance by Van Loan,
the filter-error Riccati equation `P = Phi (P - P C^T R^-1 C P) Phi^T + Q` by
fixed-point iteration from scipy's DARE solution."""

import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg

from diffpegasus._estimate._filter_error import innovations, problem
from diffpegasus._estimate._gust import Gust, LOG_LENGTH, LOG_TAU, with_gust
from diffpegasus._estimate._model import Model, Record


TRUE = {"Za": -1.2, "Zd": -0.1, "Ma": -4.0, "Mq": -1.5, "Md": -6.0}
V = 60.0
DT = 0.02
N = 300
TAU = 1.7  # s
F = (2e-3, 1e-2, 4e-3)  # white on alpha, q (rad/sqrt(s), rad/s/sqrt(s)); gust


def _rates(t, x, u, p):
    a, q = x[0], x[1]
    return jnp.stack(
        [
            p["Za"] * a + p["Zd"] * u[0] + q,
            p["Ma"] * a + p["Mq"] * q + p["Md"] * u[0],
        ]
    )


def _observe(t, x, u, p):
    return jnp.stack([x[0], x[1], V * (p["Za"] * x[0] + p["Zd"] * u[0])])


MODEL = Model(("alpha", "q"), ("de",), ("alpha", "q", "az"), TRUE, _rates, _observe)


def _matrices(tau=TAU):
    """The augmented system by hand: states alpha, q, g (the gust on alpha)."""
    za, zd, ma, mq, md = TRUE.values()
    a = np.array([[za, 1.0, za], [ma, mq, ma], [0.0, 0.0, -1.0 / tau]])
    b = np.array([[zd], [md], [0.0]])
    c = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 0.0], [V * za, 0.0, V * za]])
    d = np.array([[0.0], [0.0], [V * zd]])
    return a, b, c, d


def _numpy_filter(t, de, z, r, tau=TAU):
    """Innovations of the steady-state filter-error filter, all in numpy."""
    a, b, c, d = _matrices(tau)
    n = a.shape[0]
    f = np.diag(F)
    vl = scipy.linalg.expm(np.block([[-a, f @ f.T], [np.zeros((n, n)), a.T]]) * DT)
    phi = vl[n:, n:].T
    q = phi @ vl[:n, n:]
    # inputs linear between samples: [x, u, du/dt] propagated exactly
    m = np.zeros((n + 2, n + 2))
    m[:n, :n], m[:n, n : n + 1], m[n, n + 1] = a, b, 1.0
    e = scipy.linalg.expm(m * DT)
    g0, g1 = e[:n, n], e[:n, n + 1]
    p = scipy.linalg.solve_discrete_are(phi.T, c.T, q, r)
    ri = np.linalg.inv(r)
    for _ in range(20000):
        new = phi @ (p - p @ c.T @ ri @ c @ p) @ phi.T + q
        if np.max(np.abs(new - p)) < 1e-16 * np.max(np.abs(p)):
            break
        p = new
    k = p @ c.T @ ri
    x = np.zeros(n)
    nu = np.zeros_like(z)
    for i in range(len(t)):
        nu[i] = z[i] - (c @ x + d[:, 0] * de[i])
        xc = x + k @ nu[i]
        if i + 1 < len(t):
            x = phi @ xc + g0 * de[i] + g1 * (de[i + 1] - de[i]) / DT
    return nu, k


@pytest.fixture(scope="module")
def record():
    """A record of the augmented linear system's outputs (any data serves: the
    two filters run on the same numbers)."""
    rng = np.random.default_rng(3)
    t = DT * np.arange(N)
    de = 0.02 * np.sign(np.sin(2 * np.pi * t / 1.5))
    z = rng.normal(size=(N, 3)) * np.array([3e-3, 1e-2, 0.5])
    return Record(t, de[:, None], z, x0=np.zeros(3), name="gusty")


def test_gust_filter_matches_a_numpy_kalman_filter(record):
    gust = Gust(("alpha",), tau=TAU)
    aug = with_gust(MODEL, gust)
    assert aug.states == ("alpha", "q", "gust[alpha]")
    assert aug.parameters[-1] == LOG_TAU
    assert aug.start[-1] == pytest.approx(np.log(TAU))
    r = np.diag([1e-5, 1e-4, 0.3])
    z = jnp.asarray([*TRUE.values(), np.log(TAU), *F])
    prob = problem(aug, [record], (0, 1, 2))
    nu, _, _, k, _, _ = innovations(aug, prob, z, jnp.asarray(r))
    ref, k_ref = _numpy_filter(record.t, record.inputs[:, 0], record.measured, r)
    # the gain: one Riccati solution each (Newton in the package, fixed point
    # here), measured to agree to 1.5e-15
    np.testing.assert_allclose(np.asarray(k[0, 0]), k_ref, rtol=1e-8, atol=1e-12)
    # the innovations: RK4 at the sample step against the exact propagation;
    # measured within 1.2e-7 of the innovations' size (q; alpha 4.7e-8)
    scale = np.abs(ref).max(axis=0)
    err = np.abs(np.asarray(nu[0, :N]) - ref).max(axis=0) / scale
    assert np.all(err < 1e-6), err


def test_gust_through_a_frozen_field_decays_at_airspeed_over_length(record):
    """With `airspeed` named the correlation time is `L / V`: the airspeed a
    state of the model (held: `V' = 0`, measured without error, so the filter
    never moves it), the filter on alpha, q and az at two airspeeds is the numpy
    filter's with `tau = L / V` for one length `L`."""

    def rates(t, x, u, p):
        return jnp.concatenate([jnp.zeros(1), _rates(t, x[1:], u, p)])

    def observe(t, x, u, p):
        return jnp.concatenate([x[:1], _observe(t, x[1:], u, p)])

    model = Model(
        ("V", "alpha", "q"), ("de",), ("V", "alpha", "q", "az"), TRUE, rates, observe
    )
    length = 150.0  # m
    aug = with_gust(model, Gust(("alpha",), airspeed="V", length=length))
    assert aug.parameters[-1] == LOG_LENGTH
    assert aug.start[-1] == pytest.approx(np.log(length))
    r = np.diag([1e-5, 1e-4, 0.3])
    z = jnp.asarray([*TRUE.values(), np.log(length), 1e-3, *F])
    for speed in (V, 2.5 * V):
        rec = Record(
            record.t,
            record.inputs,
            np.column_stack([np.full(N, speed), record.measured]),
            x0=np.array([speed, 0.0, 0.0, 0.0]),
        )
        prob = problem(aug, [rec], (0, 1, 2, 3))
        nu, _, _, k, _, _ = innovations(
            aug, prob, z, jnp.asarray(scipy.linalg.block_diag(1e-2, r))
        )
        ref, k_ref = _numpy_filter(
            record.t, record.inputs[:, 0], record.measured, r, tau=length / speed
        )
        np.testing.assert_allclose(
            np.asarray(k[0, 0])[1:, 1:], k_ref, rtol=1e-8, atol=1e-12
        )
        assert np.all(np.asarray(nu[0, :N, 0]) == 0.0)
        scale = np.abs(ref).max(axis=0)
        err = np.abs(np.asarray(nu[0, :N, 1:]) - ref).max(axis=0) / scale
        assert np.all(err < 1e-6), (speed, err)


def test_gust_rejects_a_state_the_model_lacks():
    with pytest.raises(ValueError, match="gust on \\['w'\\]"):
        with_gust(MODEL, Gust(("w",)))
    with pytest.raises(ValueError, match="positive"):
        Gust(("alpha",), tau=0.0)
    with pytest.raises(ValueError, match="positive"):
        Gust(("alpha",), airspeed="V", length=-1.0)
    with pytest.raises(ValueError, match="gust on \\['V'\\]"):
        with_gust(MODEL, Gust(("alpha",), airspeed="V"))


def test_kinematic_states_take_their_rates_at_the_inertial_state():
    """With `kinematic=("h",)` the climb rate is the inertial one, the other
    rates and every output the air's (closed form on a small model)."""

    def rates(t, x, u, p):
        v, a, h = x
        return jnp.stack([p["k"] * a, -a + u[0], v * jnp.sin(-a)])

    def observe(t, x, u, p):
        return x

    model = Model(
        ("V", "alpha", "h"), ("de",), ("V", "alpha", "h"), {"k": 2.0}, rates, observe
    )
    aug = with_gust(model, Gust(("alpha",), tau=2.0, kinematic=("h",)))
    x = jnp.asarray([50.0, 0.05, 100.0, 0.01])  # the gust on alpha: 0.01 rad
    p = aug.named(jnp.asarray(aug.start))
    f = np.asarray(aug.rates(0.0, x, jnp.asarray([0.2]), p))
    np.testing.assert_allclose(
        f, [2.0 * 0.06, -0.06 + 0.2, 50.0 * np.sin(-0.05), -0.01 / 2.0], rtol=1e-14
    )
    np.testing.assert_allclose(
        np.asarray(aug.observe(0.0, x, None, p)), [50.0, 0.06, 100.0], rtol=1e-14
    )


G0 = 9.81  # m/s^2


def _body_forces(ua, wa):
    """Specific aerodynamic forces (m/s^2, body x forward, z down) of the
    air-relative body velocity."""
    return -1e-4 * ua * abs(ua), -0.02 * np.hypot(ua, wa) * wa


def test_pitch_rate_gives_the_inertial_velocity_rates_through_a_wind():
    """With `pitch_rate` the airspeed and angle-of-attack rates are the inertial
    velocity's through a wind fixed in the earth frame: against the body-axis
    equations written here in numpy (`u' = X(v_a) - q w - g sin(theta)`, `w' =
    Z(v_a) + q u + g cos(theta)` with the inertial `u, w`, the forces at the
    air-relative velocity), the form the independent generator flies."""

    def rates(t, x, u, p):
        v, a, theta, q = x
        ua, wa = v * jnp.cos(a), v * jnp.sin(a)
        xf, zf = -1e-4 * ua * jnp.abs(ua), -0.02 * v * wa
        du = xf - q * wa - G0 * jnp.sin(theta)
        dw = zf + q * ua + G0 * jnp.cos(theta)
        return jnp.stack(
            [(ua * du + wa * dw) / v, (ua * dw - wa * du) / v**2, q, -3.0 * a - q]
        )

    def observe(t, x, u, p):
        return x

    names = ("V", "alpha", "theta", "q")
    model = Model(names, ("de",), names, {"k": 1.0}, rates, observe)
    gust = Gust(("V", "alpha"), tau=2.0, pitch_rate="q")
    aug = with_gust(model, gust)
    v, a, theta, q, gv, ga = 230.0, 0.04, 0.1, 0.15, -1.2, 0.006
    x = jnp.asarray([v, a, theta, q, gv, ga])
    f = np.asarray(aug.rates(0.0, x, jnp.asarray([0.0]), aug.named(aug.start)))

    u, w = v * np.cos(a), v * np.sin(a)
    ua, wa = (v + gv) * np.cos(a + ga), (v + gv) * np.sin(a + ga)
    xf, zf = _body_forces(ua, wa)
    du = xf - q * w - G0 * np.sin(theta)
    dw = zf + q * u + G0 * np.cos(theta)
    ref = [(u * du + w * dw) / v, (u * dw - w * du) / v**2, q, -3.0 * (a + ga) - q]
    # the same arithmetic in another arrangement: agreement to rounding
    np.testing.assert_allclose(f[:4], ref, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(f[4:], [-gv / 2.0, -ga / 2.0], rtol=1e-14)
    # without the pitch rate the airspeed rate misses the wind's transport
    # less the turn of the acceleration through the gust angle, about
    # (q - alpha') W_w = (0.15 + 0.016) * 1.3 m/s: the check above can fail
    plain = with_gust(model, Gust(("V", "alpha"), tau=2.0))
    f0 = np.asarray(plain.rates(0.0, x, jnp.asarray([0.0]), plain.named(plain.start)))
    assert abs(f0[0] - ref[0]) > 0.1  # measured 0.228 m/s^2


def test_pitch_rate_needs_airspeed_and_angle_of_attack():
    with pytest.raises(ValueError, match="airspeed and the angle of attack"):
        Gust(("alpha",), pitch_rate="q")
