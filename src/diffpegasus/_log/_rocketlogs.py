"""Rocket flight logs as flight computers write them, in one time-aligned form.

[`read_rocket_log`][] reads the files of one flight (AltOS CSV from TeleMega and
TeleMetrum, CATS exports, altimeter CSVs of any layout through a column map),
cleans what flight computers leave behind (duplicate rows, dropouts, rate changes,
a late start, corrupt trailing rows), converts every channel to SI under
plausibility checks, puts every stream on one clock (seconds since liftoff) and
finds the flight's events (liftoff, burnout, apogee, deployments) from the data.

The result is a [`RocketLog`][]: named [`Channel`][]s, each with its own time base
(streams differ in rate: a 400 Hz accelerometer beside a 20 Hz barometer), the
[`Event`][]s with how each was found, the files read and one message per thing
cleaned or inferred.

**Channel names and units** (a channel is present only where a log has it):

| name | unit | meaning |
|---|---|---|
| `pressure` | Pa | static pressure at the barometer |
| `altitude` | m | barometric altitude above the pad (the log's own pre-liftoff samples are its zero where it has them) |
| `accel_axial` | m/s^2 | specific force along the body axis, nose positive, **gravity included**: what an ideal accelerometer reads, about +g on the pad, 0 in free fall, -drag/mass in the coast. Logs that remove 1 g (AltOS, CATS filtered) get g0 = 9.80665 m/s^2 added back, with a message. |
| `accel_x`, `accel_y`, `accel_z` | m/s^2 | 3-axis specific force in the sensor's axes, gravity included |
| `gyro_x`, `gyro_y`, `gyro_z` | rad/s | 3-axis rates in the sensor's axes |
| `velocity` | m/s | vertical speed as the log gives it (a flight computer's Kalman filter or a derivative of altitude: `filtered` says which) |
| `gnss_lat`, `gnss_lon` | deg | GNSS position (degrees, as receivers give them) |
| `gnss_alt` | m | GNSS altitude above mean sea level, as the receiver gives it |
| `temperature` | K | sensor temperature |

Any other name a column map gives is kept as it is mapped (SI by its unit).
"""

import dataclasses
import os
import pathlib
import tomllib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .._errors import LogError
from ._rocket_clean import (
    check_accel_axial,
    check_altitude_unit,
    check_imu,
    check_pressure,
    clean_stream,
    impossible_tail,
    Series,
)
from ._rocket_events import (
    apogee,
    burnout_from_accel,
    burnout_from_altitude,
    descent_changes,
    isa_height,
    liftoff_from_accel,
    liftoff_from_altitude,
    quantum,
    robust_sigma,
    shocks,
)
from ._rocket_maps import detect_streams, load_map, StreamSpec, streams_from_map
from ._rocket_read import Header, read_columns


G0 = 9.80665

CHANNEL_UNITS = {
    "pressure": "Pa",
    "altitude": "m",
    "accel_axial": "m/s^2",
    "accel_x": "m/s^2",
    "accel_y": "m/s^2",
    "accel_z": "m/s^2",
    "gyro_x": "rad/s",
    "gyro_y": "rad/s",
    "gyro_z": "rad/s",
    "velocity": "m/s",
    "gnss_lat": "deg",
    "gnss_lon": "deg",
    "gnss_alt": "m",
    "temperature": "K",
}
EVENT_NAMES = ("liftoff", "burnout", "apogee", "drogue", "main", "landing")


@dataclasses.dataclass(frozen=True)
class Channel:
    """One measured quantity on its own time base.

    **Fields:**

    - `t`: sample times, s since liftoff, strictly increasing, shape `(n,)`.
    - `values`: SI values, shape `(n,)` (units in the module's table).
    - `source`: where it came from, e.g. `"flight.csv: column 'alt(ft)' (ft)"`.
    - `filtered`: `True` when the flight computer smoothed or estimated it (a Kalman
      speed, a filtered altitude), `False` for a raw sensor reading.
    """

    t: np.ndarray
    values: np.ndarray
    source: str
    filtered: bool = False

    def __len__(self) -> int:
        return len(self.t)

    @property
    def rate(self) -> float:
        """Median sample rate, Hz."""
        return float(1.0 / np.median(np.diff(self.t))) if len(self.t) > 1 else 0.0


