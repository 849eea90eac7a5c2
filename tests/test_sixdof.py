"""The 6-DOF rigid-body model: its pitch-plane special case against `_dynamics.py`,
closed-form steady roll, conservation of angular momentum, the Dutch roll of the
nonlinear simulation against the eigenvalues of an independently written linear
model, Jacobians against finite differences, and the identification of the lateral
derivatives from two simulated manoeuvres."""

import functools
import pathlib
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.optimize

import diffpegasus as dp


G = 9.80665  # m/s^2, as in the 6-DOF module
EXPERIMENTS = pathlib.Path(__file__).resolve().parents[1] / "experiments"
sys.path.insert(0, str(EXPERIMENTS))
import lateral  # noqa: E402


def _rk4(f, y, dt, n):
    """`n` classical RK4 steps of `y' = f(t, y)`, every state returned `(n + 1, .)`."""

    def step(carry, _):
        t, y = carry
        k1 = f(t, y)
        k2 = f(t + dt / 2, y + dt / 2 * k1)
        k3 = f(t + dt / 2, y + dt / 2 * k2)
        k4 = f(t + dt, y + dt * k3)
        y1 = y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return (t + dt, y1), y1

    _, ys = jax.lax.scan(step, (0.0, y), None, length=n)
    return jnp.concatenate([y[None], ys])


@functools.cache
def _jet():
    aircraft = dp.business_jet()
    return aircraft, dp.trim(aircraft, 104.67)


