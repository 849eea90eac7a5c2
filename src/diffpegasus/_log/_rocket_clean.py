"""What flight computers leave in their logs, cleaned with a message.

Cleaned (each with one message naming file and column): exact duplicate rows,
rows repeating a time with other values, rows with no time, samples a channel
leaves empty, positions held between GNSS fixes, and a final run of samples that
fall faster than free fall from apogee allows (a write cut short). Reported but
kept: dropouts (gaps on the log's own sample grid), changes of sample rate, a log
that starts after liftoff. Refused with one [`LogError`][] line naming file,
column, row and value: time running backwards, a value no measurement holds (a
corrupt cell: see `_columns.corrupt_cell`).
"""

import dataclasses
import pathlib

import numpy as np

from .._errors import LogError
from ._columns import corrupt_cell
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
    """Sample-rate segments [(start time, median step)]. The steps' medians over
    blocks of 20 or more samples (at most 2000 blocks), in half-octave bins, mark
    where the rate changes; a run whose steps are not mostly (half) its own step
    within 25 % or the time's resolution (gaps of a telemetry link: 2 steps and
    more, not a new rate) joins the run before, and neighbours within a factor 1.5
    merge; each change is then placed to the sample within its blocks."""
    dt = np.diff(t)
    if dt.size < 40:
        return [(float(t[0]), float(np.median(dt)) if dt.size else 0.0)]
    distinct = np.unique(dt)
    resolution = float(np.min(np.diff(distinct))) if distinct.size > 1 else 0.0

    def regular(seg):
        step = float(np.median(seg))
        return np.mean(np.abs(seg - step) <= max(0.25 * step, resolution)) >= 0.5

    if regular(dt) and np.ptp(dt) <= max(0.1 * np.median(dt), resolution):
        return [(float(t[0]), float(np.median(dt)))]
    block = max(20, -(-dt.size // 2000))
    edges = np.arange(0, dt.size, block)
    level = np.array(
        [np.round(2 * np.log2(np.median(dt[e : e + block]))) for e in edges]
    )
    starts = edges[np.concatenate([[0], np.flatnonzero(np.diff(level)) + 1])]
    bounds = list(zip(starts, [*starts[1:], dt.size], strict=True))
    kept: list[list[int]] = []
    for a, b in bounds:
        if kept and not regular(dt[a:b]):
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
    steps = [float(np.median(dt[a:b])) for a, b in merged]
    starts = [0]
    for j in range(1, len(merged)):
        lo, hi = max(merged[j][0] - block, 0), min(merged[j][0] + block, dt.size)
        w = np.log(dt[lo:hi])
        left = np.concatenate([[0.0], np.cumsum(np.abs(w - np.log(steps[j - 1])))])
        right = np.concatenate(
            [np.cumsum(np.abs(w - np.log(steps[j]))[::-1])[::-1], [0.0]]
        )
        starts.append(lo + int(np.argmin(left + right)))
    return [(float(t[a]), step) for a, step in zip(starts, steps, strict=True)]


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
    t = (
        spec.time.step * np.arange(len(data), dtype=float)
        if spec.time.step is not None
        else data[:, cols[spec.time.column]] * spec.time.factor
    )
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
            f"{where_t}, row {rows[i]}: time {t[i]:.15g} s is before the previous "
            f"row's {t[i - 1]:.15g} s (a log must run forward; split it into one "
            "file per flight)"
        )
    span = float(t[-1] - t[0])
    gaps = np.diff(t)
    k = int(np.argmax(gaps)) if gaps.size else 0
    if gaps.size and gaps[k] >= 43200.0 and span - gaps[k] <= 2e4:
        # one jump of half a day or more in what is otherwise a flight's seconds:
        # a date or a clock reset, not milliseconds
        raise LogError(
            f"{where_t}, row {rows[k + 1]}: the time jumps {gaps[k] / 3600:+.1f} h "
            f"from row {rows[k]} (a date or clock reset mid-flight); a flight's log "
            "runs minutes, correct the times or split the file there"
        )
    if span > 2e4:
        if spec.time.unit_from:
            raise LogError(
                f"{where_t}, row {rows[-1]}: value {t[-1]:.6g} s makes a log "
                f"{span / 3600:.1f} h long; the column looks like milliseconds (give "
                'it "unit": "ms" in the column map)'
            )
        # a flight's minutes are no flight in ms either in microseconds (a
        # logger's micros(): 27 s of flight is 2.7e7), nor are samples more than a
        # second apart (a short log's 1.6e7 us are 4.5 h in ms, its samples 50 s)
        step = float(np.median(gaps[gaps > 0])) if np.any(gaps > 0) else 0.0
        ms = span * 1e-3 <= 2e4 and step * 1e-3 <= 1.0
        unit, factor = ("ms", 1e-3) if ms else ("us", 1e-6)
        t = t * factor
        messages.append(
            f"{where_t}: no unit given and {span:.6g} s is no flight: read as {unit}"
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
        found = corrupt_cell(s.v)
        if found is not None:
            i, why = found
            raise LogError(
                f"{where}, row {s.rows[i]}: value {raw[ok][i, k]:g} {why} (channel "
                f"{c.name!r})"
            )
        if np.ptp(s.v) == 0 and c.name not in ("gnss_lat", "gnss_lon", "gnss_alt"):
            messages.append(
                f"{where}: {s.v[0] / c.factor - c.offset / c.factor:g} throughout, no "
                f"data: channel {c.name!r} not used"
            )
            continue
        out[c.name] = s
    _drop_no_fix(out, messages)
    _drop_held_fixes(out, messages)
    messages += timing_messages(t, f"{file}: {spec.time.column!r}")
    return out, messages


def _drop_no_fix(out: dict[str, Series], messages: list[str]) -> None:
    """A receiver without a fix writes a position of (0, 0) or near it (one
    altimeter's -0.0001, -0.0001): rows within 0.01 deg of (0, 0) where the
    flight's other fixes lie more than a degree from it are dropped from the GNSS
    channels, with a message."""
    if "gnss_lat" not in out or "gnss_lon" not in out:
        return
    lat, lon = out["gnss_lat"], out["gnss_lon"]
    if len(lat.t) != len(lon.t) or not np.array_equal(lat.t, lon.t):
        return
    null = (np.abs(lat.v) < 0.01) & (np.abs(lon.v) < 0.01)
    if not null.any() or null.all():
        return
    if np.hypot(np.median(lat.v[~null]), np.median(lon.v[~null])) < 1.0:
        return
    names = [
        n
        for n in ("gnss_lat", "gnss_lon", "gnss_alt")
        if n in out and np.array_equal(out[n].t, lat.t)
    ]
    k = int(np.argmax(null))
    first, value = int(lat.rows[k]), f"{lat.v[k]:g}, {lon.v[k]:g}"
    for n in names:
        out[n].keep(~null)
    messages.append(
        f"{lat.file}: {int(np.count_nonzero(null))} rows with the GNSS position "
        f"within 0.01 deg of (0, 0), far from the flight's other fixes (first at row "
        f"{first}: {value}): a receiver without a "
        "fix; dropped from the GNSS channels"
    )


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


def impossible_tail(
    s: Series, t_apogee: float, h_apogee: float, t_lift: float
) -> tuple[int | None, list[float]]:
    """After apogee a rocket cannot fall faster than from rest at apogee in vacuum:
    a drop of more than `sqrt(2 g (H - h)) dt + g dt^2 / 2` plus five times the
    altitude noise between a good sample and the next is impossible. Returns the
    index from which every sample is impossible (a corrupt end of file, to drop),
    or `None`, and the start times of impossible excursions the record returns from
    (ejection-charge pressure pulses: deployment marks). Last readings far above
    apogee (more than an ejection pulse reads) are impossible too."""
    t, h = s.t, s.v
    after = np.flatnonzero(t > t_apogee)
    if after.size < 2:
        return None, []
    margin = 5.0 * robust_sigma(h) + quantum(h)
    top = max(h_apogee, float(h[after].max())) + margin

    def allowed(good, i):
        dt = t[i] - t[good]
        # a reading above the apogee (a pressure pulse) may fall back to it at once
        return (
            np.maximum(h[good] - h_apogee - margin, 0.0)
            + np.sqrt(2 * G0 * np.maximum(top - h[good], 0.0)) * dt
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
    # nor can it climb back far above its apogee: a last run of readings there (a
    # write gone wrong, 10.7 km after a 3.2 km apogee) ends the record too; the
    # allowance is an ejection pulse's (see `first_fall`: a tenth of the climb
    # under gravity alone)
    end = len(t) if bad_from is None else bad_from
    w = 0.1 * max(t_apogee - t_lift, 1.0)
    high = h_apogee + margin + 0.5 * G0 * w**2
    while end > after[0] and h[end - 1] > high:
        end -= 1
    if end < len(t) and end != bad_from:
        bad_from = end
    return bad_from, pulses