@dataclasses.dataclass(frozen=True)
class Event:
    """A flight event found in the data.

    **Fields:**

    - `t`: time, s since liftoff (liftoff itself is at 0).
    - `how`: one sentence saying from which channel and by which rule it was found.
    - `value`: the quantity that marks it, where one does (apogee altitude in m,
      burnout speed in m/s, ...), else `nan`.
    """

    t: float
    how: str
    value: float = float("nan")


@dataclasses.dataclass(frozen=True)
class RocketLog:
    """One rocket flight's logs on one clock, in SI.

    **Fields:**

    - `channels`: name to [`Channel`][] (names and units in the module's table).
    - `events`: name to [`Event`][], for those of `liftoff`, `burnout`, `apogee`,
      `drogue`, `main`, `landing` the data show; `liftoff` is always present, at 0.
    - `files`: the files read, in the order read.
    - `messages`: one line per thing cleaned or inferred (duplicate rows dropped, a
      rate change, a late start, trailing rows dropped, a unit taken from the header,
      gravity added back, ...), each naming the file and column.
    - `time_offsets`: per file, the file's own time at liftoff, s (add it to a
      channel's `t` to get the time in the file).
    - `pad`: what the log says about the pad before liftoff, where it has samples
      there: `pressure` (Pa), `gnss_lat`, `gnss_lon` (deg), `gnss_alt` (m),
      `altitude_offset` (m subtracted from the file's altitude).
    """

    channels: dict[str, Channel]
    events: dict[str, Event]
    files: tuple[pathlib.Path, ...]
    messages: tuple[str, ...] = ()
    time_offsets: dict[str, float] = dataclasses.field(default_factory=dict)
    pad: dict[str, float] = dataclasses.field(default_factory=dict)

    def __getitem__(self, name: str) -> Channel:
        return self.channels[name]

    def __contains__(self, name: str) -> bool:
        return name in self.channels


def read_rocket_log(
    source: str | os.PathLike | Sequence[str | os.PathLike],
    column_map: Mapping[str, Any] | str | os.PathLike | None = None,
) -> RocketLog:
    """Read the logs of one rocket flight.

    **Arguments:**

    - `source`: a `rocket.toml` (its `[log.*]` tables' `file` entries name the logs,
      relative to it), or one log file, or a list of the log files of one flight.
    - `column_map`: which column holds which channel, in the syntax of every column
      map (`{"altitude": {"column": "alt(ft)", "unit": "ft"}}`), as a dict or a
      `.json` / `.toml` file. For several files or several streams in one file it is
      `{"streams": [{"file": "logs/a.csv", "time": "ts", "altitude": ...}, ...]}`.
      An accelerometer's entry may say `"gravity": "included"` or `"removed"`, any
      entry `"filtered": true`. Default: the map next to the `rocket.toml`
      (`columns.json`), else a shipped one for the flight, else the layout the
      files' headers show (AltOS, CATS, or column names with units in brackets).

    **Returns:**

    A [`RocketLog`][].

    **Raises:**

    [`LogError`][] with one line naming file, column, row and value for anything
    that cannot be used (a non-numeric cell mid-file, time running backwards, a
    unit that the data contradict, no column for a channel).
    """
    files, root, messages = _sources(source)
    streams = _streams(files, root, column_map, messages)
    series_by_stream: list[dict[str, Series]] = []
    for file in dict.fromkeys(s.file for s in streams):
        header = Header(file)
        mine = [s for s in streams if s.file == file]
        wanted = sorted(
            {
                header.index(c.column)
                for s in mine
                for c in (s.time, *s.channels)
                if not c.axis_auto
            }
        )
        data, notes = read_columns(header, wanted)
        messages += notes
        cols = {header.names[j]: k for k, j in enumerate(wanted)}
        for s in mine:
            # map entries may name a column by number or in another case
            named = {
                c.column: cols[header.names[header.index(c.column)]]
                for c in (s.time, *s.channels)
                if not c.axis_auto
            }
            chans, notes = clean_stream(s, data, named)
            messages += notes
            series_by_stream.append(chans)
    order = [
        s
        for f in dict.fromkeys(s.file for s in streams)
        for s in streams
        if s.file == f
    ]
    clocks: dict[str, list[tuple[StreamSpec, dict[str, Series]]]] = {}
    for spec, chans in zip(order, series_by_stream, strict=True):
        clocks.setdefault(spec.clock, []).append((spec, chans))
    channels: dict[str, Channel] = {}
    events: dict[str, Event] = {}
    offsets: dict[str, float] = {}
    pad_info: dict[str, float] = {}
    primary = True
    for members in clocks.values():
        flat: dict[str, Series] = {}
        for spec, chans in members:
            for name, s in chans.items():
                prior = flat.get(name)
                if prior is None or (prior.spec.filtered and not s.spec.filtered):
                    if prior is not None:
                        messages.append(
                            f"{name}: {s.where} (a sensor) kept, not {prior.where} "
                            "(a flight computer's estimate)"
                        )
                    flat[name] = s
        auto = any(c.axis_auto for spec, _ in members for c in spec.channels)
        if auto and "accel_axial" in flat and flat["accel_axial"].spec.filtered:
            messages.append(
                f"accel_axial: the raw 3-axis accelerometer is used, not "
                f"{flat['accel_axial'].where} (a flight computer's estimate)"
            )
            del flat["accel_axial"]
        found = _one_clock(flat, auto, messages)
        if found is None:
            continue
        t_lift, group_events, group_pad = found
        label = members[0][0].label
        for spec, _ in members:
            offsets[str(spec.file)] = t_lift
        for name, s in flat.items():
            key = name if (primary or name not in channels) else f"{name}.{label}"
            channels[key] = Channel(
                s.t - t_lift,
                s.v,
                f"{s.file.name}: column {s.spec.column!r}"
                + (f" ({s.spec.unit})" if s.spec.unit else ""),
                s.spec.filtered,
            )
        if primary:
            events, pad_info = group_events, group_pad
        else:
            for name in ("apogee", "burnout"):
                if name in events and name in group_events:
                    messages.append(
                        f"{label}: {name} at {group_events[name].t:.2f} s after its "
                        f"own liftoff (the first clock: {events[name].t:.2f} s)"
                    )
        primary = False
    if not channels:
        raise LogError(f"{files[0]}: no channel could be read")
    return RocketLog(
        channels,
        events,
        tuple(files),
        tuple(messages),
        offsets,
        pad_info,
    )


