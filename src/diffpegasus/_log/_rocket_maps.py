"""Which column of which file is which rocket channel: column maps for flight
computers' logs, and the layouts recognised from a header when no map is given.

A flight's map is the column-map syntax of every log (`{"altitude": {"column":
"alt(ft)", "unit": "ft"}}`, see [`load_columns`][]) once per stream:

    {"streams": [
        {"file": "logs/flight.csv", "time": "Time (s)",
         "altitude": {"column": "Altitude (Ft-AGL)", "unit": "ft"}},
        {"file": "logs/flight.csv", "time": "Time-Axial Accel (Gs)",
         "accel_axial": {"column": "Axial Accel (Gs)", "unit": "g",
                         "gravity": "included"}}]}

A stream is one time column and the channels sampled at its times; several streams
may share a file (two sensors side by side) and several files one clock (a flight
computer's export split by sensor). Per stream: `file` (relative to the map, or to
the `rocket.toml`), `time`, the channels, and optionally `clock` (streams with the
same clock share time zero; default: one clock for the flight, except that each
AltOS file is its own computer) and `label` (appended to channel names that a
stream on another clock also has, as `altitude.telemega`). Per channel, beside
`column`, `unit` and `scale`: `gravity` (`"included"`: the accelerometer reads +1 g
on the pad; `"removed"`: the log subtracted 1 g) and `filtered` (true for a flight
computer's estimate rather than a sensor reading). An entry `"accel_axial": {"axis":
"auto"}` in a stream with `accel_x`, `accel_y`, `accel_z` takes the axis and sign
that read most along the boost.
"""

import dataclasses
import json
import pathlib
import re
import tomllib
from typing import Any

from .._errors import LogError
from ._columns import Column, UNITS
from ._rocket_read import Header


_EXTRA_KEYS = ("gravity", "filtered", "axis")
_READ_KEYS = ("header_row", "delimiter", "decimal")
_STREAM_KEYS = ("file", "time", "clock", "label", *_READ_KEYS)
# temperatures have an offset; the generic map's units are factors only:
# unit -> (factor, offset) to K
_TEMPERATURES = {
    "degc": (1.0, 273.15),
    "c": (1.0, 273.15),
    "k": (1.0, 0.0),
    "degf": (5.0 / 9.0, 273.15 - 32.0 * 5.0 / 9.0),
    "f": (5.0 / 9.0, 273.15 - 32.0 * 5.0 / 9.0),
}


@dataclasses.dataclass(frozen=True)
class ChannelSpec:
    """One channel of a stream: its column, its unit as given (and where from), its
    conversion to SI (`value * factor + offset`)."""

    name: str
    column: str
    factor: float
    offset: float = 0.0
    unit: str = ""
    unit_from: str = ""  # "map", "header", "format" or "" (none: SI assumed)
    gravity: str | None = None
    filtered: bool = False
    axis_auto: bool = False
    step: float | None = None  # time only: samples `step` seconds apart from 0


@dataclasses.dataclass(frozen=True)
class StreamSpec:
    file: pathlib.Path
    time: ChannelSpec
    channels: tuple[ChannelSpec, ...]
    clock: str = "flight"
    label: str = ""
    read: tuple = ()  # (key, value) of the map's header_row, delimiter, decimal

    def header(self) -> Header:
        return Header(self.file, **dict(self.read))


_SUFFIXES = {
    "m_s2": "m/s^2",
    "m_s_2": "m/s^2",
    "mps2": "m/s^2",
    "m_s": "m/s",
    "mps": "m/s",
    "ft_s": "ft/s",
    "deg_s": "deg/s",
    "rad_s": "rad/s",
    "hpa": "hpa",
    "kpa": "kpa",
    "pa": "pa",
    "ft": "ft",
    "m": "m",
    "g": "g",
    "ms": "ms",
    "us": "us",
    "s": "s",
    "degc": "degc",
    "degf": "degf",
    "mbar": "mbar",
    "atm": "atm",
    "psi": "psi",
    "inhg": "inhg",
    "mg": "mg",
}
# how logs write units in brackets, as the column-map unit
_SPELLINGS = {
    "gs": "g",
    "g's": "g",
    "sec": "s",
    "secs": "s",
    "msec": "ms",
    "millis": "ms",
    "usec": "us",
    "micros": "us",
    "µs": "us",  # the micro sign
    "μs": "us",  # the Greek mu
    "feet": "ft",
    "meters": "m",
    "metres": "m",
    "fps": "ft/s",
    "ft/sec": "ft/s",
    "m/s2": "m/s^2",
    "m/s/s": "m/s^2",
    "ft/s2": "ft/s^2",
    "ft/s/s": "ft/s^2",
    "mb": "mbar",
    "millibar": "mbar",
    "in hg": "inhg",
    "inches hg": "inhg",
    "°c": "degc",
    "deg c": "degc",
    "°f": "degf",
    "deg f": "degf",
    "°/s": "deg/s",
    "dps": "deg/s",
    "kelvin": "k",
    "c": "degc",
    "f": "degf",
}


