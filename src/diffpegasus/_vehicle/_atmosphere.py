"""International Standard Atmosphere (U.S. Standard Atmosphere 1976, 0-86 km).

Layers are defined in geopotential altitude with the standard's base temperatures,
lapse rates and base pressures (the six-figure table values, as `ambiance` and most
textbooks use them). Geometric altitude is converted with the standard's effective
Earth radius. Above 84.852 km geopotential (86 km geometric) the last layer is
extrapolated; below 0 m the first layer is.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._custom_types import Scalar, ScalarLike


G0 = 9.80665  # m/s^2, standard gravity used to define geopotential
R_AIR = 287.05287  # J/(kg K)
GAMMA_AIR = 1.4
R_EARTH_GEOPOTENTIAL = 6_356_766.0  # m
P_SEA_LEVEL = 101_325.0  # Pa

# Layer bases: geopotential altitude (m), temperature (K), lapse rate (K/m), pressure (Pa).
_H_BASE = np.array([0.0, 11e3, 20e3, 32e3, 47e3, 51e3, 71e3])
_T_BASE = np.array([288.15, 216.65, 216.65, 228.65, 270.65, 270.65, 214.65])
_LAPSE = np.array([-6.5e-3, 0.0, 1.0e-3, 2.8e-3, 0.0, -2.8e-3, -2.0e-3])
_P_BASE = np.array(
    [1.01325e5, 2.26320e4, 5.47487e3, 8.68014e2, 1.10906e2, 6.69384e1, 3.95639e0]
)


class Atmosphere(eqx.Module):
    """Atmospheric state at one altitude.

    **Fields:**

    - `temperature`: static temperature, K.
    - `pressure`: static pressure, Pa.
    - `density`: air density, kg/m^3.
    - `speed_of_sound`: m/s.
    """

    temperature: Scalar
    pressure: Scalar
    density: Scalar
    speed_of_sound: Scalar


def geopotential_altitude(h: ScalarLike) -> Scalar:
    """Geopotential altitude (m) of a geometric altitude `h` (m)."""
    return R_EARTH_GEOPOTENTIAL * h / (R_EARTH_GEOPOTENTIAL + h)


def isa(h: ScalarLike) -> Atmosphere:
    """The 1976 standard atmosphere at geometric altitude `h`.

    **Arguments:**

    - `h`: geometric altitude above mean sea level, m (scalar; `jax.vmap` for arrays).

    **Returns:**

    An [`Atmosphere`][] with temperature, pressure, density and speed of sound.
    Differentiable in `h` everywhere (the isothermal layers use their own formula,
    so no `0/0` appears in the gradient).
    """
    hg = geopotential_altitude(jnp.asarray(h, dtype=float))
    layer = jnp.clip(
        jnp.searchsorted(_H_BASE, hg, side="right") - 1, 0, len(_H_BASE) - 1
    )
    h_b = jnp.asarray(_H_BASE)[layer]
    t_b = jnp.asarray(_T_BASE)[layer]
    lapse = jnp.asarray(_LAPSE)[layer]
    p_b = jnp.asarray(_P_BASE)[layer]
    dh = hg - h_b
    temperature = t_b + lapse * dh
    isothermal = lapse == 0.0
    safe_lapse = jnp.where(isothermal, 1.0, lapse)
    p_gradient = p_b * (temperature / t_b) ** (-G0 / (R_AIR * safe_lapse))
    p_isothermal = p_b * jnp.exp(-G0 * dh / (R_AIR * t_b))
    pressure = jnp.where(isothermal, p_isothermal, p_gradient)
    density = pressure / (R_AIR * temperature)
    speed_of_sound = jnp.sqrt(GAMMA_AIR * R_AIR * temperature)
    return Atmosphere(temperature, pressure, density, speed_of_sound)


def dynamic_pressure(density: ScalarLike, airspeed: ScalarLike) -> Scalar:
    """Dynamic pressure `rho V^2 / 2`, Pa."""
    return 0.5 * density * airspeed**2
