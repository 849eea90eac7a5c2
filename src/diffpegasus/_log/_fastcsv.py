"""Reading the numbers of a large all-numeric CSV quickly, in bounded memory.

The file is read in blocks of whole lines; per block, NumPy checks that every line
has the header's number of commas, then its C reader (`np.loadtxt`) converts only
the columns asked for (an empty cell there fails it; one in a column no map asks
for does not matter). Time is linear in the
file's size and memory is the kept columns plus one block, whatever the number of
rows. Anything irregular (a ragged row, an empty or quoted cell, a word, a blank
line, a non-ASCII digit) makes it return `None`: the callers' careful readers then
find the problem and name its row, column and value.
"""

import io
import os

import numpy as np


_BLOCK_BYTES = 8 * 2**20
_NEWLINE, _COMMA = ord("\n"), ord(",")


def _block_values(block: bytes, width: int, columns: list[int]) -> np.ndarray | None:
    """The `columns` of `block` (whole lines, each ending in a newline) as a
    `(lines, len(columns))` array, or `None` if any line is not `width` plain
    numbers."""
    if b"\r" in block:
        block = block.replace(b"\r", b"")
    raw = np.frombuffer(block, np.uint8)
    newline, comma = raw == _NEWLINE, raw == _COMMA
    ends = np.flatnonzero(newline)
    per_line = np.diff(np.searchsorted(np.flatnonzero(comma), ends), prepend=0)
    if np.any(per_line != width - 1):
        return None  # a ragged row or a blank line (NumPy would read past them)
    try:
        # NumPy's C reader parses only the kept columns (the others are skipped,
        # not converted): with a few of many columns mapped, most cells cost nothing
        values = np.loadtxt(
            io.BytesIO(block),
            delimiter=",",
            usecols=columns,
            ndmin=2,
            comments=None,
            encoding="ascii",
            dtype=float,
        )
    except (ValueError, UnicodeDecodeError):
        return None
    if values.shape != (len(ends), len(columns)):
        return None
    return values


def read_numeric_csv(
    path: str | os.PathLike, skip_bytes: int, width: int, columns: list[int]
) -> np.ndarray | None:
    """The `columns` (0-based) of the all-numeric body of a CSV of `width` columns
    that starts `skip_bytes` into the file, as a `(rows, len(columns))` float64
    array; `None` if the body is not plain numbers in every cell (the callers' careful
    readers then name the first problem)."""
    kept: list[np.ndarray] = []
    with open(path, "rb") as f:
        f.seek(skip_bytes)
        rest = b""
        while True:
            chunk = f.read(_BLOCK_BYTES)
            if not chunk:
                break
            chunk = rest + chunk
            cut = chunk.rfind(b"\n") + 1
            block, rest = chunk[:cut], chunk[cut:]
            if block:
                values = _block_values(block, width, columns)
                if values is None:
                    return None
                kept.append(values)
        rest = rest.rstrip(b" \t\r\n")
        if rest:
            values = _block_values(rest + b"\n", width, columns)
            if values is None:
                return None
            kept.append(values)
    if not kept:
        return np.empty((0, len(columns)))
    return np.concatenate(kept)
