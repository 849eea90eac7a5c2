"""Plausibility checks on the physics of a log.

A unit mistake rarely makes a log unreadable; it makes every estimate wrong by a
constant factor. The checks here compare channels that physics ties together (pitch
attitude with the integral of pitch rate, airspeed and flight-path angle with the
accelerometers, dynamic pressure with airspeed and the standard atmosphere at the
logged altitude, aerodynamic coefficients implied by forces and moments) and refuse
a log whose channels disagree by a factor no flight can explain. Each check has a
name; a sidecar `"skip_checks": [name, ...]` turns it off for data known to be right.
"""

import math
from typing import Any

import numpy as np


G = 9.80665  # m/s^2
_DEG = 180.0 / math.pi

CHECKS = (
    "rates",
    "pitch_kinematics",
    "pitch_acceleration",
    "axial",
    "normal",
    "air_data",
    "coefficients",
    "geometry",
    "specific_force",
    "drag",
)
# Largest plausible pitch rate (rad/s) and pitch acceleration (rad/s^2).
_RATE_LIMITS = {"q": 5.0, "qdot": 50.0}
# A measured/implied ratio outside [1/_FACTOR, _FACTOR] is a unit or scale mistake;
# real flights (wind, sensor misalignment, non-standard day) stay within 10-20 %.
_FACTOR = 2.0
# The kinematic checks narrow that band where the log itself pins the ratio down: the
# part of the measured motion the implied one does not explain is sqrt(1 - r^2) / r of
# it (r the partial correlation), and the band is 1 + 2 of those, at least the 25 %
# real flights can differ by (wind, misalignment) and at most _FACTOR. A log whose
# channels agree closely thus shows a knots-for-m/s (1.94) or similar mistake that
# the factor 2 let through.
_FLOOR = 1.25
# What an attitude or accelerometer misalignment of 2 degrees can shift a mean
# specific force by, as a fraction of the forces involved (sin 2 deg).
_MISALIGNMENT = math.sin(math.radians(2.0))
# Below this partial correlation the data cannot tell the ratio (too little motion
# beyond the noise), so the kinematic check says nothing.
_MIN_CORRELATION = 0.9
# 95th percentile of |coefficient| at the high dynamic pressures of a log that no
# winged vehicle or body reaches.
_COEFFICIENT_LIMITS = {"CX": 1.5, "CZ": 5.0, "CM": 2.0}


def num(x: Any) -> str:
    """A number as a user reads it (`0.299`, not `np.float64(0.299)`)."""
    try:
        return repr(float(x)) if isinstance(x, float | np.floating) else str(x)
    except (TypeError, ValueError):
        return repr(x)


def _g(x: float) -> str:
    return f"{float(x):.4g}"


