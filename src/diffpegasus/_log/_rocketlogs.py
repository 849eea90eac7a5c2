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
import json
import os
import pathlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .._errors import LogError
from .._vehicle._rocket._config import read_toml
from ._rocket_clean import clean_stream, Series
from ._rocket_events import Event as Event
from ._rocket_flight import one_clock
from ._rocket_maps import detect_streams, load_map, streams_from_map, StreamSpec
from ._rocket_read import read_columns


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

    - `source`: a `rocket.toml` (its `[log]` table's `file` or `files`, or the
      `file` of each `[log.*]` table, name the logs, relative to it), or one log
      file, or a list of the log files of one flight. Its `[log.stated_events]`
      table may give events the log's writer knows, in the file's seconds
      (`liftoff_s`, `apogee_s`, ... for the events below): a simulator's export
      whose time zero is its start (`liftoff_s = 0.0`: the file's clock is kept,
      liftoff not searched for) and whose last row is its apogee. A stated event
      replaces the one found, with a message giving the found time.
    - `column_map`: which column holds which channel, in the syntax of every column
      map (`{"altitude": {"column": "alt(ft)", "unit": "ft"}}`), as a dict or a
      `.json` / `.toml` file. For several files or several streams in one file it is
      `{"streams": [{"file": "logs/a.csv", "time": "ts", "altitude": ...}, ...]}`.
      An accelerometer's entry may say `"gravity": "included"` or `"removed"`, any
      entry `"filtered": true`; a stream may say where its file's header is
      (`"header_row"`, from 1), its separator (`"delimiter"`: `","`, `";"`,
      `"tab"`, `"whitespace"`) and decimal mark (`"decimal"`: `"."`, `","`),
      where they are not found from the file (a preamble, a units row, `;` with
      decimal commas, spaces are). Default: the `rocket.toml`'s `[log] column_map`
      (a table, or the path of a map file), else the map next to the `rocket.toml`
      (`columns.json`), else a shipped one for the flight's folder, else the layout
      the files' headers show (AltOS, CATS, or column names with units in brackets
      or as a suffix: `alt(ft)`, `altitude_m`). A unit the map or header gives is
      checked against the flight; where none is given, the one that fits is taken,
      with a message.

    **Returns:**

    A [`RocketLog`][].

    **Raises:**

    [`LogError`][] with one line naming file, column, row and value for anything
    that cannot be used (a non-numeric cell mid-file, time running backwards, a
    unit that the data contradict, no column for a channel).
    """
    files, root, log_table = _sources(source)
    stated = _stated_events(log_table, root)
    messages: list[str] = []
    streams = _streams(files, root, column_map, log_table, messages)
    series_by_stream: list[dict[str, Series]] = []
    for file in dict.fromkeys(s.file for s in streams):
        mine = [s for s in streams if s.file == file]
        header = mine[0].header()
        wanted = sorted(
            {
                header.index(c.column)
                for s in mine
                for c in (s.time, *s.channels)
                if not c.axis_auto and c.step is None
            }
        )
        clocks = frozenset(
            header.index(s.time.column) for s in mine if s.time.step is None
        )
        data, notes = read_columns(header, wanted, clocks)
        messages += notes
        cols = {header.names[j]: k for k, j in enumerate(wanted)}
        for s in mine:
            # map entries may name a column by number or in another case
            named = {
                c.column: cols[header.names[header.index(c.column)]]
                for c in (s.time, *s.channels)
                if not c.axis_auto and c.step is None
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
        for _, chans in members:
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
        if primary and stated and flat:
            _stated_within(stated, flat, root)
        found = one_clock(flat, auto, messages, stated if primary else {})
        if found is None:
            files_here = ", ".join(sorted({spec.file.name for spec, _ in members}))
            messages.append(
                f"{files_here}: nothing on this clock shows liftoff (no altitude, "
                "pressure or accelerometer): its channels are not used; give its "
                'streams the "clock" of the computer that wrote them'
            )
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
        why = [m for m in messages if "not used" in m]
        raise LogError(
            f"{files[0]}: no channel could be read" + (f" ({why[0]})" if why else "")
        )
    return RocketLog(
        channels,
        events,
        tuple(files),
        tuple(messages),
        offsets,
        pad_info,
    )


def _sources(source) -> tuple[list[pathlib.Path], pathlib.Path | None, dict]:
    """The log files of a flight: those a `rocket.toml` names, or those given; the
    folder they are relative to and the `rocket.toml`'s `[log]` table."""
    if isinstance(source, str | os.PathLike):
        source = [source]
    paths = [pathlib.Path(p) for p in source]
    if len(paths) == 1 and paths[0].suffix.lower() == ".toml":
        toml = paths[0]
        facts = read_toml(toml)
        log = facts.get("log", {})
        names = [log["file"]] if isinstance(log.get("file"), str) else []
        names += [n for n in log.get("files", []) if isinstance(n, str)]
        names += [
            v["file"]
            for v in log.values()
            if isinstance(v, dict) and isinstance(v.get("file"), str)
        ]
        if not names:
            raise LogError(
                f"{toml}: [log] names no file; give `file = 'logs/name.csv'` (or "
                "`files = [...]`) under [log], or one table per file with its `file`"
            )
        return [toml.parent / n for n in names], toml.parent, log
    for p in paths:
        if not p.is_file():
            raise LogError(f"{p}: no such file")
    return paths, None, {}


