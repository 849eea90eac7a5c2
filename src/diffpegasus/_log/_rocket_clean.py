"""What flight computers leave in their logs, cleaned with a message, and units
checked against what a rocket on its pad and in flight must read.

Cleaned (each with one message naming file and column): exact duplicate rows,
rows repeating a time with other values, rows with no time, samples a channel
leaves empty, positions held between GNSS fixes, and a final run of samples that
fall faster than free fall from apogee allows (a write cut short). Reported but
kept: dropouts (gaps on the log's own sample grid), changes of sample rate, a log
that starts after liftoff. Refused with one [`LogError`][] line naming file,
column, row and value: time running backwards, and a unit the data contradict.
"""

import dataclasses
import pathlib

import numpy as np

from .._errors import LogError
from ._rocket_events import G0, quantum, robust_sigma
from ._rocket_maps import ChannelSpec, StreamSpec


@dataclasses.dataclass
class Series:
    """One channel while it is being cleaned: file time (s), SI values, data rows
    (from 1, the row after the header), and where it came from."""

    t: np.ndarray
    v: np.ndarray
    rows: np.ndarray
    spec: ChannelSpec
    file: pathlib.Path

    def keep(self, mask: np.ndarray) -> None:
        self.t, self.v, self.rows = self.t[mask], self.v[mask], self.rows[mask]

    @property
    def where(self) -> str:
        return f"{self.file}: column {self.spec.column!r}"


