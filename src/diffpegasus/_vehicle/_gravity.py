"""Gravity over a flat, non-rotating Earth frame: standard gravity at sea level,
decreasing with the inverse square of the distance from the Earth's centre.

The constants are those the standard atmosphere is defined with (see
`_atmosphere`): standard gravity `G0` and the effective Earth radius of its
geopotential altitude, so the atmosphere's hydrostatic pressure and the vehicle's
weight use one gravity. Standard gravity is the effective (gravitation plus the
Earth's rotation) value near 45 degrees of latitude; the real one at sea level lies
between 9.780 (equator) and 9.832 m/s^2 (poles). Newton's law with the equatorial
radius and no rotation (9.798 m/s^2) would be 0.008 m/s^2 weaker, which a
diagnosis of a low-noise log sees as an accelerometer bias.

Where a vehicle knows its latitude, `normal_gravity` (the WGS84 ellipsoid's,
the centrifugal part included) and `coriolis` (the frame turning with the Earth)
replace the flat, non-rotating frame's gravity.
"""

import numpy as np

from .._custom_types import Scalar, ScalarLike
from ._atmosphere import G0, R_EARTH_GEOPOTENTIAL


def gravity(h: ScalarLike) -> Scalar:
    """Gravitational acceleration `G0 (r0 / (r0 + h))^2` (m/s^2) at geometric
    altitude `h` (m): `G0 = 9.80665`, `r0 = 6 356 766 m` (the standard atmosphere's).

    It acts along the inertial +z axis (down).
    """
    return G0 * (R_EARTH_GEOPOTENTIAL / (R_EARTH_GEOPOTENTIAL + h)) ** 2


def normal_gravity(h: ScalarLike, latitude: float) -> Scalar:
    """The WGS84 normal gravity (m/s^2) at geometric height `h` (m) above the
    ellipsoid at geodetic `latitude` (deg): Somigliana's closed form on the
    ellipsoid (gravitation plus the Earth's rotation: 9.7803 at the equator, 9.8322
    at the poles) and the ellipsoid's second-order free-air decrease with height.
    It acts down along the local vertical."""
    import jax.numpy as jnp

    a, f, m = 6_378_137.0, 1 / 298.257223563, 0.00344978650684  # WGS84
    g_e, k, e2 = 9.7803253359, 0.00193185265241, 0.00669437999013
    s2 = float(np.sin(np.radians(latitude)) ** 2)
    g = g_e * (1 + k * s2) / np.sqrt(1 - e2 * s2)
    h = jnp.asarray(h, dtype=float)
    return g * (1 - 2 / a * (1 + f + m - 2 * f * s2) * h + 3 / a**2 * h**2)


EARTH_RATE = 7.292115e-5  # rad/s, WGS84's rotation rate (sidereal)


def coriolis(velocity, latitude: float):
    """The Coriolis acceleration `-2 Omega x v` (m/s^2, `(3,)`) of a body moving at
    `velocity` `(3,)` m/s in a pad-fixed east-north-up frame at geodetic `latitude`
    (deg): the Earth's rotation `Omega = EARTH_RATE (0, cos lat, sin lat)` there.

    Components: east `2 W (v_n sin lat - v_u cos lat)`, north `-2 W v_e sin lat`,
    up `2 W v_e cos lat`. The centrifugal part is in `normal_gravity`."""
    import jax.numpy as jnp

    lat = np.radians(latitude)
    s, c = float(np.sin(lat)), float(np.cos(lat))
    ve, vn, vu = velocity[0], velocity[1], velocity[2]
    w2 = 2.0 * EARTH_RATE
    return jnp.stack([w2 * (vn * s - vu * c), -w2 * ve * s, w2 * ve * c])
