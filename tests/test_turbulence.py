"""Dryden turbulence: variance, spectrum, scaling, smoothness and reproducibility."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.integrate as si
import scipy.signal as ss

import diffpegasus as dp
from diffpegasus._vehicle._effects import VerticalWind
from diffpegasus._vehicle._effects._turbulence import (
    dryden_u,
    dryden_w,
    scales,
    Turbulence,
)


V, L = 100.0, 300.0


@pytest.mark.parametrize("spectrum", [dryden_u, dryden_w])
def test_dryden_spectra_integrate_to_sigma_squared(spectrum):
    total, _ = si.quad(lambda w: spectrum(w, 2.0, L, V), 0, np.inf, limit=200)
    np.testing.assert_allclose(total, 4.0, rtol=1e-8)


def _series(seed, n=2**16, dt=0.05):
    eff = Turbulence(sigma=1.5, length_scale=L, airspeed=V, seed=seed)
    t = dt * np.arange(n)
    u, w = jax.jit(jax.vmap(eff.gusts))(jnp.asarray(t))
    return t, np.asarray(u), np.asarray(w)


def test_variance_and_spectrum_match_dryden():
    # 3277 s = 1100 correlation lengths at 100 m/s: the time variance of one
    # realisation is sigma^2 to ~1/sqrt(1100 / 2), i.e. a few percent
    variances = []
    for seed in range(4):
        _, u, w = _series(seed)
        variances.append([u.var(), w.var()])
        assert abs(u.mean()) < 0.15 and abs(w.mean()) < 0.15
    variances = np.array(variances)
    np.testing.assert_allclose(variances.mean(0), [1.5**2, 1.5**2], rtol=0.06)
    # Welch estimate (one-sided, per Hz) against the Dryden spectra converted to
    # per Hz (Phi(omega) 2 pi) in bands from 0.02 to 5 Hz: within 25% per band
    # (1024-sample segments, 128 averages; measured worst band 12%)
    for k, spectrum in ((1, dryden_u), (2, dryden_w)):
        f, pxx = ss.welch(_series(7)[k], fs=20.0, nperseg=1024)
        band = (f > 0.02) & (f < 5.0)
        model = spectrum(2 * np.pi * f[band], 1.5, L, V) * 2 * np.pi
        edges = np.geomspace(0.02, 5.0, 9)
        for lo, hi in zip(edges[:-1], edges[1:], strict=True):
            sel = (f[band] >= lo) & (f[band] < hi)
            ratio = pxx[band][sel].mean() / model[sel].mean()
            assert 0.75 < ratio < 1.25, (spectrum.__name__, lo, ratio)


def test_low_altitude_scaling_and_reproducibility():
    s_u, s_w, l_u, l_w = scales(1.0, 500.0, 100 * 0.3048)  # 100 ft
    k = 0.177 + 0.000823 * 100
    np.testing.assert_allclose(
        [s_u, l_w, l_u], [1 / k**0.4, 100 * 0.3048, 100 * 0.3048 / k**1.2]
    )
    assert s_w == 1.0
    a = Turbulence(sigma=1.0, seed=3).gusts(jnp.asarray(1.7))
    b = Turbulence(sigma=1.0, seed=3).gusts(jnp.asarray(1.7))
    c = Turbulence(sigma=1.0, seed=4).gusts(jnp.asarray(1.7))
    assert a == b and a != c


def test_wind_is_smooth_and_rotates_to_body_axes():
    eff = Turbulence(sigma=2.0, length_scale=L, airspeed=V)
    t0, h = 3.0, 1e-5
    # the simulator differentiates the wind in t: the jvp matches differences
    _, rate = jax.jvp(lambda t: eff.wind(t, 0.1)[1], (t0,), (1.0,))
    fd = (eff.wind(t0 + h, 0.1)[1] - eff.wind(t0 - h, 0.1)[1]) / (2 * h)
    np.testing.assert_allclose(rate, fd, rtol=1e-6)
    u_g, w_g = eff.gusts(t0)
    # level attitude: body = earth axes; the vertical gust is positive down like w
    np.testing.assert_allclose(eff.wind(t0, 0.0), (u_g, w_g), rtol=1e-14)
    # and the same rotation as the steady vertical wind
    up = VerticalWind(w_up=1.0).wind(t0, 0.3)
    gust_only = np.array(Turbulence(sigma=0.0).wind(t0, 0.3))
    np.testing.assert_allclose(gust_only, 0.0)
    ref = (
        -w_g * np.sin(0.3) + u_g * np.cos(0.3),
        w_g * np.cos(0.3) + u_g * np.sin(0.3),
    )
    np.testing.assert_allclose(eff.wind(t0, 0.3), ref, rtol=1e-12)
    assert np.sign(up[1]) == -1  # an updraft is negative w: consistent convention


def test_registered_for_hidden():
    eff = dp.parse_assignment("turbulence=1.5")
    assert isinstance(eff, Turbulence) and float(eff.sigma) == 1.5
    assert "turbulence" in dp.effect_names()
    # not a deterministic candidate of the diagnosis
    assert "turbulence" not in dp.EFFECTS