def _seg_rates(t: np.ndarray) -> list[tuple[float, float]]:
    """Sample-rate segments [(start time, median step)]. A running median of the
    steps (21 samples) put in half-octave bins marks where the rate changes; a run
    shorter than 20 samples, or one whose steps are not mostly (half) its own step
    within 10 % (gaps of a telemetry link, not a new rate), joins the run before."""
    dt = np.diff(t)
    if dt.size < 42:
        return [(float(t[0]), float(np.median(dt)) if dt.size else 0.0)]
    k = 21
    padded = np.pad(dt, k // 2, mode="edge")
    med = np.median(np.lib.stride_tricks.sliding_window_view(padded, k), axis=1)
    level = np.round(2 * np.log2(med))
    starts = np.concatenate([[0], np.flatnonzero(np.diff(level)) + 1])
    bounds = list(zip(starts, [*starts[1:], dt.size], strict=True))
    kept: list[list[int]] = []
    for a, b in bounds:
        seg = dt[a:b]
        step = float(np.median(seg))
        regular = np.mean(np.abs(seg - step) <= 0.1 * step) >= 0.5
        if kept and (b - a < 20 or not regular):
            kept[-1][1] = b
        else:
            kept.append([a, b])
    merged: list[list[int]] = []
    for a, b in kept:
        if merged:
            prev = np.median(dt[merged[-1][0] : merged[-1][1]])
            if abs(np.log(np.median(dt[a:b]) / prev)) < np.log(1.5):
                merged[-1][1] = b
                continue
        merged.append([a, b])
    return [(float(t[a]), float(np.median(dt[a:b]))) for a, b in merged]


def timing_messages(t: np.ndarray, where: str) -> list[str]:
    """Rate changes and dropouts of one stream, in words."""
    if len(t) < 3:
        return []
    messages = []
    segments = _seg_rates(t)
    if len(segments) > 1:
        parts = ", then ".join(
            f"{1 / step:.3g} Hz from {start:.2f} s" for start, step in segments
        )
        messages.append(f"{where}: the sample rate changes: {parts}")
    dt = np.diff(t)
    missing, largest, at = 0, 0.0, 0.0
    for k, (start, step) in enumerate(segments):
        stop = segments[k + 1][0] if k + 1 < len(segments) else np.inf
        sel = (t[:-1] >= start) & (t[:-1] < stop)
        gaps = dt[sel] / step
        miss = np.maximum(np.round(gaps) - 1, 0)
        missing += int(miss.sum())
        if sel.any() and gaps.max() > 1.5 and dt[sel].max() > largest:
            j = int(np.argmax(np.where(sel, dt, 0)))
            largest, at = float(dt[j]), float(t[j])
    if missing:
        messages.append(
            f"{where}: dropouts: {missing} samples missing on the log's own grid "
            f"({len(t)} of {len(t) + missing} present; largest gap {largest:.3g} s "
            f"at {at:.2f} s); kept as they are, each channel on its own times"
        )
    return messages


def clean_stream(
    spec: StreamSpec, data: np.ndarray, cols: dict[str, int]
) -> tuple[dict[str, Series], list[str]]:
    """The channels of one stream from the file's numbers (`cols`: column name to
    position in `data`), cleaned. Times are in the file's own seconds."""
    file = spec.file
    messages: list[str] = []
    rows = np.arange(1, len(data) + 1)
    t = data[:, cols[spec.time.column]] * spec.time.factor
    names = [c for c in spec.channels if not c.axis_auto]
    raw = (
        np.column_stack([data[:, cols[c.column]] for c in names])
        if names
        else np.empty((len(t), 0))
    )
    where_t = f"{file}: column {spec.time.column!r}"
    has_t = np.isfinite(t)
    if not has_t.all():
        last = int(np.flatnonzero(has_t)[-1]) if has_t.any() else -1
        inner = int(np.count_nonzero(~has_t[: last + 1]))
        if inner:
            messages.append(f"{where_t}: {inner} rows without a time skipped")
        t, raw, rows = t[has_t], raw[has_t], rows[has_t]
    if len(t) < 2:
        raise LogError(f"{where_t}: fewer than 2 rows with a time")
    same = np.concatenate([[False], np.diff(t) == 0])
    if same.any():
        equal = np.concatenate(
            [
                [False],
                np.all(
                    (raw[1:] == raw[:-1]) | (np.isnan(raw[1:]) & np.isnan(raw[:-1])),
                    axis=1,
                ),
            ]
        )
        exact = int(np.count_nonzero(same & equal))
        clash = int(np.count_nonzero(same & ~equal))
        if exact:
            messages.append(
                f"{file}: dropped {exact} duplicate rows (same time and values as the "
                f"row before; first at row {rows[np.argmax(same & equal)]})"
            )
        if clash:
            r = rows[np.argmax(same & ~equal)]
            messages.append(
                f"{where_t}: dropped {clash} rows repeating the previous row's time "
                f"with other values (first at row {r}); the first of each is kept"
            )
        t, raw, rows = t[~same], raw[~same], rows[~same]
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        i = int(back[0]) + 1
        raise LogError(
            f"{where_t}, row {rows[i]}: time {t[i]:.6g} s is before the previous "
            f"row's {t[i - 1]:.6g} s (a log must run forward; split it into one "
            "file per flight)"
        )
    span = float(t[-1] - t[0])
    if span > 2e4:
        if spec.time.unit_from:
            raise LogError(
                f"{where_t}, row {rows[-1]}: value {t[-1]:.6g} s makes a log "
                f"{span / 3600:.1f} h long; the column looks like milliseconds (give "
                'it "unit": "ms" in the column map)'
            )
        t = t * 1e-3
        messages.append(
            f"{where_t}: no unit given and {span:.6g} s is no flight: read as ms"
        )
    out: dict[str, Series] = {}
    for k, c in enumerate(names):
        v = raw[:, k] * c.factor + c.offset
        ok = np.isfinite(v)
        where = f"{file}: column {c.column!r}"
        if not ok.any():
            messages.append(f"{where}: no values, channel {c.name!r} not used")
            continue
        if not ok.all():
            messages.append(
                f"{where}: {int(np.count_nonzero(~ok))} empty or NaN samples dropped "
                f"from channel {c.name!r} (first at row {rows[np.argmax(~ok)]})"
            )
        s = Series(t[ok], v[ok], rows[ok], c, file)
        if np.ptp(s.v) == 0 and c.name not in ("gnss_lat", "gnss_lon", "gnss_alt"):
            messages.append(
                f"{where}: {s.v[0] / c.factor - c.offset / c.factor:g} throughout, no "
                f"data: channel {c.name!r} not used"
            )
            continue
        out[c.name] = s
    _drop_held_fixes(out, messages)
    messages += timing_messages(t, f"{file}: {spec.time.column!r}")
    return out, messages


def _drop_held_fixes(out: dict[str, Series], messages: list[str]) -> None:
    """A GNSS receiver updates slower than most logs are written: where the
    position repeats in most rows (all its channels together), keep the rows where
    it changes, so that each fix has its own time."""
    names = [n for n in ("gnss_lat", "gnss_lon", "gnss_alt") if n in out]
    if not names or len({len(out[n].t) for n in names}) != 1:
        return
    stack = np.column_stack([out[n].v for n in names])
    held = np.concatenate([[False], np.all(stack[1:] == stack[:-1], axis=1)])
    if held.mean() > 0.5:
        for n in names:
            out[n].keep(~held)
        messages.append(
            f"{out[names[0]].file}: the GNSS position is held between fixes; kept the "
            f"{int(np.count_nonzero(~held))} rows where it changes"
        )


# --- units ---------------------------------------------------------------------------


def _fix_hint(alternative: str) -> str:
    return f"(give it {alternative} in the column map)"


def check_accel_axial(s: Series, pad: np.ndarray, messages: list[str]) -> None:
    """An axial accelerometer's unit and gravity convention against its pad
    reading (g times the sine of the rail's elevation, 0.6-1 g for rails 37-90
    degrees up, gravity included; 5 % more for a sensor's bias) or, without pad samples, its boost (thrust beats
    weight: above 1 g; below 60 g for a rocket that carries a flight computer). The
    series is converted to specific force with gravity included."""
    c = s.spec
    removed = c.gravity == "removed"
    if pad.size >= 5:
        raw = float(np.median(s.v[pad])) / c.factor
        row = s.rows[pad[len(pad) // 2]]
        units = [(c.unit or "m/s^2", c.factor)] if c.unit_from else []
        units += [
            (u, f)
            for u, f in (("m/s^2", 1.0), ("g", G0))
            if f != c.factor or not c.unit_from
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
            fix = {"unit": unit, "gravity": grav}
            raise LogError(
                f"{s.where}, row {row}: reads {raw:.4g} on the pad, {what} "
                f"(give it {fix} in the column map)".replace("'", '"')
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
    # no pad: the boost decides the unit; gravity from the map or the format
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
        factor = G0 if unit == "g" else 1.0
        s.v = s.v / c.factor * factor
        messages.append(f"{s.where}: the boost reads like {unit}: taken as {unit}")
        sf = s.v + (G0 if removed else 0.0)
    s.v = sf
    if removed:
        messages.append(f"{s.where}: 1 g removed by the log; g0 added back")


def check_pressure(s: Series, pad: np.ndarray, messages: list[str]) -> None:
    """Static pressure on the pad must lie between 30 and 110 kPa (from 9 km up to
    below sea level); hPa and kPa are recognised by where the reading lands."""
    sel = pad if pad.size else np.arange(min(5, len(s.v)))
    p = float(np.median(s.v[sel]))
    if 30e3 <= p <= 110e3:
        return
    raw = p / s.spec.factor
    for unit, factor in (("Pa", 1.0), ("hPa", 100.0), ("kPa", 1e3), ("mbar", 100.0)):
        if 30e3 <= raw * factor <= 110e3:
            break
    else:
        unit = None
    row = s.rows[sel[len(sel) // 2]]
    if unit is None or s.spec.unit_from:
        what = (
            f"the column looks like {unit} "
            + _fix_hint(f'"unit": "{unit.lower() if unit != "mbar" else "hpa"}"')
            if unit
            else "no unit makes it a pressure near the ground"
        )
        raise LogError(
            f"{s.where}, row {row}: pad pressure {raw:.6g} {s.spec.unit or 'Pa'} is "
            f"not 30-110 kPa; {what}"
        )
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


def check_imu(series: dict[str, Series], pad_of, messages: list[str]) -> None:
    """3-axis accelerometers must read |a| near 1 g on the pad, gyros less than 20
    deg/s (a still rocket; MEMS biases are a few deg/s): channels that do not are
    dropped with a message (a board that logs its IMU columns but never filled
    them)."""
    acc = [n for n in ("accel_x", "accel_y", "accel_z") if n in series]
    if len(acc) == 3:
        pads = [pad_of(series[n]) for n in acc]
        if all(p.size >= 5 for p in pads):
            m = np.array([np.median(series[n].v[p]) for n, p in zip(acc, pads)])
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


def impossible_tail(
    s: Series, t_apogee: float, h_apogee: float
) -> tuple[int | None, list[float]]:
    """After apogee a rocket cannot fall faster than from rest at apogee in vacuum:
    a drop of more than `sqrt(2 g (H - h)) dt + g dt^2 / 2` plus five times the
    altitude noise between a good sample and the next is impossible. Returns the
    index from which every sample is impossible (a corrupt end of file, to drop),
    or `None`, and the start times of impossible excursions the record returns from
    (ejection-charge pressure pulses: deployment marks)."""
    t, h = s.t, s.v
    after = np.flatnonzero(t > t_apogee)
    if after.size < 2:
        return None, []
    margin = 5.0 * robust_sigma(h) + quantum(h)
    top = max(h_apogee, float(h[after].max())) + margin

    def allowed(good, i):
        dt = t[i] - t[good]
        return (
            np.sqrt(2 * G0 * np.maximum(top - h[good], 0.0)) * dt
            + 0.5 * G0 * dt**2
            + margin
        )

    prev, this = after[:-1], after[1:]
    suspects = this[h[prev] - h[this] > allowed(prev, this)]
    bad_from, pulses, i_done = None, [], -1
    for first in suspects:
        if first <= i_done:
            continue
        good = int(first) - 1
        i = int(first)
        while i < len(t) and h[good] - h[i] > allowed(good, i):
            i += 1
        if i == len(t):
            bad_from = int(first)
            break
        pulses.append(float(t[first]))
        i_done = i
    return bad_from, pulses
