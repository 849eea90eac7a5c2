import ambiance
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diffpegasus as dp
from diffpegasus._vehicle._atmosphere import _H_BASE, geopotential_altitude


ALTITUDES = np.concatenate([np.linspace(0.0, 81_000.0, 163), [11_019.1, 47_350.0]])


@pytest.mark.parametrize(
    "ours,theirs",
    [
        ("temperature", "temperature"),
        ("pressure", "pressure"),
        ("density", "density"),
        ("speed_of_sound", "speed_of_sound"),
    ],
)
def test_matches_ambiance(ours, theirs):
    atm = jax.vmap(dp.isa)(jnp.asarray(ALTITUDES))
    reference = getattr(ambiance.Atmosphere(ALTITUDES), theirs)
    np.testing.assert_allclose(np.asarray(getattr(atm, ours)), reference, rtol=1e-6)


def test_sea_level_values():
    atm = dp.isa(0.0)
    assert float(atm.temperature) == pytest.approx(288.15, rel=1e-12)
    assert float(atm.pressure) == pytest.approx(101_325.0, rel=1e-12)
    assert float(atm.density) == pytest.approx(1.225, rel=1e-4)
    assert float(atm.speed_of_sound) == pytest.approx(340.294, rel=1e-5)


def test_continuous_across_layers():
    # Six-figure base pressures leave jumps below 1e-5 relative at the boundaries.
    r = 6_356_766.0
    for hb in _H_BASE[1:]:
        h = r * hb / (r - hb)  # geometric altitude of the boundary
        below, above = dp.isa(h - 1e-6), dp.isa(h + 1e-6)
        assert abs(float(above.pressure / below.pressure) - 1) < 1e-5
        assert abs(float(above.temperature - below.temperature)) < 1e-6


def test_gradient_is_finite_and_matches_hydrostatics():
    # dp/dh = -rho g(h) in geopotential terms: dp/dh_geometric = -rho g0 dH/dh.
    for h in [5_000.0, 15_000.0, 25_000.0, 49_000.0, 60_000.0, 80_000.0]:
        dpdh = jax.grad(lambda x: dp.isa(x).pressure)(h)
        dhg = jax.grad(geopotential_altitude)(h)
        expected = -dp.isa(h).density * 9.80665 * dhg
        assert np.isfinite(float(dpdh))
        assert float(dpdh) == pytest.approx(float(expected), rel=1e-9)


def test_gravity_inverse_square():
    # standard gravity at sea level, inverse square with the standard atmosphere's
    # effective radius: the gravity its geopotential altitude is defined with
    assert float(dp.gravity(0.0)) == pytest.approx(9.80665, rel=1e-14)
    assert float(dp.gravity(6_356_766.0)) == pytest.approx(9.80665 / 4, rel=1e-14)
    # d(geopotential)/dh = g(h) / g0: the atmosphere's and the vehicle's gravity agree
    for h in (0.0, 12_000.0, 40_000.0):
        dhg = float(jax.grad(geopotential_altitude)(h))
        assert float(dp.gravity(h)) == pytest.approx(9.80665 * dhg, rel=1e-12)
