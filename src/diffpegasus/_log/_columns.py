"""Column maps: logs from anywhere into a model's inputs and outputs.

A column map says, for each channel a model needs, which column of the file holds it,
in which unit, and with what extra scale factor. It is a dict (or a JSON / TOML file)

    {"t": "T",                                   # column name only: SI already
     "de": {"column": "DELV"},                   # the same, long form
     "alpha": {"column": "AOA", "unit": "deg"},  # converted to rad
     "az": {"column": "NZ", "unit": "g", "scale": -1.0}}

Units understood: see [`UNITS`][]; a value is multiplied by the unit's factor to SI,
then by `scale`. A channel missing from the map, or whose mapped column the file does
not have, is looked up by its own name (in SI units).

Files: MATLAB `.mat` (v5 and v7.3) and HDF5 files (see `_matfile`); CSV with a
header row (`.csv`, or anything with commas in its header); the
column text files of FVSysID (`.asc`: free-text lines, a row of names starting with
`T`, a row of units, then numbers); and plain numeric tables with no header at all
(whitespace or commas), whose columns are numbered from 1 as FVSysID's MATLAB scripts
and the textbook count them: `{"p": {"column": 7, "unit": "deg/s"}}`. A file with no
time column gets its time from the sample step: `{"t": {"step": 0.04}}` (s, the
first sample at 0). Channels no map can express (a sum or difference of columns)
come from a model file's `read(path)` function instead (see [`load_record`][]).
"""

import json
import math
import os
import pathlib
import re
import tomllib

import numpy as np

from .._errors import LogError
from .._model import Model, Record
from ._table import open_table, Table


G0 = 9.80665
UNITS = {
    "": 1.0,
    "1": 1.0,
    "-": 1.0,
    "si": 1.0,
    "s": 1.0,
    "ms": 1e-3,
    "us": 1e-6,
    "rad": 1.0,
    "deg": math.pi / 180,
    "rad/s": 1.0,
    "deg/s": math.pi / 180,
    "rad/s^2": 1.0,
    "deg/s^2": math.pi / 180,
    "m": 1.0,
    "ft": 0.3048,
    "km": 1e3,
    "m/s": 1.0,
    "ft/s": 0.3048,
    "kt": 1852.0 / 3600.0,
    "km/h": 1.0 / 3.6,
    "m/s^2": 1.0,
    "ft/s^2": 0.3048,
    "g": G0,
    "mg": G0 * 1e-3,  # milli-g (mG), as accelerometer logs write it; no mass unit
    "n": 1.0,
    "kn": 1e3,
    "lbf": 4.4482216152605,
    "pa": 1.0,
    "kpa": 1e3,
    "hpa": 1e2,
    "mbar": 1e2,
    "bar": 1e5,
    "atm": 101325.0,
    "psi": 6894.757293168,
    "inhg": 3386.389,
    "psf": 47.880258980336,
    "kg": 1.0,
    "lb": 0.45359237,
}


