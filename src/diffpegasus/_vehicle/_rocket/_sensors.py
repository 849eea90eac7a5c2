"""What a rocket's flight computer measures, from the flight's state.

- Barometric altitude: flight computers turn static pressure into altitude with the
  standard atmosphere. Over a troposphere with the standard lapse rate but another
  surface temperature `T` the reading above the pad is the geometric height times
  `s = T_std(pad) / T` exactly, so a hot day reads low (6 % at 300 K on a high pad).
  Ports and bay venting read a static pressure off by `c_s q` (dynamic pressure
  `q`), which lowers the reading most at burnout. A first-order lag `tau` (filtering, port volume) delays it by `tau` (to first
  order in `tau`), and near Mach 1 the shock system over the static ports lowers the
  sensed pressure by `c q b(M)` (`b` a unit bump at Mach 1, width 0.05), which reads as
  a jump of altitude.
- Accelerometer: specific force (acceleration minus gravity) along the body axis.
"""

import jax.numpy as jnp
import numpy as np

from ..._vehicle._atmosphere import _H_BASE, _LAPSE, _P_BASE, _T_BASE, G0, isa, R_AIR


_R_EARTH = 6_356_766.0  # m, the standard atmosphere's geopotential radius
TRANSONIC_WIDTH = 0.05  # Mach; half-width of the static-pressure disturbance


def pressure_altitude(p):
    """Standard-atmosphere (pressure) altitude, m, of static pressure `p`, Pa
    (troposphere and lower stratosphere; numpy or jax)."""
    xp = jnp if not isinstance(p, np.ndarray | float | int) else np
    p = xp.asarray(p, dtype=float)
    t0, lapse, p0 = _T_BASE[0], _LAPSE[0], _P_BASE[0]
    trop = t0 / -lapse * (1.0 - (p / p0) ** (R_AIR * -lapse / G0))
    strat = _H_BASE[1] - R_AIR * _T_BASE[1] / G0 * xp.log(p / _P_BASE[1])
    hg = xp.where(p > _P_BASE[1], trop, strat)
    return _R_EARTH * hg / (_R_EARTH - hg)  # geopotential to geometric


def baro_scale(pad_pressure, temperature):
    """`s`: barometric height reading per metre of geometric height, given the pad's
    pressure (Pa) and temperature (K)."""
    return isa(pressure_altitude(pad_pressure)).temperature / temperature


def linear_lapse_air(pad_pressure, temperature, lapse, height):
    """The air at `height` m above the pad in an atmosphere whose temperature falls
    linearly with height from `temperature` K at the pad at `lapse` K/km (-6.5 is
    the standard atmosphere's), in hydrostatic balance from the pad's pressure (Pa).

    **Returns:** `(pressure Pa, temperature K, reading m, rate)`: `reading` the
    standard-atmosphere (pressure) altitude above the pad a barometer shows there,
    `rate` its change per metre of height (`T_std(reading) / T`, times the
    geometric metres per geopotential one at the reading; with the standard
    lapse it is `T_std(pad) / temperature` at every height, a hot day reading low).
    """
    lapse = lapse * 1e-3
    lapse = jnp.where(jnp.abs(lapse) < 1e-9, -1e-9, lapse)
    temp = temperature + lapse * height
    log_ratio = -G0 / (R_AIR * lapse) * jnp.log1p(lapse * height / temperature)
    p = pad_pressure * jnp.exp(log_ratio)
    h_pad = pressure_altitude(pad_pressure)
    h = pressure_altitude(p)
    t_std = isa(h).temperature
    # the standard atmosphere is in geopotential height; the reading in geometric
    geometric = ((_R_EARTH + h) / _R_EARTH) ** 2
    return p, temp, h - h_pad, t_std / temp * geometric


def transonic_bump(mach):
    """Unit bump of the static-pressure error at Mach 1."""
    return jnp.exp(-(((mach - 1.0) / TRANSONIC_WIDTH) ** 2))


def baro_altitude(reading, climb, scale, lag, static, transonic, q, density, g, mach):
    """Barometric altitude above the pad, m, as the flight computer reports it.

    **Arguments:** `reading`, the true static pressure's altitude above the pad (m;
    see [`linear_lapse_air`][]), `climb` rate (m/s), `scale` the reading's change per
    metre of height (see [`linear_lapse_air`][] or [`baro_scale`][]), `lag` (s), `static` (static-pressure error per dynamic
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
