"""What a rocket's flight computer measures, from the flight's state.

- Barometric altitude: flight computers turn static pressure into altitude with the
  standard atmosphere. Over a troposphere with the standard lapse rate but another
  surface temperature `T` the reading above the pad is the geopotential height
  times `s = T_std(pad) / T` exactly, so a hot day reads low (6 % at 300 K on a high
  pad). The reading is in geopotential metres, as the standard defines pressure
  altitude and as flight computers print it.
  Ports and bay venting read a static pressure off by `c_s q` (dynamic pressure
  `q`), which lowers the reading most at burnout. A first-order lag `tau` (filtering, port volume) delays it by `tau` (to first
  order in `tau`), and near Mach 1 the shock system over the static ports lowers the
  sensed pressure by `c q b(M)` (`b` a unit bump at Mach 1, width 0.05), which reads as
  a jump of altitude.
- Accelerometer: specific force (acceleration minus gravity) along the body axis.
"""

import jax.numpy as jnp
import numpy as np

from ..._vehicle._atmosphere import (
    _H_BASE,
    _LAPSE,
    _P_BASE,
    _T_BASE,
    G0,
    geopotential_altitude,
    R_AIR,
    R_EARTH_GEOPOTENTIAL,
)


TRANSONIC_WIDTH = 0.05  # Mach; half-width of the static-pressure disturbance


def pressure_altitude(p):
    """Standard-atmosphere pressure altitude, m, of static pressure `p`, Pa
    (troposphere and lower stratosphere; numpy or jax). Geopotential metres, as the
    standard defines it and as flight computers print it (`44330.8 (1 - (p /
    101325)^0.190263)` in the troposphere)."""
    xp = jnp if not isinstance(p, np.ndarray | float | int) else np
    p = xp.asarray(p, dtype=float)
    t0, lapse, p0 = _T_BASE[0], _LAPSE[0], _P_BASE[0]
    trop = t0 / -lapse * (1.0 - (p / p0) ** (R_AIR * -lapse / G0))
    strat = _H_BASE[1] - R_AIR * _T_BASE[1] / G0 * xp.log(p / _P_BASE[1])
    return xp.where(p > _P_BASE[1], trop, strat)


def _standard_temperature(hp):
    """K, the standard atmosphere's temperature at geopotential altitude `hp` m
    (troposphere and lower stratosphere)."""
    return jnp.where(hp < _H_BASE[1], _T_BASE[0] + _LAPSE[0] * hp, _T_BASE[1])


def baro_scale(pad_pressure, temperature):
    """`s`: barometric height reading per geopotential metre of height, given the
    pad's pressure (Pa) and temperature (K)."""
    return _standard_temperature(pressure_altitude(pad_pressure)) / temperature


def layered_air(
    pad_pressure, temperature, lapse, height, *, offsets=(), top=1.0, elevation=0.0
):
    """The air at `height` m (geometric) above the pad in hydrostatic balance from
    the pad's pressure (Pa), its temperature piecewise linear in geopotential height
    above the pad: `temperature` K at the pad, falling at `lapse` K/km (-6.5 the
    standard atmosphere's) on average to `top` m, departing from that line by
    `offsets` K at `len(offsets)` evenly spaced heights between (layers of
    `top / (len(offsets) + 1)` m; the first layer's and the last's slopes continue
    below the pad and above `top`). With no offsets, one lapse rate everywhere.

    **Arguments:** `elevation` m above sea level of the pad, for geopotential height
    (`R h / (R + h)`, `R` the standard's 6356.766 km).

    **Returns:** `(pressure Pa, temperature K, reading m, rate)`: `reading` the
    standard-atmosphere (pressure) altitude above the pad a barometer shows there,
    in geopotential metres as flight computers print it, `rate` its change per
    geometric metre of height (`T_std(reading) / T` times the geopotential metres per
    geometric one; with the standard lapse `T_std(pad) / temperature`, a hot day
    reading low).
    """
    n = len(offsets)
    layer = top / (n + 1)
    # geopotential height above the pad and its rate per geometric metre
    h_asl = elevation + height
    hg = geopotential_altitude(h_asl) - geopotential_altitude(elevation)
    dhg = (R_EARTH_GEOPOTENTIAL / (R_EARTH_GEOPOTENTIAL + h_asl)) ** 2
    lapse = lapse * 1e-3
    knots_t = [temperature + lapse * layer * k for k in range(n + 2)]
    for k, d in enumerate(offsets):
        knots_t[k + 1] = knots_t[k + 1] + d
    log_ratio = 0.0
    temp = temperature
    for k in range(n + 1):
        lo = -jnp.inf if k == 0 else 0.0
        hi = jnp.inf if k == n else layer
        dz = jnp.clip(hg - k * layer, lo, hi)
        slope = (knots_t[k + 1] - knots_t[k]) / layer
        slope = jnp.where(jnp.abs(slope) < 1e-12, -1e-12, slope)
        log_ratio = log_ratio - G0 / (R_AIR * slope) * jnp.log1p(
            slope * dz / knots_t[k]
        )
        temp = temp + slope * dz
    p = pad_pressure * jnp.exp(log_ratio)
    h = pressure_altitude(p)
    reading = h - pressure_altitude(pad_pressure)
    return p, temp, reading, _standard_temperature(h) / temp * dhg


def transonic_bump(mach):
    """Unit bump of the static-pressure error at Mach 1."""
    return jnp.exp(-(((mach - 1.0) / TRANSONIC_WIDTH) ** 2))


def baro_altitude(reading, climb, scale, lag, static, transonic, q, density, g, mach):
    """Barometric altitude above the pad, m, as the flight computer reports it.

    **Arguments:** `reading`, the true static pressure's altitude above the pad (m;
    see [`layered_air`][]), `climb` rate (m/s), `scale` the reading's change per
    metre of height (see [`layered_air`][] or [`baro_scale`][]), `lag` (s), `static` (static-pressure error per dynamic
    pressure, positive reading high: ports and bay venting), `transonic` (the extra
    error at Mach 1, positive reading low), dynamic pressure `q` (Pa), air `density` (kg/m^3), gravity
    `g` (m/s^2), `mach`.
    """
    dp = (static - transonic * transonic_bump(mach)) * q
    return reading - scale * lag * climb - dp * scale / (density * g)


def axial_specific_force(accel, g, axis):
    """Specific force (m/s^2) along the unit body `axis` `(3,)`, east-north-up, for
    an acceleration `accel` `(3,)` and gravity magnitude `g` (acting down)."""
    return jnp.dot(accel, axis) + g * axis[2]
