"""Equations of motion: closed-form cases, energy, restoring moment."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diffpegasus as dp

from .helpers import numpy_channels, short_config


def _inertial(u, w, theta):
    """Body velocities to (north, down) inertial components."""
    return u * np.cos(theta) + w * np.sin(theta), -u * np.sin(theta) + w * np.cos(theta)


def test_free_fall_is_g_down_in_any_attitude():
    rng = np.random.default_rng(0)
    for _ in range(5):
        u, w, q, theta = rng.normal(size=4) * [200, 20, 0.3, 0.7]
        udot, wdot, _ = dp.pitch_plane_rates(u, w, q, theta, 0, 0, 0, 1e4, 1e5, 0, 9.7)
        # inertial acceleration = d/dt of the rotated velocity
        ax = (udot + q * w) * np.cos(theta) + (wdot - q * u) * np.sin(theta)
        az = -(udot + q * w) * np.sin(theta) + (wdot - q * u) * np.cos(theta)
        assert float(ax) == pytest.approx(0.0, abs=1e-12)
        assert float(az) == pytest.approx(9.7, rel=1e-12)


def test_hover_balance():
    m, g = 12_000.0, 9.78
    udot, wdot, qdot = dp.pitch_plane_rates(
        0.0, 0.0, 0.0, np.pi / 2, m * g, 0.0, 0.0, m, 1e5, -500.0, g
    )
    assert abs(float(udot)) < 1e-12 and abs(float(wdot)) < 1e-12 and float(qdot) == 0


def test_varying_inertia_term():
    _, _, qdot = dp.pitch_plane_rates(100, 0, 0.2, 0, 0, 0, 1000.0, 1, 2e4, -2e3, 9.8)
    assert float(qdot) == pytest.approx((1000.0 + 2e3 * 0.2) / 2e4, rel=1e-14)


def test_restoring_moment_when_cp_aft_of_cg():
    # Upward (negative) aerodynamic z force at a cp aft of the CG pitches nose down.
    m = dp.moment_about_cg(1e4, 13.5, 2.48, 0.0, -5e4, xcg=8.0, xcp=10.0)
    assert float(m) == pytest.approx(-1e5)
    # Same in the full model: more alpha, more nose-down pitch acceleration.
    config = dp.PegasusConfig()
    y = config.initial.state()
    v = jnp.hypot(y[0], y[1])

    def qdot_at(alpha):
        y2 = y.at[0].set(v * jnp.cos(alpha)).at[1].set(v * jnp.sin(alpha))
        return dp.evaluate(30.0, y2, config.model).rates[2]

    slope = jax.grad(qdot_at)(0.05)
    assert float(slope) < 0
    assert float(qdot_at(0.08)) < float(qdot_at(0.02))


def test_energy_conserved_without_aero_or_thrust():
    # No aerodynamics, no thrust: specific energy V^2/2 - g0 r0^2 / (r0 + h) is
    # constant (gravity g0 (r0 / (r0 + h))^2, standard gravity and the standard
    # atmosphere's radius)
    config = short_config()
    vehicle = config.vehicle.perturbed(lift=0.0, drag=0.0, moment=0.0, thrust=0.0)
    config = eqx.tree_at(lambda c: c.vehicle, config, vehicle)
    flight = numpy_channels(dp.simulate(config, noise=False))
    vn, vd = _inertial(flight["u"], flight["w"], flight["theta"])
    r0 = 6_356_766.0
    energy = 0.5 * (vn**2 + vd**2) - 9.80665 * r0**2 / (r0 + flight["h"])
    drift = np.max(np.abs(energy - energy[0])) / abs(energy[0])
    assert drift < 1e-10
    # and the vehicle fell: it lost altitude and gained speed
    assert flight["h"][-1] < flight["h"][0] - 1000


def test_specific_force_is_non_gravitational_acceleration():
    flight = numpy_channels(dp.simulate(short_config(), noise=False))
    t = flight["t"]
    vn, vd = _inertial(flight["u"], flight["w"], flight["theta"])
    an, ad = np.gradient(vn, t), np.gradient(vd, t)
    g = np.asarray(jax.vmap(dp.gravity)(jnp.asarray(flight["h"])))
    th = flight["theta"]
    # specific force = inertial acceleration - gravity, rotated into body axes
    fx = an * np.cos(th) - (ad - g) * np.sin(th)
    fz = an * np.sin(th) + (ad - g) * np.cos(th)
    sl = slice(50, -50)
    # 100 Hz central differences blur the 20 ms elevator-pulse edges by ~0.1 m/s^2;
    # a wrong sign or a missing gravity term would be off by ~10 m/s^2.
    np.testing.assert_allclose(flight["ax"][sl], fx[sl], atol=0.2)
    np.testing.assert_allclose(flight["az"][sl], fz[sl], atol=0.2)