def _sources(source) -> tuple[list[pathlib.Path], pathlib.Path | None, list[str]]:
    """The log files of a flight: those a `rocket.toml` names, or those given."""
    if isinstance(source, str | os.PathLike):
        source = [source]
    paths = [pathlib.Path(p) for p in source]
    if len(paths) == 1 and paths[0].suffix.lower() == ".toml":
        toml = paths[0]
        try:
            facts = tomllib.loads(toml.read_text(encoding="utf-8"))
        except OSError as e:
            raise LogError(f"{toml}: cannot read ({e.strerror})") from None
        except tomllib.TOMLDecodeError as e:
            raise LogError(f"{toml}: not valid TOML ({e})") from None
        log = facts.get("log", {})
        names = [
            v["file"]
            for v in log.values()
            if isinstance(v, dict) and isinstance(v.get("file"), str)
        ]
        if not names:
            raise LogError(
                f"{toml}: [log] names no file; give each log as a table with "
                '`file = "logs/name.csv"` under [log]'
            )
        return [toml.parent / n for n in names], toml.parent, []
    for p in paths:
        if not p.is_file():
            raise LogError(f"{p}: no such file")
    return paths, None, []


def shipped_map(folder: str) -> pathlib.Path | None:
    """The column map shipped for a known flight's folder name, if any."""
    path = pathlib.Path(__file__).parents[1] / "data" / "rocket_logs" / f"{folder}.json"
    return path if path.is_file() else None


def _streams(files, root, column_map, messages) -> list[StreamSpec]:
    if column_map is None and root is not None:
        beside = root / "columns.json"
        column_map = beside if beside.is_file() else shipped_map(root.name)
    if column_map is not None:
        data, map_folder = load_map(column_map)
        where = str(column_map) if not isinstance(column_map, dict) else "column map"
        # a map's file names are relative to the rocket.toml, else to the map
        return streams_from_map(data, where, root or map_folder, files)
    out = []
    for f in files:
        found, layout = detect_streams(f)
        messages.append(f"{f.name}: read as {layout} (no column map given)")
        out += found
    return out


def _pad_of(t_lift: float):
    def pad(s: Series) -> np.ndarray:
        idx = np.flatnonzero(s.t < t_lift)
        return idx[: int(0.9 * len(idx))]

    return pad