def isa_density_and_sound(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Density (kg/m^3) and speed of sound (m/s) of the 1976 standard atmosphere at
    geometric altitudes `h` (m); NumPy, so a log of millions of rows costs no
    compilation."""
    from .._vehicle._atmosphere import (
        _H_BASE,
        _LAPSE,
        _P_BASE,
        _T_BASE,
        G0,
        GAMMA_AIR,
        R_AIR,
        R_EARTH_GEOPOTENTIAL,
    )

    # The standard ends at 86 km; checks use only altitudes inside it.
    h = np.clip(h, -5000.0, 86_000.0)
    hg = R_EARTH_GEOPOTENTIAL * h / (R_EARTH_GEOPOTENTIAL + h)
    k = np.clip(np.searchsorted(_H_BASE, hg, side="right") - 1, 0, len(_H_BASE) - 1)
    t_b, lapse, p_b, h_b = _T_BASE[k], _LAPSE[k], _P_BASE[k], _H_BASE[k]
    temperature = t_b + lapse * (hg - h_b)
    isothermal = lapse == 0.0
    with np.errstate(all="ignore"):
        p = np.where(
            isothermal,
            p_b * np.exp(-G0 * (hg - h_b) / (R_AIR * t_b)),
            p_b
            * (temperature / t_b) ** (-G0 / (R_AIR * np.where(isothermal, 1.0, lapse))),
        )
    return p / (R_AIR * temperature), np.sqrt(GAMMA_AIR * R_AIR * temperature)


class PlausibilityError(ValueError):
    """Channels that disagree with each other by a factor no flight explains."""


def _integral(x: np.ndarray, dt: float) -> np.ndarray:
    out = np.empty_like(x)
    out[0] = 0.0
    np.cumsum(0.5 * (x[1:] + x[:-1]) * dt, out=out[1:])
    return out


def _ratio(y: np.ndarray, x: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """Slope `k` of `y = a + b t + k x` and the partial correlation of x and y once
    a straight line in time is removed from both (a constant sensor bias integrates
    to such a line, so it does not spoil the ratio)."""
    tc = (t - t.mean()) / (np.ptp(t) or 1.0)
    tt = float(tc @ tc) or 1.0

    def detrend(z):
        # tc has zero mean, so [1, tc] are orthogonal: the projection in closed form
        return z - z.mean() - (float(tc @ z) / tt) * tc

    yr, xr = detrend(y), detrend(x)
    sxx, syy, sxy = float(xr @ xr), float(yr @ yr), float(xr @ yr)
    if sxx <= 0 or syy <= 0:
        return math.nan, 0.0
    return sxy / sxx, abs(sxy) / math.sqrt(sxx * syy)


def _unit_hint(k: float, hints: dict[float, str], within: float = 1.15) -> str:
    for factor, text in hints.items():
        if k * factor > 0 and abs(math.log(k / factor)) < math.log(within):
            return "; " + text
    return ""


def _skip_note(name: str) -> str:
    return f' (if the data are right, add "skip_checks": ["{name}"] to the sidecar)'


def _check_rates(c, name):
    for col, limit in _RATE_LIMITS.items():
        if col in c:
            v = c[col]
            i = int(np.argmax(np.abs(v)))
            if abs(v[i]) > limit:
                unit = "rad/s" if col == "q" else "rad/s^2"
                raise PlausibilityError(
                    f"{name}: column {col!r}, row {i + 1}: value {num(v[i])} is larger "
                    f"than {limit:g} {unit}, beyond any pitching flight; the column "
                    f"looks like {'deg/s' if col == 'q' else 'deg/s^2'} (flight logs "
                    f"store {unit})" + _skip_note("rates")
                )


def _check_kinematics(c, name, skip):
    t = c["t"]
    dt = float(t[1] - t[0])
    need = {
        "pitch_kinematics": ("theta", "q"),
        "pitch_acceleration": ("q", "qdot"),
        "axial": ("V", "theta", "alpha", "ax", "az"),
        "normal": ("V", "theta", "alpha", "ax", "az"),
    }
    for check, cols in need.items():
        if check in skip or not all(col in c for col in cols):
            continue
        if check == "pitch_kinematics":
            y, x = c["theta"], _integral(c["q"], dt)
            k, r = _ratio(y, x, t)
            what = (
                "the pitch attitude 'theta' changes {k} times as much as the integral "
                "of the pitch rate 'q' (d theta/dt = q in pitch-plane flight)"
            )
            hints = {
                _DEG: "theta looks like degrees; angles are in rad, rates in rad/s",
                1 / _DEG: "q looks like deg/s; pitch rate is in rad/s",
                -1.0: "q or theta has the wrong sign (q positive nose up)",
            }
        elif check == "pitch_acceleration":
            y, x = c["q"], _integral(c["qdot"], dt)
            k, r = _ratio(y, x, t)
            what = (
                "the pitch rate 'q' changes {k} times as much as the integral of the "
                "pitch acceleration 'qdot'"
            )
            hints = {
                1 / _DEG: "qdot looks like deg/s^2; pitch acceleration is in rad/s^2",
                _DEG: "q looks like deg/s while qdot is in rad/s^2",
                -1.0: "qdot has the wrong sign",
            }
        else:
            alpha, v = c["alpha"], c["V"]
            gamma = c["theta"] - alpha
            ax, az = c["ax"], c["az"]
            if check == "axial":
                y = v + _integral(G * np.sin(gamma), dt)
                x = _integral(ax * np.cos(alpha) + az * np.sin(alpha), dt)
                what = (
                    "the airspeed 'V' changes {k} times as much as the accelerometers "
                    "'ax', 'az' imply (dV/dt = ax cos alpha + az sin alpha - "
                    "g sin(theta - alpha))"
                )
            else:
                y = gamma + _integral(G * np.cos(gamma) / v, dt)
                x = _integral((ax * np.sin(alpha) - az * np.cos(alpha)) / v, dt)
                what = (
                    "the flight-path angle 'theta' - 'alpha' turns {k} times as much "
                    "as the normal acceleration from 'ax', 'az' and 'V' implies"
                )
            k, r = _ratio(y, x, t)
            hints = {
                G: "ax and az look like units of g; accelerations are in m/s^2",
                0.3048: "ax and az look like ft/s^2 (or V like ft/s); use m/s^2 "
                "and m/s",
                1 / 0.3048: "V looks like ft/s; airspeed is in m/s",
                1 / 1.943844: "V looks like knots; airspeed is in m/s",
                1.943844: "V looks like knots; airspeed is in m/s",
                0.1: "ax and az look 10 times too large",
                10.0: "ax and az look 10 times too small",
                -1.0: "az looks positive up; body z points down, so az is about "
                "-9.8 m/s^2 in level flight",
            }
        if not (math.isfinite(k) and r >= _MIN_CORRELATION):
            continue
        band = _band(r)
        if 1 / band <= k <= band:
            continue
        raise PlausibilityError(
            f"{name}: {what.format(k=_g(k))}, over rows 1-{len(t)}; the channels "
            f"agree closely (correlation {r:.3f}), so a ratio beyond {band:.2f} is a "
            f"unit or scale mistake{_unit_hint(k, hints)}" + _skip_note(check)
        )


def _band(r: float) -> float:
    """How far a kinematic ratio may stray from 1 at partial correlation `r`."""
    unexplained = math.sqrt(max(1.0 - r * r, 0.0)) / r
    return min(max(1.0 + 2.0 * unexplained, _FLOOR), _FACTOR)


def _check_specific_force(c, name):
    """The mean accelerometer readings against what the record's own motion and
    gravity require: in the pitch plane, with u = V cos(alpha), w = V sin(alpha),
    du/dt = ax - g sin(theta) - q w and dw/dt = az + g cos(theta) + q u, so over the
    record mean(ax) = du/T + mean(g sin theta + q w), and likewise for az. A factor
    beyond 2 that is also more than a 2-degree misalignment can shift the mean is a
    unit mistake (e.g. ax logged in g, read as m/s^2)."""
    if not all(col in c for col in ("t", "V", "alpha", "theta", "q")):
        return
    t, v, alpha, theta, q = (c[k] for k in ("t", "V", "alpha", "theta", "q"))
    span = float(t[-1] - t[0])
    if span <= 0:
        return
    dt = float(t[1] - t[0])
    u, w = v * np.cos(alpha), v * np.sin(alpha)

    def mean(x):
        return float(_integral(x, dt)[-1]) / span

    for col, implied, sense in (
        ("ax", (u[-1] - u[0]) / span + mean(G * np.sin(theta) + q * w), "axial"),
        ("az", (w[-1] - w[0]) / span + mean(-G * np.cos(theta) - q * u), "normal"),
    ):
        if col not in c:
            continue
        measured = mean(c[col])
        scale = max(abs(implied), abs(measured), G)
        if abs(measured - implied) <= _MISALIGNMENT * scale:
            continue
        k = measured / implied if implied else math.inf
        if 1 / _FACTOR <= k <= _FACTOR:
            continue
        raise PlausibilityError(
            f"{name}: column {col!r} averages {_g(measured)} m/s^2, but the record's "
            f"own motion ('V', 'alpha', 'theta', 'q') and gravity require a mean "
            f"{sense} specific force of {_g(implied)} m/s^2 ({_g(k)} times); "
            + (
                f"{col} looks like units of g (accelerations are in m/s^2)"
                if abs(math.log(abs(k) * G)) < math.log(1.3)
                else f"check the units of {col} (m/s^2), V (m/s) and the angles (rad)"
            )
            + _skip_note("specific_force")
        )


def _check_drag(c, meta, name):
    """Thrust against mass and acceleration: the aerodynamic force along the flight
    path, D = -((mass ax - thrust) cos alpha + mass az sin alpha), is a drag, not a
    push; a median push beyond what a 2-degree misalignment of the thrust line or the
    accelerometers explains means the thrust is too small for the mass (e.g. lbf
    logged as N) or the mass too large."""
    if not all(col in c for col in ("thrust", "mass", "ax", "az", "alpha")):
        return
    thrust, mass = c["thrust"], c["mass"]
    powered = thrust > _MISALIGNMENT * mass * G
    if "qbar" in c:
        powered &= c["qbar"] >= 0.2 * float(np.max(c["qbar"]))
    if np.count_nonzero(powered) < 2:
        return
    alpha, ax, az = c["alpha"][powered], c["ax"][powered], c["az"][powered]
    m, f = mass[powered], thrust[powered]
    drag = -((m * ax - f) * np.cos(alpha) + m * az * np.sin(alpha))
    allowance = _MISALIGNMENT * (f + m * np.hypot(ax, az))
    j = int(np.argsort(drag)[len(drag) // 2])
    if drag[j] + allowance[j] >= 0:
        return
    i = int(np.flatnonzero(powered)[j])
    ratio = (m[j] * ax[j] * np.cos(alpha[j]) + m[j] * az[j] * np.sin(alpha[j])) / (
        f[j] * np.cos(alpha[j])
    )
    raise PlausibilityError(
        f"{name}: the forces imply a drag of {_g(drag[j])} N (the median over the "
        f"powered rows, e.g. row {i + 1}: 'mass' {num(m[j])} kg times 'ax' "
        f"{num(ax[j])} m/s^2 exceeds 'thrust' {num(f[j])} N), a forward push no "
        f"airframe gives: the thrust would have to be at least {_g(ratio)} times "
        "larger for this mass"
        + _unit_hint(ratio, {4.4482216: " (thrust in lbf logged as N?)"}).replace(
            "; ", ""
        )
        + "; check thrust (N), mass (kg) and ax (m/s^2)"
        + _skip_note("drag")
    )


def _check_air_data(c, name):
    if "qbar" not in c or "V" not in c:
        return
    qbar, v = c["qbar"], c["V"]
    if "h" in c:
        h = c["h"]
        rho, sound = isa_density_and_sound(h)
        ok = (h > -1000.0) & (h < 86_000.0) & (v > 1.0)
        implied = 0.5 * rho * v**2
        use = ok & (implied > 100.0)
        if np.count_nonzero(use) >= 2:
            ratio = qbar[use] / implied[use]
            i = np.flatnonzero(use)[np.argsort(ratio)[len(ratio) // 2]]
            med = qbar[i] / implied[i]
            if not 1 / _FACTOR <= med <= _FACTOR:
                hint = _unit_hint(
                    med,
                    {
                        1e-3: "qbar looks like kPa",
                        1e-2: "qbar looks like hPa or mbar",
                        1 / 47.880259: "qbar looks like lbf/ft^2",
                        1 / 6894.757: "qbar looks like psi",
                        1.943844**-2: "V looks like knots",
                        (1 / 0.3048) ** -2: "V looks like ft/s",
                        3.6**-2: "V looks like km/h",
                    },
                )
                raise PlausibilityError(
                    f"{name}: column 'qbar', row {i + 1}: value {num(qbar[i])} Pa is "
                    f"{_g(med)} times 0.5 rho V^2 = {_g(implied[i])} Pa from 'V' "
                    f"{num(v[i])} m/s and the standard-atmosphere density at 'h' "
                    f"{num(h[i])} m (the median over the log){hint}; check the units "
                    "of qbar (Pa), V (true airspeed, m/s) and h (geometric, m)"
                    + _skip_note("air_data")
                )
        if "mach" in c:
            use = ok & (v > 30.0)
            if np.count_nonzero(use) >= 2:
                ratio = c["mach"][use] * sound[use] / v[use]
                i = np.flatnonzero(use)[np.argsort(ratio)[len(ratio) // 2]]
                med = ratio[np.argsort(ratio)[len(ratio) // 2]]
                if not 0.7 <= med <= 1.4:
                    raise PlausibilityError(
                        f"{name}: column 'mach', row {i + 1}: value "
                        f"{num(c['mach'][i])} is {_g(med)} times 'V' / speed of sound "
                        f"= {num(v[i])} m/s / {_g(sound[i])} m/s at 'h' {num(h[i])} m "
                        "(the median over the log); check the units of V (m/s) and "
                        "h (m)" + _skip_note("air_data")
                    )
    else:
        use = v > 30.0
        if np.count_nonzero(use) >= 2:
            rho = 2.0 * qbar[use] / v[use] ** 2
            j = np.argsort(rho)[len(rho) // 2]
            i = np.flatnonzero(use)[j]
            if not 1e-3 <= rho[j] <= 1.6:
                raise PlausibilityError(
                    f"{name}: column 'qbar', row {i + 1}: value {num(qbar[i])} Pa with "
                    f"'V' {num(v[i])} m/s implies an air density of {_g(rho[j])} "
                    "kg/m^3 (the median over the log), outside 0.001-1.6 kg/m^3; "
                    "check the units of qbar (Pa) and V (true airspeed, m/s)"
                    + _skip_note("air_data")
                )


def _check_coefficients(c, meta, name):
    need = ("qbar", "mass", "ax", "az")
    if not all(col in c for col in need):
        return
    qbar = c["qbar"]
    peak = float(np.max(qbar))
    if peak < 500.0:
        return
    use = qbar >= 0.2 * peak
    s_ref, c_ref = float(meta["S_ref"]), float(meta["c_ref"])
    qs = qbar[use] * s_ref
    coef = {
        "CZ": (c["mass"][use] * c["az"][use] / qs, "mass * az / (qbar S_ref)"),
    }
    thrust = c["thrust"][use] if "thrust" in c else 0.0
    coef["CX"] = (
        (c["mass"][use] * c["ax"][use] - thrust) / qs,
        "(mass * ax - thrust) / (qbar S_ref)",
    )
    if all(col in c for col in ("Iyy", "qdot")):
        moment = c["Iyy"][use] * c["qdot"][use]
        if "Iyy_dot" in c and "q" in c:
            moment = moment + c["Iyy_dot"][use] * c["q"][use]
        coef["CM"] = (moment / (qs * c_ref), "Iyy qdot / (qbar S_ref c_ref)")
    for key in ("CZ", "CX", "CM"):
        if key not in coef:
            continue
        values, formula = coef[key]
        mag = np.abs(values)
        p95 = float(np.percentile(mag, 95))
        if p95 > _COEFFICIENT_LIMITS[key]:
            i = int(np.flatnonzero(use)[np.argmin(np.abs(mag - p95))])
            raise PlausibilityError(
                f"{name}: the forces imply |{key}| = |{formula}| of {_g(p95)} (95th "
                f"percentile over the rows with qbar above 20% of its peak, e.g. row "
                f"{i + 1}), more than {_COEFFICIENT_LIMITS[key]:g} that no airframe "
                "reaches; a channel is probably in the wrong unit or scale (mass kg, "
                "ax/az m/s^2, thrust N, Iyy kg m^2, qdot rad/s^2, qbar Pa) or the "
                f"sidecar's S_ref {num(s_ref)} m^2 / c_ref {num(c_ref)} m do not "
                "belong to this vehicle" + _skip_note("coefficients")
            )


def _check_geometry(c, meta, name, where):
    s_ref, c_ref = float(meta["S_ref"]), float(meta["c_ref"])
    shape = c_ref / math.sqrt(s_ref)
    if not 0.05 <= shape <= 5.0:
        raise PlausibilityError(
            f"{where}: c_ref {num(c_ref)} m and S_ref {num(s_ref)} m^2 do not belong "
            f"to one vehicle (c_ref / sqrt(S_ref) = {_g(shape)}, outside 0.05-5); "
            "S_ref is in m^2, c_ref in m" + _skip_note("geometry")
        )
    if "mass" in c:
        loading = float(np.median(c["mass"])) / s_ref
        if not 0.5 <= loading <= 20_000.0:
            raise PlausibilityError(
                f"{where}: mass / S_ref = {_g(loading)} kg/m^2 (median 'mass' of "
                f"{name} over S_ref {num(s_ref)} m^2) is outside 0.5-20000 kg/m^2 "
                "of flying vehicles; check S_ref (m^2) and mass (kg)"
                + _skip_note("geometry")
            )


def check_physics(
    channels: dict[str, np.ndarray], metadata: dict[str, Any], name: str, where: str
) -> None:
    """Raise [`PlausibilityError`][] for the first sign of a unit or scale mistake.

    **Arguments:**

    - `channels`: validated channels (finite, uniform time, angles already checked
      against their radian limits).
    - `metadata`: the sidecar with `S_ref`, `c_ref` and optionally `skip_checks`.
    - `name`: the log file, for messages; `where`: the sidecar, for messages about
      reference geometry.
    """
    skip = set(metadata.get("skip_checks", ()))
    for col in ("qbar", "mach"):
        if col in channels:
            bad = np.flatnonzero(channels[col] < 0)
            if bad.size:
                i = int(bad[0])
                raise PlausibilityError(
                    f"{name}: column {col!r}, row {i + 1}: value "
                    f"{num(channels[col][i])} is negative; "
                    f"{'dynamic pressure' if col == 'qbar' else 'Mach number'} "
                    "cannot be (a sign or offset mistake in the data)"
                )
    if "geometry" not in skip:
        _check_geometry(channels, metadata, name, where)
    if "rates" not in skip:
        _check_rates(channels, name)
    _check_kinematics(channels, name, skip)
    if "air_data" not in skip:
        _check_air_data(channels, name)
    if "coefficients" not in skip:
        _check_coefficients(channels, metadata, name)
    if "specific_force" not in skip:
        _check_specific_force(channels, name)
    if "drag" not in skip:
        _check_drag(channels, metadata, name)