class Column:
    """Where one channel comes from: `column` name, `factor` to SI (unit times
    scale)."""

    def __init__(self, channel: str, spec, where: str):
        if isinstance(spec, str | int) and not isinstance(spec, bool):
            spec = {"column": spec}
        if not isinstance(spec, dict):
            raise LogError(
                f"{where}: channel {channel!r} must map to a column name or a table "
                f"with 'column', 'unit', 'scale', got {spec!r}"
            )
        unknown = set(spec) - {"column", "unit", "scale", "step"}
        if unknown:
            raise LogError(
                f"{where}: channel {channel!r} has unknown keys {sorted(unknown)} "
                "(allowed: column, unit, scale, step)"
            )
        if "step" in spec and "column" in spec:
            raise LogError(
                f"{where}: channel {channel!r} has both a column "
                f"({spec['column']!r}) and a step ({spec['step']!r}); give one: the "
                "column of times, or the step of a file with no time column"
            )
        self.channel = channel
        self.step = spec.get("step")
        if self.step is not None and (
            isinstance(self.step, bool)
            or not isinstance(self.step, int | float)
            or not math.isfinite(self.step)
            or self.step <= 0
        ):
            raise LogError(
                f"{where}: channel {channel!r}: step must be a positive number of "
                f"seconds, got {self.step!r}"
            )
        column = spec.get("column", channel)
        if isinstance(column, int) and not isinstance(column, bool):
            if column < 1:
                raise LogError(
                    f"{where}: channel {channel!r}: column numbers count from 1, "
                    f"got {column}"
                )
            column = str(column)
        if not isinstance(column, str):
            raise LogError(
                f"{where}: channel {channel!r}: column must be a name or a number "
                f"(from 1), got {column!r}"
            )
        self.column = column
        unit = spec.get("unit", "")
        self.unit = unit
        if not isinstance(unit, str) or unit.lower() not in UNITS:
            raise LogError(
                f"{where}: channel {channel!r}: unknown unit {unit!r} "
                f"(known: {', '.join(u for u in UNITS if u)})"
            )
        scale = spec.get("scale", 1.0)
        if isinstance(scale, bool) or not isinstance(scale, int | float):
            raise LogError(f"{where}: channel {channel!r}: scale must be a number")
        if not math.isfinite(scale) or scale == 0:
            raise LogError(f"{where}: channel {channel!r}: scale {scale} is not usable")
        self.factor = UNITS[unit.lower()] * float(scale)


def _no_duplicate_keys(pairs):
    keys = [k for k, _ in pairs]
    for k in keys:
        if keys.count(k) > 1:
            raise _DuplicateKey(k)
    return dict(pairs)


class _DuplicateKey(ValueError):
    pass


def load_columns(source, where: str = "column map") -> dict[str, Column]:
    """A column map from a dict, or a `.json` / `.toml` file (UTF-8; a key given
    twice is refused, not silently overwritten). `where` names a dict's origin in
    messages (e.g. the model file that defines it)."""
    if source is None:
        return {}
    if not isinstance(source, dict | str | os.PathLike):
        raise LogError(
            f"{where}: a column map is a dict of channel -> column, or the path of a "
            f"JSON or TOML file, got {type(source).__name__}"
        )
    if not isinstance(source, dict):
        path = pathlib.Path(source)
        where = str(path)
        try:
            data = path.read_bytes()
        except OSError as e:
            raise LogError(
                f"{path}: cannot read the column map ({e.strerror})"
            ) from None
        if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
            raise LogError(f"{path}: the column map is UTF-16 text; save it as UTF-8")
        try:
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError as e:
            raise LogError(
                f"{path}: the column map is not UTF-8 text (byte {e.start} is "
                f"{data[e.start]:#04x}; a Latin-1 or Windows-1252 file?): save it as "
                "UTF-8"
            ) from None
        try:
            source = (
                tomllib.loads(text)
                if path.suffix.lower() == ".toml"
                else json.loads(text, object_pairs_hook=_no_duplicate_keys)
            )
        except _DuplicateKey as e:
            raise LogError(
                f"{path}: key {e.args[0]!r} is given twice in one table of the column "
                "map; keep one"
            ) from None
        except (ValueError, tomllib.TOMLDecodeError) as e:
            raise LogError(f"{path}: not a valid column map ({e})") from None
        if not isinstance(source, dict):
            raise LogError(f"{path}: a column map is a table of channels")
    bad = [k for k in source if not isinstance(k, str)]
    if bad:
        raise LogError(f"{where}: channel names are strings, got {bad[0]!r}")
    return {ch: Column(ch, spec, where) for ch, spec in source.items()}


