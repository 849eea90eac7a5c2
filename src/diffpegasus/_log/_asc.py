"""Reader for the column text files of flight-test data (`.asc`, as shipped with
FVSysID test cases): a few free-text lines, a row of channel names, a row of units,
then one row of numbers per sample."""

import os
import pathlib

import numpy as np

from .._vehicle._lateral import LATERAL_COLUMNS
from ._format import _NUMBER, LogError


def read_asc(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Channels of an `.asc` file by name (upper case as in the file), SI units.

    **Raises:** [`LogError`][] naming the file, line, channel and value of the first
    problem (no header, a ragged line, a cell that is not a plain number, no data).
    """
    path = pathlib.Path(path)
    try:
        lines = path.read_text(encoding="utf-8-sig").splitlines()
    except OSError as e:
        raise LogError(f"{path}: cannot read the file ({e.strerror})") from None
    except UnicodeDecodeError:
        raise LogError(f"{path}: not a UTF-8 text file") from None
    rows = [line.split() for line in lines]
    for i, row in enumerate(rows):
        if row and row[0] == "T":
            names = row
            start = i + 2
            break
    else:
        raise LogError(f"{path}: no header row starting with 'T' (the time channel)")
    data = []
    for j, row in enumerate(rows[start:], start=start + 1):
        if not row:
            continue
        if len(row) != len(names):
            raise LogError(
                f"{path}: line {j} has {len(row)} values, expected {len(names)}"
            )
        for name, cell in zip(names, row, strict=True):
            if not _NUMBER.fullmatch(cell):
                raise LogError(
                    f"{path}: line {j}, channel {name!r}: {cell!r} is not a number"
                )
        data.append([float(x) for x in row])
    if not data:
        raise LogError(f"{path}: no data rows after the header and units rows")
    arr = np.asarray(data)
    return {name: arr[:, k] for k, name in enumerate(names)}


def read_lateral_asc(path, columns: dict | None = None) -> dict[str, np.ndarray]:
    """The lateral channels of an FVSysID `.asc` file (see [`LATERAL_COLUMNS`][];
    `columns` overrides names), SI units and radians as in the file."""
    data = read_asc(path)
    names = {**LATERAL_COLUMNS, **(columns or {})}
    return {k: data[v] for k, v in names.items() if v in data}
