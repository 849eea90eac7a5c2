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


G0 = 9.80665
UNITS = {
    "": 1.0,
    "1": 1.0,
    "-": 1.0,
    "si": 1.0,
    "s": 1.0,
    "ms": 1e-3,
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
    "n": 1.0,
    "kn": 1e3,
    "lbf": 4.4482216152605,
    "pa": 1.0,
    "kpa": 1e3,
    "hpa": 1e2,
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


def load_columns(source) -> dict[str, Column]:
    """A column map from a dict, or a `.json` / `.toml` file."""
    where = "column map"
    if source is None:
        return {}
    if not isinstance(source, dict):
        path = pathlib.Path(source)
        where = str(path)
        try:
            text = path.read_text(encoding="utf-8-sig")
        except OSError as e:
            raise LogError(
                f"{path}: cannot read the column map ({e.strerror})"
            ) from None
        try:
            source = (
                tomllib.loads(text)
                if path.suffix.lower() == ".toml"
                else json.loads(text)
            )
        except (ValueError, tomllib.TOMLDecodeError) as e:
            raise LogError(f"{path}: not a valid column map ({e})") from None
        if not isinstance(source, dict):
            raise LogError(f"{path}: a column map is a table of channels")
    return {ch: Column(ch, spec, where) for ch, spec in source.items()}


def _numeric_rows(path: pathlib.Path, head: str):
    """The table of a file with no header (every non-blank line numbers), by column
    number from 1; `None` if the first non-blank line is not all numbers."""
    from ._format import _NUMBER

    cells = head.replace(",", " ").split()
    if not cells or not all(_NUMBER.fullmatch(c) for c in cells):
        return None
    data, width = [], len(cells)
    with open(path, encoding="utf-8-sig") as f:
        for j, line in enumerate(f, start=1):
            row = line.replace(",", " ").split()
            if not row:
                continue
            if len(row) != width:
                raise LogError(
                    f"{path}: line {j} has {len(row)} values, the first line {width}"
                )
            for k, cell in enumerate(row, start=1):
                if not _NUMBER.fullmatch(cell):
                    raise LogError(
                        f"{path}: line {j}, column {k}: {cell!r} is not a number"
                    )
            data.append([float(c) for c in row])
    arr = np.asarray(data, float)
    return {str(k + 1): arr[:, k] for k in range(width)}


def read_table(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Every numeric column of a file: by header name for CSV and `.asc` files, by
    number (`"1"`, `"2"`, ...) for plain numeric tables with no header."""
    from ._asc import read_asc
    from ._matfile import read_matrix_file, SUFFIXES

    path = pathlib.Path(path)
    if path.suffix.lower() in SUFFIXES:
        return read_matrix_file(path)
    try:
        with open(path, encoding="utf-8-sig") as f:
            head = ""
            for head in f:
                if head.strip():
                    break
    except OSError as e:
        raise LogError(f"{path}: cannot read the file ({e.strerror})") from None
    except UnicodeDecodeError:
        raise LogError(f"{path}: not a UTF-8 text file") from None
    if (table := _numeric_rows(path, head)) is not None:
        return table
    if path.suffix.lower() == ".asc" or "," not in head:
        return read_asc(path)
    import csv

    with open(path, newline="", encoding="utf-8-sig") as f:
        rows = list(csv.reader(f))
    if not rows or not rows[0]:
        raise LogError(f"{path}: the file is empty")
    names = [n.strip() for n in rows[0]]
    out: dict[str, list[float]] = {n: [] for n in names}
    numeric = dict.fromkeys(names, True)
    for r, row in enumerate(rows[1:], start=1):
        if not row:
            continue
        if len(row) != len(names):
            raise LogError(
                f"{path}: row {r} has {len(row)} values, the header {len(names)}"
            )
        for name, cell in zip(names, row, strict=True):
            try:
                if "_" in cell or not cell.isascii():
                    raise ValueError
                out[name].append(float(cell))
            except ValueError:
                if numeric[name] and len(out[name]) == 0 and r == 1:
                    numeric[name] = False
                if numeric[name]:
                    raise LogError(
                        f"{path}: column {name!r} row {r}: {cell!r} is not a number"
                    ) from None
    return {n: np.asarray(v, float) for n, v in out.items() if numeric[n]}


def _channel(table, columns, name, path):
    col = columns.get(name) or Column(name, name, "column map")
    if col.step is not None:
        n = len(next(iter(table.values())))
        return col.step * np.arange(n)
    if col.column not in table and name in table:
        # a log in our own layout (e.g. simulated) read through a vehicle's map
        col = Column(name, name, "column map")
    if col.column not in table:
        raise LogError(
            f"{path}: no column {col.column!r} for channel {name!r} (columns: "
            f"{_listing(table)}); map it in the column map (--columns, or the model "
            "file's columns)"
        )
    values = table[col.column] * col.factor
    bad = ~np.isfinite(values)
    if bad.any():
        row = int(np.argmax(bad)) + 1
        raise LogError(
            f"{path}: column {col.column!r} row {row}: value "
            f"{table[col.column][row - 1]:g} is not finite"
        )
    return values


def _listing(table) -> str:
    names = list(table)
    if names and all(n.isdigit() for n in names):
        return f"numbered 1 to {len(names)}, the file has no header"
    return ", ".join(names)


def _read_with(reader, path: pathlib.Path) -> dict[str, np.ndarray]:
    """Channels from a user's `read(path)`: a dict of equal-length 1-D arrays, SI."""
    try:
        out = reader(str(path))
    except LogError:
        raise
    except Exception as e:  # the user's code: one line, naming the file
        raise LogError(f"{path}: read() failed: {type(e).__name__}: {e}") from None
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
    whose channels are combinations of columns."""
    path = pathlib.Path(path)
    columns = (
        load_columns(columns)
        if not isinstance(columns, dict)
        else {
            k: v if isinstance(v, Column) else Column(k, v, "column map")
            for k, v in columns.items()
        }
    )
    if reader is not None:
        table, columns = _read_with(reader, path), {}
    else:
        table = read_table(path)
    t = _channel(table, columns, time, path)
    inputs = np.column_stack([_channel(table, columns, n, path) for n in model.inputs])
    measured = np.column_stack(
        [_channel(table, columns, n, path) for n in model.outputs]
    )
    # the unit-mistake checks of flight logs, on whatever channels the model has
    # (a theta in degrees, q in deg/s, qbar against 0.5 rho V^2, ...)
    from ._checks import check_physics
    from ._format import check_ranges

    channels = {"t": t}
    for j, n in enumerate(model.inputs):
        channels[n] = inputs[:, j]
    for j, n in enumerate(model.outputs):
        channels[n] = measured[:, j]
    check_ranges(
        channels,
        str(path),
        {n: c.column for n, c in columns.items()},
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
    if x0 is None:
        guess = []
        for name in model.states:
            try:
                guess.append(_channel(table, columns, name, path)[0])
            except LogError:
                guess.append(math.nan)
        x0 = None if any(math.isnan(g) for g in guess) else np.asarray(guess)
    try:
        return Record(t, inputs, measured, x0=x0, name=path.name)
    except ValueError as e:
        raise LogError(f"{path}: {e}".replace(f"{path.name}: ", "", 1)) from None