def _bracket_unit(name: str) -> str:
    """The unit written in a column name: 'alt(ft)' -> 'ft', 'Altitude (Ft-AGL)' ->
    'ft', 'velocity[m/s]' -> 'm/s', 'Axial Accel (Gs)' -> 'g', 'accel_m_s2' ->
    'm/s^2'; '' if none known."""
    m = re.search(r"[\(\[]([^\)\]]*)[\)\]]\s*$", name)
    if not m:
        # a suffix: altitude_m, accel_m_s2, time_s, pressure_hPa
        m = re.search(r"_(" + "|".join(_SUFFIXES) + r")$", name.strip().lower())
        return _SUFFIXES[m.group(1)] if m else ""
    return unit_name(m.group(1))


def unit_name(text: str) -> str:
    """A unit as a log writes it ('Ft-AGL', 'm/s²', '°F', 'mbar') as the column-map
    unit ('ft', 'm/s^2', 'degf', 'mbar'); '' if not one known."""
    text = text.strip().strip("()[]").strip().lower().replace("²", "2")
    text = re.sub(r"[-_ ]*(agl|asl|msl)$", "", text)
    text = _SPELLINGS.get(text, text)
    text = re.sub(r"^(m|ft)/s2$", r"\1/s^2", text)
    return text if text in UNITS or text in _TEMPERATURES else ""


def channel_spec(
    name: str, spec: Any, where: str, header: Header | None, unit_from: str = "map"
) -> ChannelSpec:
    """A map entry as a [`ChannelSpec`][]: the generic column-map entry plus
    `gravity`, `filtered`, `axis`; a unit not in the map is read from the header."""
    if isinstance(spec, str | int) and not isinstance(spec, bool):
        spec = {"column": spec}
    if not isinstance(spec, dict):
        raise LogError(
            f"{where}: channel {name!r} must map to a column name or a table with "
            f"'column', 'unit', 'scale', got {spec!r}"
        )
    extra = {k: spec[k] for k in _EXTRA_KEYS if k in spec}
    base = {k: v for k, v in spec.items() if k not in _EXTRA_KEYS}
    gravity = extra.get("gravity")
    if gravity not in (None, "included", "removed"):
        raise LogError(
            f'{where}: channel {name!r}: gravity must be "included" (reads +1 g on '
            f'the pad) or "removed" (reads 0 on the pad), got {gravity!r}'
        )
    filtered = extra.get("filtered", False)
    if not isinstance(filtered, bool):
        raise LogError(f"{where}: channel {name!r}: filtered must be true or false")
    if extra.get("axis") not in (None, "auto"):
        raise LogError(f'{where}: channel {name!r}: axis can only be "auto"')
    if extra.get("axis") == "auto":
        return ChannelSpec(name, "", 1.0, gravity="included", axis_auto=True)
    unit = base.get("unit", "")
    offset = 0.0
    if isinstance(unit, str) and unit.lower() in _TEMPERATURES:
        factor, offset = _TEMPERATURES[unit.lower()]
        base = {**base, "unit": "", "scale": factor * base.get("scale", 1.0)}
    column = Column(name, base, where)
    if header is not None:
        try:
            header.index(column.column)
        except KeyError:
            raise LogError(
                f"{header.path}: no column {column.column!r} for channel {name!r} "
                f"(columns: {', '.join(header.names)}); map it in the column map"
            ) from None
    source = unit_from if unit else ""
    if not unit and header is not None:
        j = header.index(column.column)
        found = _bracket_unit(header.names[j])
        if not found and j < len(header.units):
            found = unit_name(header.units[j])  # a row of units under the header
        if found:
            unit, source = found, "header"
            if found in _TEMPERATURES:
                factor, offset = _TEMPERATURES[found]
                column = Column(
                    name, {**base, "scale": factor * base.get("scale", 1.0)}, where
                )
            else:
                column = Column(name, {**base, "unit": found}, where)
    return ChannelSpec(
        name,
        column.column,
        column.factor,
        offset,
        unit,
        source,
        gravity,
        filtered,
    )


