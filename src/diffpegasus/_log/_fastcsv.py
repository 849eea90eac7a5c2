"""Reading the numbers of a large all-numeric CSV quickly, in bounded memory.

A first pass reads the file in blocks of whole lines and checks, with NumPy, that
every line has the header's number of commas (NumPy's reader would read past a
ragged row); then NumPy's C reader (`np.loadtxt`) converts only the columns asked
for (an empty cell there fails it; one in a column no map asks for does not
matter). Time is linear in the
file's size and memory is the kept columns plus one block, whatever the number of
rows. Anything irregular (a ragged row, an empty or quoted cell, a word, a blank
line, a non-ASCII digit) makes it return `None`: the callers' careful readers then
find the problem and name its row, column and value.
"""

import os

import numpy as np


_BLOCK_BYTES = 8 * 2**20
_NEWLINE, _COMMA = ord("\n"), ord(",")


def marks_per_line(marks: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """How many of the sorted byte offsets `marks` (separators, say) fall on each line
    of a block whose lines end at the sorted offsets `ends`; shape `ends.shape`."""
    return np.diff(np.searchsorted(marks, ends), prepend=0)


def _regular_lines(block: bytes, width: int) -> int | None:
    """How many lines `block` (whole lines, each ending in a newline) has, or `None`
    if one of them does not have `width` cells."""
    raw = np.frombuffer(block, np.uint8)
    ends = np.flatnonzero(raw == _NEWLINE)
    per_line = marks_per_line(np.flatnonzero(raw == _COMMA), ends)
    if np.any(per_line != width - 1):
        return None  # a ragged row or a blank line (NumPy would read past them)
    return len(ends)


def read_numeric_csv(
    path: str | os.PathLike,
    skip_bytes: int,
    width: int,
    columns: list[int],
    skip_lines: int,
) -> np.ndarray | None:
    """The `columns` (0-based) of the all-numeric body of a CSV of `width` columns
    that starts `skip_bytes` (`skip_lines`) into the file, as a
    `(rows, len(columns))` float64 array; `None` if the body is not plain numbers in
    every mapped cell (the callers' careful readers then name the first problem).

    Two passes: the blocks' line shapes (bounded memory), then NumPy's C reader over
    the whole file, converting only `columns`."""
    lines = 0
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
                n = _regular_lines(block.replace(b"\r", b""), width)
                if n is None:
                    return None
                lines += n
        rest = rest.replace(b"\r", b"").rstrip(b" \t\n")
        if rest:
            n = _regular_lines(rest + b"\n", width)
            if n is None:
                return None
            lines += n
    if lines == 0:
        return np.empty((0, len(columns)))
    try:
        values = np.loadtxt(
            path,
            delimiter=",",
            skiprows=skip_lines,
            usecols=columns,
            ndmin=2,
            comments=None,
            encoding="utf-8-sig",
            dtype=float,
        )
    except (ValueError, UnicodeDecodeError):
        return None
    if values.shape != (lines, len(columns)):
        return None
    return values
