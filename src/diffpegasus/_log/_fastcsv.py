"""Reading the numbers of a large all-numeric CSV quickly, in bounded memory.

The file is read in blocks of whole lines; per block, NumPy checks that every line
has the header's number of commas and no empty cell, then parses the block's numbers
in C (`np.fromstring`) and keeps only the columns asked for. Time is linear in the
file's size and memory is the kept columns plus one block, whatever the number of
rows. Anything irregular (a ragged row, an empty or quoted cell, a word, a blank
line, a non-ASCII digit) makes it return `None`: the callers' careful readers then
find the problem and name its row, column and value.
"""

import os
import re
import warnings

import numpy as np


_BLOCK_BYTES = 8 * 2**20
# A cell holding only blanks: np.fromstring reads it as -1 instead of failing.
_BLANK_CELL = re.compile(rb"(?:^|,)[ \t]*(?:,|$)", re.MULTILINE)
_NEWLINE, _COMMA = ord("\n"), ord(",")


def _block_values(block: bytes, width: int) -> np.ndarray | None:
    """The numbers of `block` (whole lines, each ending in a newline) as a
    `(lines, width)` array, or `None` if any line is not `width` plain numbers."""
    if b"\r" in block:
        block = block.replace(b"\r", b"")
    raw = np.frombuffer(block, np.uint8)
    ends = np.flatnonzero(raw == _NEWLINE)
    commas = np.flatnonzero(raw == _COMMA)
    per_line = np.diff(np.searchsorted(commas, ends), prepend=0)
    if np.any(per_line != width - 1) or _BLANK_CELL.search(block):
        return None
    with warnings.catch_warnings():
        # a cell np.fromstring cannot parse ends it early with a warning
        warnings.simplefilter("error")
        try:
            values = np.fromstring(block.replace(b"\n", b","), sep=",")
        except (ValueError, DeprecationWarning):
            return None
    if values.size != len(ends) * width:
        return None
    return values.reshape(len(ends), width)


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
                values = _block_values(block, width)
                if values is None:
                    return None
                kept.append(values[:, columns])
        rest = rest.rstrip(b" \t\r\n")
        if rest:
            values = _block_values(rest + b"\n", width)
            if values is None:
                return None
            kept.append(values[:, columns])
    if not kept:
        return np.empty((0, len(columns)))
    return np.concatenate(kept)
