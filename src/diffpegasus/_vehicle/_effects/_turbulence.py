"""Atmospheric turbulence: Dryden longitudinal and vertical gusts.

A gust realisation must plug into the `wind(t, theta)` hook, which the simulator
differentiates in `t` (the wind's rate enters the air-relative accelerations) and in
the parameters; filtered white noise would need extra states. So the gusts are a
sum of sinusoids (Shinozuka's spectral representation): frequencies jittered inside
log-spaced bins over the band where the Dryden spectra carry their power, amplitudes
`sqrt(2 Phi(omega) d omega)` and phases drawn from the seed. Over a long record the
variance is `sigma^2` and the spectrum the Dryden one (tested); it is smooth in `t`.

Dryden spectra in time with Taylor's frozen field at airspeed `V` (MIL-F-8785C),
one-sided in `omega` (rad/s), each integrating to `sigma^2`:

    Phi_u(omega) = sigma_u^2 2 L_u / (pi V) / (1 + (L_u omega / V)^2)
    Phi_w(omega) = sigma_w^2 L_w / (pi V) (1 + 3 (L_w omega / V)^2) / (1 + (L_w omega / V)^2)^2
"""

import functools

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._custom_types import ScalarLike
from ._base import AbstractEffect


FT = 0.3048  # m


def dryden_u(omega, sigma, length, airspeed):
    """One-sided longitudinal Dryden spectrum, (m/s)^2 / (rad/s)."""
    x = length * omega / airspeed
    return sigma**2 * 2 * length / (np.pi * airspeed) / (1 + x**2)


def dryden_w(omega, sigma, length, airspeed):
    """One-sided vertical Dryden spectrum, (m/s)^2 / (rad/s)."""
    x = length * omega / airspeed
    return sigma**2 * length / (np.pi * airspeed) * (1 + 3 * x**2) / (1 + x**2) ** 2


def scales(sigma, length_scale, altitude):
    """`(sigma_u, sigma_w, L_u, L_w)` (m/s, m): isotropic at `length_scale` when
    `altitude` is None, else the MIL-F-8785C low-altitude model at `altitude` m
    (clipped to 10-1000 ft): `L_w = h`, `L_u = h / (0.177 + 0.000823 h)^1.2`,
    `sigma_u = sigma_w / (0.177 + 0.000823 h)^0.4`, `h` in ft."""
    if altitude is None:
        return sigma, sigma, length_scale, length_scale
    h = float(np.clip(altitude / FT, 10.0, 1000.0))
    k = 0.177 + 0.000823 * h
    return sigma / k**0.4, sigma, h / k**1.2 * FT, h * FT


@functools.lru_cache(maxsize=64)
def _components(seed, n, spectrum, length, airspeed, stream):
    """Frequencies (rad/s), amplitudes (per unit sigma) and phases of one gust
    component, as tuples (static, so the effect stays a small Module)."""
    rng = np.random.default_rng([seed, stream])
    # in x = L omega / V the spectra have their power within 1e-3 < x < 1e3
    edges = np.geomspace(1e-3, 1e3, n + 1) * airspeed / length
    omega = edges[:-1] * (edges[1:] / edges[:-1]) ** rng.uniform(size=n)
    power = spectrum(omega, 1.0, length, airspeed) * np.diff(edges)
    power = power / power.sum()  # the band holds > 99.9%; give exactly sigma^2
    amp = np.sqrt(2 * power)
    phase = rng.uniform(0, 2 * np.pi, size=n)
    return tuple(omega.tolist()), tuple(amp.tolist()), tuple(phase.tolist())


class Turbulence(AbstractEffect):
    """Dryden turbulence: longitudinal `u_g` and vertical `w_g` gusts (earth axes,
    `w_g` positive down) of intensity `sigma` (m/s, the vertical one) and length
    scale `length_scale` (m; MIL-F-8785C's 1750 ft above 2000 ft), or scaled with
    `altitude` (m) by the low-altitude model. `airspeed` (m/s) turns the spatial
    spectra into time (frozen field; default 250 m/s, Pegasus at drop, M 0.8 at
    12 km; one value for the flight, so on a vehicle that accelerates a lot the
    gust time scale is that of the chosen speed); `seed` picks the realisation;
    `components` sinusoids per gust.
    """

    sigma: ScalarLike = 0.0
    length_scale: float = eqx.field(static=True, default=1750 * FT)
    altitude: float | None = eqx.field(static=True, default=None)
    airspeed: float = eqx.field(static=True, default=250.0)
    seed: int = eqx.field(static=True, default=0)
    components: int = eqx.field(static=True, default=200)
    name = "turbulence"
    description = "Dryden gusts, vertical intensity sigma (m/s), seeded (process noise)"
    parameter = "sigma"

    def __check_init__(self):
        if not self.length_scale > 0 or not self.airspeed > 0:
            raise ValueError("turbulence needs a positive length_scale and airspeed")

    def gusts(self, t):
        """Earth-axis gusts `(u_g, w_g)`, m/s, at time `t` (s)."""
        s_u, s_w, l_u, l_w = scales(1.0, self.length_scale, self.altitude)
        out = []
        for stream, (spec, s, length) in enumerate(
            ((dryden_u, s_u, l_u), (dryden_w, s_w, l_w))
        ):
            om, amp, ph = _components(
                self.seed, self.components, spec, length, self.airspeed, stream
            )
            om, amp, ph = jnp.asarray(om), jnp.asarray(amp), jnp.asarray(ph)
            out.append(self.sigma * s * jnp.sum(amp * jnp.cos(om * t + ph)))
        return out[0], out[1]

    def wind(self, t, theta):
        u_g, w_g = self.gusts(t)
        return u_g * jnp.cos(theta) - w_g * jnp.sin(theta), u_g * jnp.sin(
            theta
        ) + w_g * jnp.cos(theta)