def _stated_events(log_table: dict, root: pathlib.Path | None) -> dict[str, float]:
    """name -> the file's time (s) of the events a `rocket.toml`'s
    `[log.stated_events]` states (`liftoff_s`, `apogee_s`, ...: what the log's
    writer knows, a simulator's time zero and its end at apogee)."""
    table = log_table.get("stated_events", {})
    where = f"{root / 'rocket.toml' if root is not None else 'rocket.toml'}"
    if not isinstance(table, dict):
        raise LogError(f"{where}: [log.stated_events] must be a table of times in s")
    out = {}
    for key, value in table.items():
        name = key.removesuffix("_s")
        if not key.endswith("_s") or name not in EVENT_NAMES:
            raise LogError(
                f"{where}: [log.stated_events] {key}: not an event time; give "
                + ", ".join(f"{n}_s" for n in EVENT_NAMES)
            )
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise LogError(
                f"{where}: [log.stated_events] {key} = {value!r}: not a time in s"
            )
        if not np.isfinite(value):
            raise LogError(
                f"{where}: [log.stated_events] {key} = {value!r}: not a finite time"
            )
        out[name] = float(value)
    return out


def _stated_within(stated: dict[str, float], flat: dict, root) -> None:
    """Refuse a stated event outside the log's own times (s, the file's clock): it
    would move every event, or cut the ascent past the descent."""
    first = min(float(c.t[0]) for c in flat.values())
    last = max(float(c.t[-1]) for c in flat.values())
    for name, t in stated.items():
        if not first <= t <= last:
            where = root / "rocket.toml" if root is not None else "rocket.toml"
            raise LogError(
                f"{where}: [log.stated_events] {name}_s = {t:g} is outside the log's "
                f"times ({first:g} to {last:g} s in the file)"
            )


def shipped_map(folder: str, files=None, root=None) -> pathlib.Path | None:
    """The column map shipped for a known flight's folder name, if any; with
    `files` (the logs the `rocket.toml` in `root` names), only when the map reads
    exactly those files: a folder of another flight under a shipped name, or a
    `rocket.toml` pointing at another log, is read by its own headers instead of
    the shipped flight's files."""
    path = pathlib.Path(__file__).parents[1] / "data" / "rocket_logs" / f"{folder}.json"
    if not path.is_file():
        return None
    if files is None:
        return path
    streams = json.loads(path.read_text()).get("streams", [])
    named = {(root / s["file"]).resolve() for s in streams if "file" in s}
    return path if named == {pathlib.Path(f).resolve() for f in files} else None


def _streams(files, root, column_map, log_table, messages) -> list[StreamSpec]:
    """The streams to read: the map given; else, beside a `rocket.toml`, its
    `[log] column_map`, its per-file `column_map` tables (the other files by their
    headers), a `columns.json` beside it, the map shipped for its folder; else the
    layouts the headers show."""
    if column_map is None and root is not None:
        named = log_table.get("column_map")
        per_file = {
            v["file"]: v["column_map"]
            for v in log_table.values()
            if isinstance(v, dict) and "file" in v and "column_map" in v
        }
        if isinstance(named, str):
            column_map = root / named
        elif isinstance(named, dict):
            column_map = named
        elif per_file:
            out = []
            for f in files:
                rel = str(f.relative_to(root)) if f.is_relative_to(root) else str(f)
                if rel in per_file:
                    where = f"{root / 'rocket.toml'}: [log] column_map of {rel}"
                    data, folder = load_map(
                        per_file[rel]
                        if isinstance(per_file[rel], dict)
                        else root / per_file[rel]
                    )
                    out += streams_from_map(data, where, folder or root, [f])
                else:
                    found, layout = detect_streams(f)
                    messages.append(f"{f.name}: read as {layout} (no column map given)")
                    out += found
            return out
        else:
            beside = root / "columns.json"
            column_map = (
                beside if beside.is_file() else shipped_map(root.name, files, root)
            )
    if column_map is not None:
        data, map_folder = load_map(column_map)
        if not isinstance(column_map, dict):
            where = str(column_map)
        elif root is not None and column_map is log_table.get("column_map"):
            where = f"{root / 'rocket.toml'}: [log] column_map"
        else:
            where = "column map"
        # a map's file names are relative to the rocket.toml, else to the map
        return streams_from_map(data, where, root or map_folder, files)
    out = []
    for f in files:
        found, layout = detect_streams(f)
        messages.append(f"{f.name}: read as {layout} (no column map given)")
        out += found
    return out