def load_map(source: Any) -> tuple[dict, pathlib.Path | None]:
    """A flight's column map from a dict or a `.json` / `.toml` file, and the folder
    its file names are relative to."""
    if isinstance(source, dict):
        return source, None
    if not isinstance(source, str | pathlib.PurePath):
        raise LogError(
            "column map: give a table of channels or the path of a .json / .toml "
            f"file, got {type(source).__name__}"
        )
    path = pathlib.Path(source)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as e:
        raise LogError(f"{path}: cannot read the column map ({e.strerror})") from None
    try:
        data = (
            tomllib.loads(text) if path.suffix.lower() == ".toml" else json.loads(text)
        )
    except (ValueError, tomllib.TOMLDecodeError) as e:
        raise LogError(f"{path}: not a valid column map ({e})") from None
    if not isinstance(data, dict):
        raise LogError(f"{path}: a column map is a table of channels")
    return data, path.parent


def streams_from_map(
    data: dict, where: str, root: pathlib.Path | None, files: list[pathlib.Path]
) -> list[StreamSpec]:
    """The streams a map describes. A map with no `streams` is one stream of the one
    file given."""
    if "streams" not in data:
        if len(files) != 1:
            raise LogError(
                f"{where}: a column map without 'streams' applies to one file, and "
                f"{len(files)} were given; list them as "
                '{"streams": [{"file": ..., "time": ..., ...}]}'
            )
        flat = _time_key({**data, "file": str(files[0])})
        if "time" not in flat:
            header = Header(files[0], **_read_options(flat, where))
            times = [n for n in header.names if _is_time(n)]
            if len(times) != 1:
                raise LogError(
                    f'{where}: give the time column as "time" (the header of '
                    f"{files[0].name} has {len(times) or 'no'} time-like columns: "
                    f"{', '.join(header.names)})"
                )
            flat["time"] = times[0]
        data = {"streams": [flat]}
    streams = data["streams"]
    if not isinstance(streams, list) or not streams:
        raise LogError(f"{where}: 'streams' must be a list of tables")
    out = []
    for k, s in enumerate(streams, start=1):
        here = f"{where}: stream {k}"
        s = _time_key(s) if isinstance(s, dict) else s
        if not isinstance(s, dict) or "file" not in s or "time" not in s:
            raise LogError(f"{here}: needs 'file' and 'time'")
        file = pathlib.Path(s["file"])
        # a map without streams names the file given, already found
        if not file.is_absolute() and root is not None and file not in files:
            file = root / file
        read = _read_options(s, here)
        header = Header(file, **read)
        time = _time_spec(s["time"], here, header)
        channels = tuple(
            channel_spec(n, v, here, header)
            for n, v in s.items()
            if n not in _STREAM_KEYS
        )
        out.append(
            StreamSpec(
                file,
                time,
                channels,
                str(s.get("clock", "flight")),
                str(s.get("label", file.stem)),
                tuple(sorted(read.items())),
            )
        )
    return out


def _read_options(stream: dict, where: str) -> dict:
    """A stream's `header_row`, `delimiter`, `decimal`, checked."""
    out = {k: stream[k] for k in _READ_KEYS if k in stream}
    row = out.get("header_row")
    if row is not None and (
        isinstance(row, bool) or not isinstance(row, int) or row < 1
    ):
        raise LogError(f"{where}: header_row must be a line number from 1, got {row!r}")
    if "decimal" in out and out["decimal"] not in (".", ","):
        raise LogError(f'{where}: decimal must be "." or ",", got {out["decimal"]!r}')
    if "delimiter" in out and out["delimiter"] not in (",", ";", "tab", "whitespace"):
        raise LogError(
            f'{where}: delimiter must be ",", ";", "tab" or "whitespace", got '
            f"{out['delimiter']!r}"
        )
    return out