def test_symmetric_rates_equal_the_pitch_plane_model():
    rng = np.random.default_rng(0)
    inertia = dp.inertia_tensor(3.0e4, 4.5e4, 7.0e4, ixz=2.0e3)
    inertia_dot = dp.inertia_tensor(-30.0, -40.0, -60.0, ixz=-2.0)
    scale = np.array([50, 5, 0.3, 0.2, 1e4, 1e4, 1e4])
    for _ in range(5):
        u, w, q, theta, fx, fz, m_y = rng.normal(size=7) * scale
        u += 100.0
        vel_dot, omega_dot, euler_dot = dp.rigid_body_rates(
            jnp.array([u, 0.0, w]),
            jnp.array([0.0, q, 0.0]),
            jnp.array([0.0, theta, 0.0]),
            jnp.array([fx, 0.0, fz]),
            jnp.array([0.0, m_y, 0.0]),
            7000.0,
            inertia,
            inertia_dot,
            9.8,
        )
        udot, wdot, qdot = dp.pitch_plane_rates(
            u, w, q, theta, fx, fz, m_y, 7000.0, inertia[1, 1], inertia_dot[1, 1], 9.8
        )
        np.testing.assert_allclose(vel_dot, [udot, 0.0, wdot], rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(omega_dot, [0.0, qdot, 0.0], rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(euler_dot, [0.0, q, 0.0], rtol=1e-13, atol=1e-15)


def test_symmetric_flight_follows_the_pitch_plane_model():
    """An elevator doublet from trim: the 6-DOF simulation stays in the plane of
    symmetry and its longitudinal states are the 3-DOF model's (`pitch_plane_rates`
    with the same aerodynamics) integrated by the same RK4."""
    a, tr = _jet()
    elevator = dp.doublet(2.0, 1.0, start=1.0)
    dt, n = 0.02, 400
    six = dp.simulate_sixdof(a, tr, elevator=elevator, t_final=dt * n, dt=dt)

    def pitch_plane(t, y):
        u, w, q, theta, h = y
        speed = jnp.sqrt(u**2 + w**2)
        alpha = jnp.arctan2(w, u)
        qbar = 0.5 * a.rho * speed**2
        cl, cd = a.CL0 + a.CLa * alpha, a.CD0 + a.CDa * alpha
        cm = (
            a.Cm0 + a.Cma * alpha + a.Cmq * q * a.c_ref / (2 * speed)
            + a.Cmde * (tr.de + elevator(t))
        )  # fmt: skip
        fx, fz = dp.body_axis(cl, cd, alpha)
        udot, wdot, qdot = dp.pitch_plane_rates(
            u, w, q, theta,
            qbar * a.s_ref * fx + tr.thrust, qbar * a.s_ref * fz,
            qbar * a.s_ref * a.c_ref * cm, a.mass, a.inertia[1, 1], 0.0, G,
        )  # fmt: skip
        return jnp.stack([udot, wdot, qdot, q, u * jnp.sin(theta) - w * jnp.cos(theta)])

    y0 = jnp.array([tr.y[0], tr.y[2], 0.0, tr.y[7], tr.y[11]])
    three = np.asarray(_rk4(jax.jit(pitch_plane), y0, dt, n))
    assert np.ptp(six["q"]) > 0.02  # the doublet moved the aircraft
    # the same scheme on the same equations: agreement to rounding (measured 1e-14)
    for k, name in enumerate(("u", "w", "q", "theta", "h")):
        np.testing.assert_allclose(six[name], three[:, k], rtol=1e-9, atol=1e-9)
    for name in ("v", "p", "r", "phi", "psi", "beta", "ay"):
        np.testing.assert_array_equal(six[name], 0.0)


def test_steady_roll_has_the_closed_form_rate_and_time_constant():
    """Roll damping and aileron only: `pdot = Lp p + Lda da` with `Lp = qbar S b^2
    Cl_p / (2 V Ixx)`, so `p(t) = -Lda da / Lp (1 - exp(Lp t))`."""
    v, rho, s, b, ixx = 100.0, 1.0, 30.0, 14.0, 3.0e4
    derivs = dp.LateralDerivatives(Cl_p=-0.5, Cl_da=-0.1)
    qbar = 0.5 * rho * v**2
    da = np.deg2rad(3.0)

    def f(t, y):
        del t
        omega = y[3:6]
        _, cl, _ = dp.lateral_coefficients(
            derivs, 0.0, omega[0], omega[2], da, 0.0, v, b
        )
        moment = jnp.stack([qbar * s * b * cl, 0.0, 0.0])
        vel_dot, omega_dot, euler_dot = dp.rigid_body_rates(
            y[:3], omega, y[6:9], jnp.zeros(3), moment, 5000.0,
            dp.inertia_tensor(ixx, 5e4, 7e4), jnp.zeros((3, 3)), 0.0,
        )  # fmt: skip
        return jnp.concatenate([vel_dot, omega_dot, euler_dot])

    dt, n = 0.01, 500
    ys = np.asarray(_rk4(jax.jit(f), jnp.array([v] + [0.0] * 8), dt, n))
    t = dt * np.arange(n + 1)
    lp = qbar * s * b**2 * derivs.Cl_p / (2 * v * ixx)
    lda = qbar * s * b * derivs.Cl_da / ixx
    p_ss = -lda * da / lp
    # RK4 at 1/100 of the roll time constant: 1e-10 relative
    np.testing.assert_allclose(
        ys[:, 3], p_ss * (1 - np.exp(lp * t)), rtol=1e-8, atol=1e-10
    )
    np.testing.assert_allclose(
        ys[:, 6], p_ss * (t - np.expm1(lp * t) / lp), rtol=1e-7, atol=1e-9
    )
    np.testing.assert_allclose(ys[:, [1, 2, 4, 5]], 0.0, atol=1e-12)


def test_torque_free_body_conserves_angular_momentum_and_energy():
    inertia = dp.inertia_tensor(3.0e4, 4.5e4, 7.0e4, ixz=2.0e3, ixy=500.0, iyz=-300.0)
    rate = dp.inertia_tensor(-300.0, -200.0, -500.0, ixz=-20.0)

    def f(t, y, inertia_dot):
        vel_dot, omega_dot, _ = dp.rigid_body_rates(
            jnp.zeros(3), y, jnp.zeros(3), jnp.zeros(3), jnp.zeros(3), 1.0,
            inertia + t * inertia_dot, inertia_dot, 0.0,
        )  # fmt: skip
        del vel_dot
        return omega_dot

    dt, n = 0.005, 2000
    w0 = jnp.array([0.5, -0.3, 0.8])
    rigid = np.asarray(_rk4(lambda t, y: f(t, y, jnp.zeros((3, 3))), w0, dt, n))
    h = rigid @ np.asarray(inertia)
    energy = np.einsum("ni,ij,nj->n", rigid, np.asarray(inertia), rigid)
    assert np.ptp(rigid[:, 0]) > 0.1  # it tumbles
    np.testing.assert_allclose(
        np.linalg.norm(h, axis=1), np.linalg.norm(h[0]), rtol=1e-9
    )
    np.testing.assert_allclose(energy, energy[0], rtol=1e-9)
    # a burning stage: |I omega| is still conserved (d(I w)/dt = -w x I w), energy not
    burning = np.asarray(_rk4(lambda t, y: f(t, y, rate), w0, dt, n))
    t = dt * np.arange(n + 1)
    i_t = np.asarray(inertia)[None] + t[:, None, None] * np.asarray(rate)[None]
    h = np.einsum("nij,nj->ni", i_t, burning)
    np.testing.assert_allclose(
        np.linalg.norm(h, axis=1), np.linalg.norm(h[0]), rtol=1e-9
    )


def _textbook_lateral_matrix(a, tr):
    """The linear lateral equations in `(beta, p, r, phi)`, body axes, from the
    dimensional derivatives (written out here, not derived from the code)."""
    speed = float(jnp.linalg.norm(tr.y[:3]))
    alpha = float(tr.y[7])
    d = a.lateral
    qbar = 0.5 * a.rho * speed**2
    b2v = a.b_ref / (2 * speed)
    y = qbar * a.s_ref / a.mass * np.array([d.CY_beta, d.CY_p * b2v, d.CY_r * b2v])
    lmom = qbar * a.s_ref * a.b_ref * np.array([d.Cl_beta, d.Cl_p * b2v, d.Cl_r * b2v])
    nmom = qbar * a.s_ref * a.b_ref * np.array([d.Cn_beta, d.Cn_p * b2v, d.Cn_r * b2v])
    inertia = np.asarray(a.inertia)[np.ix_([0, 2], [0, 2])]
    ln = np.linalg.solve(inertia, np.vstack([lmom, nmom]))
    return np.array(
        [
            [y[0] / speed, y[1] / speed + np.sin(alpha), y[2] / speed - np.cos(alpha),
             G * np.cos(alpha) / speed],
            [*ln[0], 0.0],
            [*ln[1], 0.0],
            [0.0, 1.0, np.tan(alpha), 0.0],
        ]
    )  # fmt: skip


def test_linearisation_and_dutch_roll():
    a, tr = _jet()
    jac, _ = dp.linearise(a, tr)
    jac = np.asarray(jac)
    speed = float(jnp.linalg.norm(tr.y[:3]))
    lat = [1, 3, 5, 6]  # v, p, r, phi
    scale = np.diag([1 / speed, 1, 1, 1])  # beta = v / V to first order
    ours = scale @ jac[np.ix_(lat, lat)] @ np.linalg.inv(scale)
    book = _textbook_lateral_matrix(a, tr)
    np.testing.assert_allclose(ours, book, rtol=1e-9, atol=1e-12)
    # lateral and longitudinal motions decouple at a symmetric trim
    lon = [0, 2, 4, 7]
    np.testing.assert_allclose(jac[np.ix_(lat, lon)], 0.0, atol=1e-12)
    eig, vec = np.linalg.eig(book)
    i = int(np.argmax(eig.imag))
    omega_n, zeta = abs(eig[i]), -eig[i].real / abs(eig[i])
    assert 1.0 < omega_n < 2.5 and 0.05 < zeta < 0.3  # a lightly damped Dutch roll

    # The nonlinear simulation started on the Dutch-roll eigenvector rings at the
    # eigenvalue: a damped cosine fitted to its yaw rate gives it back.
    mode = np.real(vec[:, i]) / np.max(np.abs(vec[:, i]))
    y0 = np.asarray(tr.y).copy()
    amp = 1e-3  # rad of sideslip: small enough to stay linear
    beta0 = amp * mode[0]
    y0[1] = speed * np.sin(beta0)
    y0[0] = speed * np.cos(beta0) * np.cos(tr.y[7])
    y0[2] = speed * np.cos(beta0) * np.sin(tr.y[7])
    y0[3], y0[5], y0[6] = amp * mode[1], amp * mode[2], amp * mode[3]
    out = dp.simulate_sixdof(
        a, dp.Trim(y=jnp.asarray(y0), de=tr.de, thrust=tr.thrust), t_final=12.0, dt=0.02
    )

    def ring(t, c, s, sigma, omega):
        return np.exp(sigma * t) * (c * np.cos(omega * t) + s * np.sin(omega * t))

    guess = [out["r"][0], 0.0, eig[i].real, eig[i].imag]
    (_, _, sigma, omega), _ = scipy.optimize.curve_fit(
        ring, out["t"], out["r"], p0=guess
    )
    # measured: 4e-8 (decay rate) and 1.5e-8 (frequency) relative, the
    # nonlinearity at 1e-3 rad and RK4 at 0.02 s
    assert sigma == pytest.approx(eig[i].real, rel=1e-6)
    assert omega == pytest.approx(eig[i].imag, rel=1e-6)


def test_jacobian_matches_finite_differences():
    a, tr = _jet()
    y = np.asarray(tr.y) + np.array(
        [2, 3, -1, 0.1, -0.05, 0.08, 0.3, 0.05, 0.4, 0, 0, 0]
    )
    c = dp.Controls(de=tr.de, da=jnp.array(0.02), dr=jnp.array(-0.01), thrust=tr.thrust)
    f = jax.jit(lambda y: dp.sixdof_rates(y, c, a))
    jac = np.asarray(jax.jacfwd(f)(jnp.asarray(y)))
    fd = np.zeros_like(jac)
    for k in range(12):
        h = 1e-6 * max(1.0, abs(y[k]))
        e = np.zeros(12)
        e[k] = h
        fd[:, k] = (np.asarray(f(y + e)) - np.asarray(f(y - e))) / (2 * h)
    # central differences in float64: truncation and rounding near 1e-8
    np.testing.assert_allclose(jac, fd, rtol=1e-6, atol=1e-7)


@pytest.mark.slow
def test_lateral_derivatives_from_two_simulated_manoeuvres():
    """The experiment's two manoeuvres (aileron and rudder 3-2-1-1 and doublets),
    shortened, with white sensor noise: output error with the 6-DOF lateral model
    from a start 40% off recovers all 15 derivatives within their standard errors."""
    aircraft, _ = _jet()
    _, _, records = lateral.simulate(aircraft, seed=3, t_final=16.0)
    truth = {
        n: float(getattr(aircraft.lateral, n)) for n in dp.LATERAL_DERIVATIVE_NAMES
    }
    model = lateral.lateral_model_of(aircraft, {n: 0.6 * v for n, v in truth.items()})
    fit = dp.fit(model, records)
    assert fit.converged
    est = fit.estimates()
    z = [(est[n] - truth[n]) / fit.stderr[i] for i, n in enumerate(model.parameters)]
    # an exact model with white noise: Cramer-Rao bounds hold (measured |z| <= 2.5
    # on the full-length records); 3.5 leaves a 1% chance over 15 parameters
    assert max(map(abs, z)) < 3.5, dict(zip(model.parameters, z, strict=True))
    # the moment derivatives are well determined (measured: below 2% relative)
    for i, n in enumerate(model.parameters):
        if n.startswith(("Cl_", "Cn_")) and truth[n] != 0:
            assert fit.stderr[i] < 0.05 * abs(truth[n]), n