def _one_clock(flat: dict[str, Series], auto: bool, messages: list[str]):
    """Liftoff, units, events of the channels on one clock (file time)."""
    alt = flat.get("altitude")
    press = flat.get("pressure")
    if alt is None and press is None:
        if "accel_axial" not in flat:
            return None
    # a height to find liftoff and apogee with: the altitude, else ISA from pressure
    if press is not None:
        check_pressure(press, np.arange(min(5, len(press.t))), messages)
    if alt is not None:
        th, hh = alt.t, alt.v
    elif press is not None:
        th, hh = press.t, isa_height(press.v, float(np.median(press.v[:5])))
    else:
        th = hh = None
    t_lift, late, how = None, False, ""
    if th is not None:
        top = (
            float(np.max(np.convolve(hh, np.ones(3) / 3, "same")[1:-1]))
            if len(hh) > 3
            else float(hh.max())
        )
        t_lift, late, how = liftoff_from_altitude(th, hh, top)
    if auto and "accel_axial" not in flat and t_lift is not None:
        _auto_axis(flat, t_lift, messages)
    acc = flat.get("accel_axial")
    if acc is not None:
        guess = t_lift if t_lift is not None else float(acc.t[np.argmax(acc.v)])
        refined = liftoff_from_accel(acc.t, acc.v, guess)
        if refined is not None and (t_lift is None or abs(refined - t_lift) < 1.0):
            if t_lift is not None and late:
                late = False
            t_lift = refined
            how = (
                "the axial accelerometer leaves its pad reading by more than five "
                "times its pad noise, on the rise to the boost"
            )
    if t_lift is None:
        return None
    pad_of = _pad_of(t_lift)
    if press is not None:
        check_pressure(press, pad_of(press), messages)
    check_imu(flat, pad_of, messages)
    acc = flat.get("accel_axial")
    if acc is not None:
        check_accel_axial(acc, pad_of(acc), messages)
        if acc.spec.filtered:
            zero = np.flatnonzero(acc.v != acc.v[-1])
            if (
                acc.v[-1] == (G0 if acc.spec.gravity == "removed" else 0.0)
                and zero.size
                and zero[-1] < len(acc.v) - 10
            ):
                cut = int(zero[-1]) + 1
                messages.append(
                    f"{acc.where}: held at exactly {acc.v[-1] - G0 * (acc.spec.gravity == 'removed'):g} "
                    f"from {acc.t[cut] - t_lift:.2f} s on (the flight computer stops "
                    "filtering it); those samples dropped"
                )
                acc.keep(np.arange(len(acc.t)) < cut)
    pad = {}
    if alt is not None:
        p = pad_of(alt)
        if p.size >= 3:
            offset = float(np.median(alt.v[p]))
            alt.v = alt.v - offset
            pad["altitude_offset"] = offset
            if abs(offset) > 5 * robust_sigma(alt.v) + quantum(alt.v):
                messages.append(
                    f"{alt.where}: reads {offset:.3g} m on the pad; altitude is "
                    "taken from the pad's own reading"
                )
        th, hh = alt.t, alt.v
    if late:
        first = th[0] if th is not None else t_lift
        messages.append(
            f"the log starts {first - t_lift:.2f} s after liftoff"
            + (f" at {hh[0]:.3g} m" if hh is not None else "")
            + "; liftoff extrapolated"
        )
    for name in ("pressure", "gnss_lat", "gnss_lon", "gnss_alt"):
        if name in flat:
            p = pad_of(flat[name])
            if p.size:
                pad[name] = float(np.median(flat[name].v[p]))
    events = {"liftoff": Event(0.0, how)}
    if th is None:
        return t_lift, events, pad
    t_apo, h_apo = apogee(th, hh, t_lift)
    if alt is not None:
        bad_from, pulses = impossible_tail(alt, t_apo, h_apo)
        if bad_from is not None:
            n = len(alt.t) - bad_from
            messages.append(
                f"{alt.where}: dropped the last {n} samples from row "
                f"{alt.rows[bad_from]} ({alt.v[bad_from]:.4g} m at "
                f"{alt.t[bad_from] - t_lift:.2f} s): a fall faster than free fall "
                "from apogee, a corrupt end of the file"
            )
            bad_rows = set(alt.rows[bad_from:].tolist())
            for s in flat.values():
                if s.file == alt.file:
                    s.keep(~np.isin(s.rows, list(bad_rows)))
            th, hh = alt.t, alt.v
    else:
        pulses = []
    events["apogee"] = Event(
        t_apo - t_lift,
        "vertex of a parabola of curvature -g/2 through the "
        f"{'altitude' if alt is not None else 'pressure (standard-atmosphere height)'}"
        f" near its highest sample ({float(np.max(hh)):.5g} m)",
        h_apo,
    )
    t_bo = None
    if acc is not None:
        t_bo = burnout_from_accel(acc.t, acc.v, t_lift)
        if t_bo is not None:
            events["burnout"] = Event(
                t_bo - t_lift,
                "the axial specific force turns negative after the boost (thrust "
                "below drag) for five samples",
            )
    if t_bo is None:
        t_bo, v_bo = burnout_from_altitude(th, hh, t_lift, t_apo)
        if np.isfinite(t_bo):
            events["burnout"] = Event(
                t_bo - t_lift,
                "greatest climb rate of a smoothing spline through the ascent "
                "altitude (no accelerometer over the boost)",
                v_bo,
            )
    if alt is not None and t_bo is not None and np.isfinite(t_bo):
        h_bo = float(np.interp(t_bo, th, hh))
        factor = check_altitude_unit(alt, t_bo, h_bo, t_apo, h_apo, messages)
        if factor != 1.0:
            hh = alt.v
            events["apogee"] = dataclasses.replace(
                events["apogee"], value=h_apo * factor
            )
            h_apo *= factor
    _deployments(events, flat, th, hh, t_lift, t_apo, h_apo, pulses, messages)
    return t_lift, events, pad


