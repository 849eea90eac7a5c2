"""Units from a column map, a header or a format, checked against what a rocket
must read: an accelerometer on the pad or at the top of the climb, the coast from
burnout to apogee, the pressure on the ground, a still gyro. A unit the data
contradict is refused with the fix; with no unit given, the one that fits is taken
with a message.
"""

import dataclasses
import json

import numpy as np

from .._errors import LogError
from ._columns import UNITS
from ._rocket_clean import Series
from ._rocket_events import G0


def _fix_hint(alternative: str) -> str:
    return f"(give it {alternative} in the column map)"


def _map_scale(c) -> float:
    """A channel's `scale` from its map: its factor over its unit's (the unit's
    alternatives the checks try keep it: an axis mapped tail-first stays so)."""
    return c.factor / UNITS.get(c.unit, UNITS.get(c.unit.lower(), 1.0))


def check_accel_axial(
    s: Series, pad: np.ndarray, near_top: np.ndarray, messages: list[str]
) -> None:
    """An axial accelerometer's unit and gravity convention against its pad
    reading (g times the sine of the rail's elevation, 0.6-1 g for rails 37-90
    degrees up, gravity included; 5 % more for a sensor's bias) or, without pad samples, its boost (thrust beats
    weight: above 1 g; below 60 g for a rocket that carries a flight computer). The
    series is converted to specific force with gravity included."""
    c = s.spec
    removed = c.gravity == "removed"
    scale = _map_scale(c)
    if pad.size >= 5:
        raw = float(np.median(s.v[pad])) / c.factor
        row = s.rows[pad[len(pad) // 2]]
        units = [(c.unit or "m/s^2", c.factor)] if c.unit_from else []
        units += [
            (u, f * scale)
            for u, f in (("m/s^2", 1.0), ("g", G0))
            if f * scale != c.factor or not c.unit_from
        ]
        gravities = [c.gravity] if c.gravity else []
        gravities += [g for g in ("included", "removed") if g != c.gravity]
        options = [
            (u, f, g, raw * f + (G0 if g == "removed" else 0.0))
            for u, f in units
            for g in gravities
        ]
        fits = [o for o in options if 0.6 * G0 <= o[3] <= 1.05 * G0]
        # what the map or the format said, as much of it as the reading allows
        fits.sort(key=lambda o: (o[2] != c.gravity, o[1] != c.factor))
        if not fits and any(0.6 * G0 <= -o[3] <= 1.05 * G0 for o in options):
            # about -1 g: the axis points tail-first (a board mounted upside down)
            raise LogError(
                f"{s.where}, row {row}: reads {raw:.4g} {c.unit or 'm/s^2'} on the "
                "pad, about -1 g: its axis points tail-first (give it "
                '{"scale": -1} in the column map)'
            )
        if not fits:
            raise LogError(
                f"{s.where}, row {row}: reads {raw:.4g} {c.unit or 'm/s^2'} on the "
                "pad, where an axial accelerometer reads about 1 g (gravity included) "
                "or 0 (1 g removed); check its unit and scale"
            )
        unit, factor, grav, _ = fits[0]
        declared_unit = bool(c.unit_from)
        if (declared_unit and factor != c.factor) or (c.gravity and grav != c.gravity):
            if declared_unit and factor != c.factor:
                what = f"1 g in {unit}, not in {c.unit}: the column looks like {unit}"
            else:
                what = (
                    "about 1 g: gravity is included"
                    if grav == "included"
                    else "about 0: 1 g is removed"
                )
            fix = json.dumps({"unit": unit, "gravity": grav})
            raise LogError(
                f"{s.where}, row {row}: reads {raw:.4g} on the pad, {what} "
                f"(give it {fix} in the column map)"
            )
        s.v = s.v / c.factor * factor + (G0 if grav == "removed" else 0.0)
        said = [f"unit {unit}"] if not declared_unit else []
        said += [f"gravity {grav}"] if not c.gravity else []
        if said or grav == "removed":
            messages.append(
                f"{s.where}: reads {raw:.3g} on the pad"
                + (f": taken as {' and '.join(said)}" if said else "")
                + (
                    "; 1 g removed by the log, g0 added back"
                    if grav == "removed"
                    else ""
                )
            )
        return
    # no pad: the boost decides the unit; gravity from the map or the format, else
    # from the end of the climb, where drag vanishes: the specific force reads ~0
    # (gravity included) or ~-1 g (1 g removed)
    if c.gravity is None and near_top.size >= 5:
        top = float(np.median(s.v[near_top]))
        for factor in (c.factor, (G0 if c.factor == scale else 1.0) * scale):
            x = top / c.factor * factor
            if abs(x) < 0.25 * G0 or abs(x + G0) < 0.25 * G0:
                grav = "included" if abs(x) < 0.25 * G0 else "removed"
                c = s.spec = dataclasses.replace(c, gravity=grav)
                removed = grav == "removed"
                messages.append(
                    f"{s.where}: no samples on the pad; reads {top / s.spec.factor:.3g} "
                    f"just before apogee, where drag vanishes: gravity {grav}"
                )
                break
    if c.gravity is None:
        raise LogError(
            f"{s.where}: the log has no samples on the pad to tell whether gravity is "
            'included; give it "gravity": "included" or "removed" in the column map'
        )
    sf = s.v + (G0 if removed else 0.0)
    peak = float(np.max(sf))
    if peak < G0 or peak > 60 * G0:
        unit = "g" if peak < G0 else "m/s^2"
        hint = _fix_hint(f'"unit": "{unit}"')
        if c.unit_from:
            raise LogError(
                f"{s.where}, row {s.rows[int(np.argmax(sf))]}: the boost peaks at "
                f"{peak / c.factor:.4g} {c.unit or 'm/s^2'}, {peak / G0:.3g} g: the "
                f"column looks like {unit} {hint}"
            )
        factor = (G0 if unit == "g" else 1.0) * scale
        s.v = s.v / c.factor * factor
        messages.append(f"{s.where}: the boost reads like {unit}: taken as {unit}")
        sf = s.v + (G0 if removed else 0.0)
    s.v = sf
    if removed:
        messages.append(f"{s.where}: 1 g removed by the log; g0 added back")


def check_pressure(s: Series, pad: np.ndarray, messages: list[str]) -> None:
    """Static pressure on the pad must lie between 30 and 110 kPa (from 9 km up to
    below sea level); hPa, kPa and psi are recognised by where the reading lands."""
    sel = pad if pad.size else np.arange(min(5, len(s.v)))
    p = float(np.median(s.v[sel]))
    if 30e3 <= p <= 110e3:
        return
    raw = p / s.spec.factor
    fits = [
        (unit, factor)
        for unit, factor in (
            ("Pa", 1.0),
            ("hPa", 100.0),
            ("kPa", 1e3),
            ("psi", UNITS["psi"]),  # 4.4-16 psi: no overlap with the others
        )
        if 30e3 <= raw * factor <= 110e3
    ]
    row = s.rows[sel[len(sel) // 2]]
    if not fits or s.spec.unit_from:
        what = (
            f"the column looks like {fits[0][0]} "
            + _fix_hint(f'"unit": "{fits[0][0]}"')
            if fits
            else "no unit makes it a pressure near the ground"
        )
        raise LogError(
            f"{s.where}, row {row}: pad pressure {raw:.6g} {s.spec.unit or 'Pa'} is "
            f"not 30-110 kPa; {what}"
        )
    unit, factor = fits[0]
    s.v = s.v / s.spec.factor * factor
    messages.append(f"{s.where}: pad pressure {raw:.6g}: read as {unit}")


def check_altitude_unit(
    s: Series,
    t_burnout: float,
    h_burnout: float,
    t_apogee: float,
    h_apogee: float,
    messages: list[str],
) -> float:
    """The coast from burnout to apogee decides metres against feet: against gravity
    and drag the rocket climbs at least g t^2 / 2 in a coast of t seconds (drag only
    adds deceleration, so more height is lost per second), and the six rockets of
    the shipped data climb 1.07-1.26 times that; a unit that makes it less than 0.8
    times or more than 2.5 times (a coast ratio of 3.28 is the same flight in feet
    read as metres) is refused or, with no unit given, replaced. Returns the factor
    applied to the series (1 if none)."""
    coast = t_apogee - t_burnout
    if not (np.isfinite(coast) and coast > 2.0):
        return 1.0
    ratio = (h_apogee - h_burnout) / (0.5 * G0 * coast**2)
    if 0.8 <= ratio <= 2.5:
        return 1.0
    c = s.spec
    raw_ratio = ratio / c.factor
    better = [
        (u, f) for u, f in (("m", 1.0), ("ft", 0.3048)) if 0.8 <= raw_ratio * f <= 2.5
    ]
    verdict = (
        f"the column looks like {better[0][0]} "
        + _fix_hint(f'"unit": "{better[0][0]}"')
        if better
        else "check its unit and scale"
    )
    detail = (
        f"{s.where}: climbs {h_apogee - h_burnout:.0f} m in the {coast:.1f} s "
        f"coast from burnout to apogee, {ratio:.2f} times a drag-free coast "
        f"(g t^2/2 = {0.5 * G0 * coast**2:.0f} m)"
    )
    if c.unit_from or not better:
        raise LogError(f"{detail}; {verdict}")
    factor = better[0][1] / c.factor
    s.v = s.v * factor
    messages.append(f"{detail}: no unit given, read as {better[0][0]}")
    return factor


def check_velocity_unit(
    s: Series, t_lift: float, t_apogee: float, h_climb: float, messages: list[str]
) -> bool:
    """A vertical speed integrated from liftoff to apogee must climb the height the
    altitude climbs there: 0.6-1.6 times it (a flight computer's Kalman speed
    lags, a telemetry link drops samples); a ratio 3.28 times that (ft/s read as
    m/s) is refused or, with no unit given, read as ft/s. A speed no unit explains
    is dropped with a message (returns False): the fit does not use a flight
    computer's speed, so its log is still read. Checked where the speed covers at
    least 80 % of the climb and the climb is at least 50 m."""
    inside = (s.t >= t_lift) & (s.t <= t_apogee)
    climb = t_apogee - t_lift
    if (
        h_climb < 50.0
        or np.count_nonzero(inside) < 10
        or s.t[inside][-1] - s.t[inside][0] < 0.8 * climb
    ):
        return True
    t, v = s.t[inside], s.v[inside]
    climbed = float(np.sum(0.5 * (v[1:] + v[:-1]) * np.diff(t)))
    ratio = climbed / h_climb
    if 0.6 <= ratio <= 1.6:
        return True
    c = s.spec
    raw = ratio / c.factor
    better = [
        (u, f) for u, f in (("m/s", 1.0), ("ft/s", 0.3048)) if 0.6 <= raw * f <= 1.6
    ]
    detail = (
        f"{s.where}: integrated from liftoff to apogee it climbs {climbed:.0f} m, "
        f"{ratio:.2f} times the altitude's {h_climb:.0f} m"
    )
    if not better:
        messages.append(f"{detail}: no unit explains it, the channel is not used")
        return False
    if c.unit_from:
        raise LogError(
            f"{detail}; the column looks like {better[0][0]} "
            + _fix_hint(f'"unit": "{better[0][0]}"')
        )
    s.v = s.v / c.factor * better[0][1]
    messages.append(f"{detail}: no unit given, read as {better[0][0]}")
    return True


def check_imu(series: dict[str, Series], pad_of, messages: list[str]) -> None:
    """3-axis accelerometers must read |a| near 1 g on the pad, gyros less than 20
    deg/s (a still rocket; MEMS biases are a few deg/s): channels that do not are
    dropped with a message (a board that logs its IMU columns but never filled
    them)."""
    acc = [n for n in ("accel_x", "accel_y", "accel_z") if n in series]
    if len(acc) == 3:
        pads = [pad_of(series[n]) for n in acc]
        if all(p.size >= 5 for p in pads):
            m = np.array(
                [np.median(series[n].v[p]) for n, p in zip(acc, pads, strict=False)]
            )
            norm = float(np.linalg.norm(m))
            if not 0.7 * G0 <= norm <= 1.3 * G0:
                s = series[acc[0]]
                raw = norm / s.spec.factor
                if 0.7 <= raw <= 1.3 and s.spec.factor == 1.0:
                    raise LogError(
                        f"{s.where}: the 3-axis accelerometer reads |a| = {raw:.3g} "
                        "on the pad, 1 g in g; the columns look like g "
                        + _fix_hint('"unit": "g"')
                    )
                for n in acc:
                    del series[n]
                messages.append(
                    f"{s.file}: 3-axis accelerometer reads |a| = {norm:.3g} m/s^2 on "
                    "the pad, not about 1 g: no usable data, accel_x/y/z not used"
                )
    for n in ("gyro_x", "gyro_y", "gyro_z"):
        if n in series:
            s = series[n]
            p = pad_of(s)
            if p.size >= 5:
                w = abs(float(np.median(s.v[p])))
                if w > np.deg2rad(20.0):
                    del series[n]
                    messages.append(
                        f"{s.where}: reads {np.rad2deg(w):.3g} deg/s on the pad, "
                        f"where a still rocket reads near 0: {n} not used"
                    )
                    continue
            if float(np.max(np.abs(s.v))) > 60.0 and s.spec.factor == 1.0:
                raise LogError(
                    f"{s.where}, row {s.rows[int(np.argmax(np.abs(s.v)))]}: "
                    f"{float(np.max(np.abs(s.v))):.4g} rad/s is no rocket's rate; the "
                    "column looks like deg/s " + _fix_hint('"unit": "deg/s"')
                )


def check_temperature(s: Series, messages: list[str]) -> None:
    """A sensor's temperature must lie between 200 and 350 K (-73 to 77 degC, a
    board in any weather and its own warmth); with no unit given, a reading that
    lands there in degC is taken as degC."""
    t = float(np.median(s.v))
    if 200.0 <= t <= 350.0:
        return
    raw = (t - s.spec.offset) / s.spec.factor
    row = s.rows[len(s.rows) // 2]
    if not s.spec.unit_from and 200.0 <= raw + 273.15 <= 350.0:
        s.v = (s.v - s.spec.offset) / s.spec.factor + 273.15
        messages.append(f"{s.where}: reads {raw:.3g}: no unit given, read as degC")
        return
    raise LogError(
        f"{s.where}, row {row}: temperature {raw:.4g} {s.spec.unit or 'K'} is not "
        '200-350 K; check its unit (degC is written "unit": "degC")'
    )