def read_table(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Every numeric column of a file: by header name for CSV and `.asc` files, by
    number (`"1"`, `"2"`, ...) for plain numeric tables with no header."""
    return open_table(path).read()


def _resolve(table: Table, columns: dict[str, Column], channels) -> dict[str, Column]:
    """Which column of `table` each of `channels` comes from.

    A channel the map does not name is read from the column of its own name. A mapped
    column the file lacks falls back to the channel's own name only when the whole
    file is in that layout (none of the map's columns in it: a log this package
    wrote, read through a vehicle's map) and the entry asks for no unit or scale
    (which the fallback would drop); anything else is an error naming both."""
    names = set(table.names)
    own_layout = not any(
        c.column in names for ch, c in columns.items() if c.column != ch
    )
    out = {}
    for ch in channels:
        col = columns.get(ch) or Column(ch, ch, "column map")
        if col.step is not None or col.column in names:
            out[ch] = col
            continue
        found = ch in names
        if found and own_layout and col.factor == 1.0:
            out[ch] = Column(ch, ch, "column map")
            continue
        where = f"{table.path}: no column {col.column!r} for channel {ch!r}"
        near = [n for n in table.names if n.lower() == col.column.lower()]
        if near:
            raise LogError(
                f"{where}: the file has {near[0]!r} (column names are "
                f"case-sensitive); map the channel to {near[0]!r}"
                + (f", and check that its unit is {col.unit!r}" if col.unit else "")
            )
        if found:
            raise LogError(
                f"{where}, although it has a column {ch!r}: the map says "
                f"{col.column!r}"
                + (f" in {col.unit!r}" if col.unit else "")
                + f", and reading {ch!r} in SI units instead could be wrong; map "
                f'it explicitly ("{ch}": {{"column": "{ch}", "unit": ...}})'
            )
        raise LogError(
            f"{where} (columns: {table.listing()}); map it in the column map "
            "(--columns, or the model file's columns)"
        )
    used: dict[str, str] = {}
    for ch, col in out.items():
        if col.step is not None:
            continue
        if col.column in used:
            raise LogError(
                f"{table.path}: channels {used[col.column]!r} and {ch!r} both read "
                f"column {col.column!r}; each channel needs its own column (check the "
                "column map)"
            )
        used[col.column] = ch
    return out


def _channel(table: Table, data, col: Column, n: int) -> np.ndarray:
    """A channel's values in SI units, refused where they cannot be measurements."""
    if col.step is not None:
        t = col.step * np.arange(n)
        if col.channel in data:
            _check_step(table, data[col.channel], col)
        return t
    raw = data[col.column]
    bad = ~np.isfinite(raw)
    if bad.any():
        row = int(np.argmax(bad)) + 1
        raise LogError(
            f"{table.path}: column {col.column!r} (channel {col.channel!r}) row "
            f"{row}: value {raw[row - 1]:g} is not finite"
        )
    _check_outliers(table, raw, col)
    return raw * col.factor


def _check_step(table: Table, t: np.ndarray, col: Column) -> None:
    """A `step` beside a time column of the channel's name: both must agree."""
    if len(t) < 2:
        return
    dt = float(np.median(np.diff(t)))
    if not abs(dt - col.step) <= 1e-6 * col.step:
        raise LogError(
            f"{table.path}: the column map gives channel {col.channel!r} a step of "
            f"{col.step:g} s, but the file's column {col.channel!r} steps by {dt:g} s; "
            "remove the step or the column from the map"
        )


def corrupt_cell(values: np.ndarray) -> tuple[int, str] | None:
    """The first value no measurement holds, as `(index, why)`, or `None`: one whose
    square, summed over the record, would overflow float64; one a million times
    beyond the column's own 90th-percentile spread about its median with ordinary
    samples on both sides (a corrupt cell, not a measurement: a control moved for
    under a tenth of a record that is otherwise still, to rounding, spans several
    samples). `values` in SI units, finite."""
    big = np.abs(values)
    i = int(np.argmax(big))
    if big[i] > np.sqrt(np.finfo(float).max / (4 * len(values))):
        return i, (
            "is too large for a measurement (its square summed over the record "
            "overflows float64); a corrupt cell or a wrong scale"
        )
    # the median and spread from at most 65536 evenly spaced samples: a factor of a
    # million needs no more precision, and a long log costs no sort of every value
    sample = values[:: max(1, len(values) // 65536)]
    med = float(np.median(sample))
    spread = float(np.percentile(np.abs(sample - med), 90))
    dev = np.abs(values - med)
    far = dev > 1e6 * spread
    beside = np.zeros_like(far)
    beside[1:] |= far[:-1]
    beside[:-1] |= far[1:]
    lone = far & ~beside
    i = int(np.argmax(np.where(lone, dev, -1.0)))
    if spread > 0 and lone[i]:
        return i, (
            f"is {dev[i] / spread:.3g} times the column's 90th-percentile spread "
            f"about its median ({med:g}): a corrupt cell, not a measurement"
        )
    return None


def _check_outliers(table: Table, raw: np.ndarray, col: Column) -> None:
    """A value the fit cannot use (`corrupt_cell`) is one error line."""
    found = corrupt_cell(raw * col.factor)
    if found is not None:
        i, why = found
        raise LogError(
            f"{table.path}: column {col.column!r} (channel {col.channel!r}) row "
            f"{i + 1}: value {raw[i]:g} {why}"
        )


def _read_with(reader, path: pathlib.Path) -> dict[str, np.ndarray]:
    """Channels from a user's `read(path)`: a dict of equal-length 1-D arrays, SI."""
    from .._usercode import contained

    where = getattr(getattr(reader, "__code__", None), "co_filename", str(path))
    with contained(where, f"in read({str(path)!r})"):
        out = reader(str(path))
    if not isinstance(out, dict) or not out:
        raise LogError(
            f"{path}: read() must return a dict of channel name -> 1-D array, got "
            f"{type(out).__name__}"
        )
    table, n = {}, None
    for k, v in out.items():
        try:
            a = np.asarray(v, float)
        except (TypeError, ValueError):
            raise LogError(f"{path}: read() channel {k!r} is not numeric") from None
        if a.ndim != 1 or (n is not None and len(a) != n):
            raise LogError(
                f"{path}: read() channel {k!r} has shape {a.shape}; every channel "
                f"must be 1-D of one length ({n})"
            )
        n = len(a)
        table[str(k)] = a
    return table


def load_record(
    model: Model, path, columns=None, x0=None, time: str = "t", reader=None
) -> Record:
    """A [`Record`][] of `model` from a file: its time, inputs and outputs by the
    column map `columns`; the initial state `x0` (default: the state channels at the
    first sample where the file has them). `reader(path) -> {channel: array}` (SI
    units, by channel name) replaces the file reading and the column map, for files
    whose channels are combinations of columns.

    **Raises:** [`LogError`][] naming the file and, where they apply, the column,
    row and value: an unreadable file, a mapped column the file lacks, two channels
    on one column, a cell that is not a number, a value no measurement has, a channel
    whose unit disagrees with the physics of the others, a record too short to fit.
    """
    path = pathlib.Path(path)
    columns = (
        load_columns(columns)
        if not isinstance(columns, dict)
        else {
            k: v if isinstance(v, Column) else Column(k, v, "column map")
            for k, v in columns.items()
        }
    )
    needed = (time, *model.inputs, *model.outputs)
    if reader is not None:
        data = _read_with(reader, path)
        table = Table(path, tuple(data), "read", 0, 0, None)
        resolved = _resolve(table, {}, needed)
    else:
        table = open_table(path)
        resolved = _resolve(table, columns, needed)
        state_cols = _state_columns(table, columns, model, resolved)
        wanted = [c.column for c in resolved.values() if c.step is None]
        wanted += [c.column for c in state_cols.values()]
        wanted += [
            ch for ch, c in resolved.items() if c.step is not None and ch in table.names
        ]
        data = table.read(wanted)
    n = len(next(iter(data.values()))) if data else 0
    channels = {ch: _channel(table, data, col, n) for ch, col in resolved.items()}
    t = channels[time]
    inputs = (
        np.column_stack([channels[n_] for n_ in model.inputs])
        if model.inputs
        else np.zeros((n, 0))
    )
    measured = np.column_stack([channels[n_] for n_ in model.outputs])
    _check_record(path, channels, model, resolved, time)
    _check_units(path, channels, resolved)
    if x0 is None:
        if reader is not None:
            guess = [data[s][0] if s in data else math.nan for s in model.states]
        else:
            guess = [
                _channel(table, data, state_cols[s], n)[0]
                if s in state_cols
                else channels[s][0]
                if s in channels
                else math.nan
                for s in model.states
            ]
        x0 = None if any(math.isnan(g) for g in guess) else np.asarray(guess)
    try:
        return Record(t, inputs, measured, x0=x0, name=path.name)
    except ValueError as e:
        raise LogError(f"{path}: {e}".replace(f"{path.name}: ", "", 1)) from None


def _check_units(path, channels, resolved) -> None:
    """The unit-mistake checks of flight logs on whatever channels a column map
    gave (a theta in degrees, q in deg/s, qbar against 0.5 rho V^2, ...), each
    failure one [`LogError`][] that points at the column map."""
    from ._checks import check_physics
    from ._format import check_ranges

    check_ranges(
        channels,
        str(path),
        {ch: c.column for ch, c in resolved.items()},
        hint='give it "unit": "deg" in the column map',
    )
    try:
        check_physics(channels, {"skip_checks": ["geometry"]}, str(path), str(path))
    except ValueError as e:
        # a file read through a column map has no sidecar to skip checks in
        message = re.sub(
            r" \(if the data are right, add \"skip_checks\": \[\"\w+\"\] to the "
            r"sidecar\)",
            " (check that channel's unit and scale in the column map)",
            str(e),
        )
        raise LogError(message) from None


def _state_columns(table, columns, model, resolved) -> dict[str, Column]:
    """Columns of the states that are not also inputs or outputs (for the initial
    state), where the file has them; a state the map names must be there."""
    out = {}
    for s in model.states:
        if s in resolved:
            continue
        if s in columns:
            out[s] = _resolve(table, columns, (s,))[s]
        elif s in table.names:
            out[s] = Column(s, s, "column map")
    return out


def _check_record(path, channels, model, resolved, time) -> None:
    """What no fit can use: too few samples, or an output that never changes."""
    n = len(channels[time])
    if n < 3:
        raise LogError(
            f"{path}: only {n} sample(s); a record needs at least 3 (two steps of "
            "the dynamics) and, over all records, more measured values than "
            "unknowns"
        )
    for name in model.outputs:
        v = channels[name]
        if np.all(v == v[0]):
            col = resolved[name].column
            raise LogError(
                f"{path}: column {col!r} (output {name!r}) is {v[0] + 0.0:g} in all {n} "
                "rows: a dead sensor or an empty column; the fit weighs each output by "
                "its residual variance, which a constant makes zero (remove the "
                "output from the model, or map the right column)"
            )


def read_channels(path, columns, time: str = "t") -> dict[str, np.ndarray]:
    """Every channel a column map names (and `time`), in SI units, with the checks
    [`load_record`][] makes on them (cells, outliers, ranges, unit mistakes found
    by the physics of the channels present): what `diffpegasus check --columns`
    reads.

    **Raises:** [`LogError`][] naming the file and, where they apply, the column,
    row and value.
    """
    path = pathlib.Path(path)
    columns = load_columns(columns)
    table = open_table(path)
    wanted = (time, *(ch for ch in columns if ch != time))
    resolved = _resolve(table, columns, wanted)
    data = table.read([c.column for c in resolved.values() if c.step is None])
    n = len(next(iter(data.values()))) if data else 0
    channels = {ch: _channel(table, data, col, n) for ch, col in resolved.items()}
    _check_units(path, channels, resolved)
    return channels