def _time_key(stream: dict) -> dict:
    """`t`, the time channel's name in every other column map, as `time`."""
    if "t" in stream and "time" not in stream:
        stream = {k if k != "t" else "time": v for k, v in stream.items()}
    return stream


def _time_spec(spec: Any, where: str, header: Header) -> ChannelSpec:
    """The time column, or `{"step": seconds}` for a file with no time column
    (samples that far apart from 0, as in every column map)."""
    if isinstance(spec, dict) and "step" in spec:
        step = spec["step"]
        if (
            isinstance(step, bool)
            or not isinstance(step, int | float)
            or not step > 0
            or step == float("inf")
        ):
            raise LogError(
                f"{where}: time: step must be a positive number of seconds, got "
                f"{step!r}"
            )
        return ChannelSpec("time", "", 1.0, unit="s", unit_from="map", step=float(step))
    return channel_spec("time", spec, where, header)


# --- layouts recognised from the header ---------------------------------------------

_ALTOS = {
    "accel_axial": {"column": "acceleration", "unit": "m/s^2", "gravity": "removed"},
    "pressure": {"column": "pressure", "unit": "Pa"},
    "altitude": {"column": "height", "unit": "m"},
    "velocity": {"column": "speed", "unit": "m/s", "filtered": True},
    "temperature": {"column": "temperature", "unit": "degC"},
    "accel_x": {"column": "accel_x", "unit": "m/s^2", "gravity": "included"},
    "accel_y": {"column": "accel_y", "unit": "m/s^2", "gravity": "included"},
    "accel_z": {"column": "accel_z", "unit": "m/s^2", "gravity": "included"},
    "gyro_x": {"column": "gyro_roll", "unit": "deg/s"},
    "gyro_y": {"column": "gyro_pitch", "unit": "deg/s"},
    "gyro_z": {"column": "gyro_yaw", "unit": "deg/s"},
    "gnss_lat": {"column": "latitude", "unit": ""},
    "gnss_lon": {"column": "longitude", "unit": ""},
    "gnss_alt": {"column": "altitude (2)", "unit": "m"},
}
# CATS exports: one file per sensor, all on the flight computer's clock `ts`
_CATS = {
    "accel_x": {"column": "Ax", "unit": "m/s^2", "gravity": "included"},
    "accel_y": {"column": "Ay", "unit": "m/s^2", "gravity": "included"},
    "accel_z": {"column": "Az", "unit": "m/s^2", "gravity": "included"},
    "gyro_x": {"column": "Gx", "unit": "deg/s"},
    "gyro_y": {"column": "Gy", "unit": "deg/s"},
    "gyro_z": {"column": "Gz", "unit": "deg/s"},
    "pressure": {"column": "P", "unit": "Pa"},
    "temperature": {"column": "T", "unit": "degC"},
    "velocity": {"column": "velocity", "unit": "m/s", "filtered": True},
    "altitude": {"column": "filteredAltitudeAGL", "unit": "m", "filtered": True},
    "altitude_": {"column": "filtered_altitude_AGL", "unit": "m", "filtered": True},
    "accel_axial": {
        "column": "filteredAcceleration",
        "unit": "m/s^2",
        "gravity": "removed",
        "filtered": True,
    },
    "accel_axial_": {
        "column": "filtered_acceleration",
        "unit": "m/s^2",
        "gravity": "removed",
        "filtered": True,
    },
    "gnss_lat": {"column": "latitude", "unit": ""},
    "gnss_lon": {"column": "longitude", "unit": ""},
}
# a generic altimeter's column names: the first keyword a name holds decides
_KEYWORDS = (
    ("gnss_lat", ("latitude", "lat")),
    ("gnss_lon", ("longitude", "lon", "lng")),
    ("pressure", ("pressure", "press")),
    ("temperature", ("temperature", "temp")),
    ("accel_axial", ("accel", "acc", "az")),
    ("velocity", ("velocity", "vel", "speed", "vz")),
    ("altitude", ("altitude", "alt", "height", "h")),
    ("pressure", ("baro",)),  # a barometer's column that says nothing more
)
_TIME_NAMES = ("t", "ts", "time", "timestamp", "time_s", "seconds", "millis", "micros")
# an Arduino sketch's clock, named after the function that read it
_CLOCK_UNITS = {"millis": "ms", "micros": "us"}