def _auto_axis(flat, t_lift, messages):
    acc = [flat.get(n) for n in ("accel_x", "accel_y", "accel_z")]
    if any(a is None for a in acc):
        return
    best, sign, name = 0.0, 1.0, ""
    for n, a in zip(("accel_x", "accel_y", "accel_z"), acc):
        sel = (a.t >= t_lift) & (a.t <= t_lift + 1.0)
        if sel.any():
            m = float(np.median(a.v[sel]))
            if abs(m) > best:
                best, sign, name = abs(m), np.sign(m), n
    if not name:
        return
    a = flat[name]
    spec = dataclasses.replace(
        a.spec, name="accel_axial", factor=a.spec.factor * sign, gravity="included"
    )
    flat["accel_axial"] = Series(a.t, a.v * sign, a.rows, spec, a.file)
    messages.append(
        f"{a.where}: accel_axial is {'-' if sign < 0 else '+'}{name}, the axis that "
        "reads most along the boost"
    )


def _deployments(events, flat, th, hh, t_lift, t_apo, h_apo, pulses, messages):
    t_bo = events["burnout"].t + t_lift if "burnout" in events else t_lift
    after = 0.5 * (t_bo + t_apo)
    marks: list[tuple[float, str]] = [
        (p, "a pressure pulse the altitude returns from (an ejection charge)")
        for p in pulses
    ]
    for name in ("accel_axial", "accel_x", "accel_y", "accel_z"):
        if name in flat and not flat[name].spec.filtered:
            s = flat[name]
            for t in shocks(s.t, s.v, after):
                marks.append((t, f"an opening shock on {name}"))
    marks.sort()
    changes = descent_changes(th, hh, t_apo, h_apo)
    landing = None
    mains = []
    for t, before, after_rate in changes:
        h_here = float(np.interp(t, th, hh))
        if h_here < 0.05 * h_apo and after_rate < 0.3 * before:
            landing = (t, before, after_rate) if landing is None else landing
        else:
            mains.append((t, before, after_rate))
    if mains:
        t, before, after_rate = mains[0]
        near = [m for m in marks if t - 3.0 <= m[0] <= t + 1.0]
        how = (
            f"the descent rate falls from {before:.3g} to {after_rate:.3g} m/s "
            "(two straight lines through the descent altitude)"
        )
        if near:
            t, what = near[0]
            how = f"{what}, where {how}"
        events["main"] = Event(t - t_lift, how, float(np.interp(t, th, hh)))
    t_main = events["main"].t + t_lift if "main" in events else np.inf
    early = [m for m in marks if m[0] < t_main - 1.0]
    if early:
        t, what = early[0]
        events["drogue"] = Event(t - t_lift, what, float(np.interp(t, th, hh)))
    if landing is not None:
        t, before, after_rate = landing
        events["landing"] = Event(
            t - t_lift,
            f"the descent stops: {before:.3g} m/s, then {after_rate:.3g} m/s (two "
            "straight lines through the descent altitude)",
            float(np.interp(t, th, hh)),
        )
    elif th[-1] > t_apo:
        messages.append(
            f"the log ends {th[-1] - t_lift:.1f} s after liftoff at {hh[-1]:.4g} m, "
            "still descending: no landing"
        )
