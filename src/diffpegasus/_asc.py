"""Reader for the column text files of flight-test data (`.asc`, as shipped with
FVSysID test cases): a few free-text lines, a row of channel names, a row of units,
then one row of numbers per sample."""

import os
import pathlib

import numpy as np

from ._log import LogError


def read_asc(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Channels of an `.asc` file by name (upper case as in the file), SI units."""
    path = pathlib.Path(path)
    try:
        lines = path.read_text().splitlines()
    except OSError as e:
        raise LogError(f"{path}: cannot read the file ({e.strerror})") from None
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
        try:
            data.append([float(x) for x in row])
        except ValueError:
            raise LogError(
                f"{path}: line {j} has a value that is not a number"
            ) from None
    arr = np.asarray(data)
    return {name: arr[:, k] for k, name in enumerate(names)}