def _bare(name: str) -> str:
    return re.sub(r"\s*[\(\[][^\)\]]*[\)\]]\s*$", "", name).strip().lower()


def _is_time(name: str) -> bool:
    bare = _bare(name)
    return (
        bare in _TIME_NAMES
        or bare.startswith("time")
        # 'Flight_Time_(s)': a time with a time unit (a clock 'Time' may precede it)
        or (
            "time" in re.split(r"[^a-z]+", bare)
            and _bracket_unit(name) in ("s", "ms", "us")
        )
    )


def detect_streams(file: pathlib.Path) -> tuple[list[StreamSpec], str]:
    """The streams of a file whose layout the header shows, and the layout's name."""
    header = Header(file)
    names = header.names
    where = f"{file} (layout from its header)"
    if names[:2] == ["version", "serial"] and "time" in names:
        spec = {n: v for n, v in _ALTOS.items() if v["column"] in names}
        chans = tuple(
            channel_spec(n, v, where, header, "format") for n, v in spec.items()
        )
        time = channel_spec(
            "time", {"column": "time", "unit": "s"}, where, header, "format"
        )
        return [
            StreamSpec(file, time, chans, clock=file.name, label=file.stem)
        ], "AltOS"
    cats_only = {"Ax", "P", "filteredAltitudeAGL", "filtered_altitude_AGL", "height"}
    if "ts" in names and cats_only & set(names):
        spec = {n.rstrip("_"): v for n, v in _CATS.items() if v["column"] in names}
        if {"accel_x", "accel_y", "accel_z"} <= set(spec):
            spec["accel_axial"] = {"axis": "auto"}
        if spec:
            chans = tuple(
                channel_spec(n, v, where, header, "format") for n, v in spec.items()
            )
            time = channel_spec(
                "time", {"column": "ts", "unit": "s"}, where, header, "format"
            )
            return [StreamSpec(file, time, chans, label=file.stem)], "CATS"
    times = [j for j, n in enumerate(names) if _is_time(n)]
    if not times:
        raise LogError(
            f"{file}: no time column among {', '.join(names)}; give a column map with "
            '"time"'
        )
    streams = []
    for k, j in enumerate(times):
        end = times[k + 1] if k + 1 < len(times) else len(names)
        # a time column's channels follow it; columns before the first time column
        # (a logger that writes `alt,t`) are the first stream's too
        cols = names[: times[0]] + names[j + 1 : end] if k == 0 else names[j + 1 : end]
        taken: dict[str, dict] = {}
        for col in cols:
            bare = _bare(col)
            words = re.split(r"[^a-z]+", bare)
            for channel, keys in _KEYWORDS:
                if any(w in keys for w in words) or any(
                    bare.startswith(key) for key in keys if len(key) > 2
                ):
                    entry = {"column": col}
                    if "filter" in bare:
                        entry["filtered"] = True
                    prior = taken.get(channel)
                    # two columns of one quantity (alt in ft and in m): keep the SI one
                    if prior is None or (
                        _bracket_unit(prior["column"])
                        not in ("m", "m/s", "pa", "m/s^2")
                        and _bracket_unit(col) in ("m", "m/s", "pa", "m/s^2")
                    ):
                        taken[channel] = entry
                    break
        if not taken:
            continue
        time_unit = _bracket_unit(names[j]) or _CLOCK_UNITS.get(_bare(names[j]), "")
        time = channel_spec(
            "time",
            {
                "column": names[j],
                **({"unit": time_unit} if time_unit in ("s", "ms", "us") else {}),
            },
            where,
            None,
        )
        chans = tuple(
            channel_spec(n, v, where, header, "header") for n, v in taken.items()
        )
        streams.append(StreamSpec(file, time, chans, label=file.stem))
    if not streams:
        raise LogError(
            f"{file}: no column recognised as altitude, pressure, acceleration, speed "
            f"or position among {', '.join(names)}; give a column map"
        )
    return streams, "altimeter CSV"
