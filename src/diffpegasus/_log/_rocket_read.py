"""The numbers of a flight computer's CSV file, fast where the file is clean and
exact about where it is not.

A file is read once for all the columns its streams need: numpy's C parser on the
wanted columns (a million rows of an 80-column AltOS export in about 4 s), and only
when that fails a line-by-line pass that finds the first bad cell, or a block of
corrupt rows at the end of the file (a flight computer losing power while writing),
which it drops with a message.
"""

import csv
import math
import pathlib
import re
import warnings

import numpy as np

from .._errors import LogError


# ASCII decimal with optional exponent, nan, inf (what a flight computer writes);
# Python's float() also takes "1_000" and non-ASCII digits, which are not data.
_NUMBER = re.compile(
    r"\s*[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf|infinity)\s*",
    re.IGNORECASE | re.ASCII,
)
_SEPARATORS = (",", ";", "\t")


class Header:
    """A CSV file's column names, where its data start, its separator."""

    def __init__(self, path: pathlib.Path):
        self.path = path
        try:
            with open(path, encoding="utf-8-sig", newline="") as f:
                skipped = 0
                for line in f:
                    skipped += 1
                    if line.strip():
                        break
                else:
                    raise LogError(f"{path}: the file is empty")
        except OSError as e:
            raise LogError(f"{path}: cannot read the file ({e.strerror})") from None
        except UnicodeDecodeError:
            raise LogError(f"{path}: not a UTF-8 text file") from None
        self.sep = max(_SEPARATORS, key=line.count)
        if line.count(self.sep) == 0 and len(line.split()) > 1:
            raise LogError(
                f"{path}: the first line has no ',', ';' or tab: not a CSV file "
                "with a header row"
            )
        cells = next(csv.reader([line], delimiter=self.sep))
        if all(_NUMBER.fullmatch(c) for c in cells):
            raise LogError(
                f"{path}: the first line is numbers, not a header of column names; "
                "give the columns by number in a column map (from 1)"
            )
        names = [c.strip().lstrip("#").strip() for c in cells]
        # a name written twice (AltOS: baro and GPS 'altitude') gets ' (2)', ' (3)'
        seen: dict[str, int] = {}
        self.names = []
        for n in names:
            seen[n] = seen.get(n, 0) + 1
            self.names.append(n if seen[n] == 1 else f"{n} ({seen[n]})")
        self.skip = skipped

    def index(self, column: str) -> int:
        """0-based position of a column given by name or by number from 1."""
        if column in self.names:
            return self.names.index(column)
        if column.isdigit() and 1 <= int(column) <= len(self.names):
            return int(column) - 1
        lowered = [n.lower() for n in self.names]
        if column.lower() in lowered:
            return lowered.index(column.lower())
        raise KeyError(column)


def read_columns(header: Header, columns: list[int]) -> tuple[np.ndarray, list[str]]:
    """The float values of `columns` (0-based), shape `(rows, len(columns))`; empty
    cells are nan. Returns the array and messages about rows dropped."""
    path = header.path
    columns = sorted(set(columns))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "input contained no data": checked after
            data = np.loadtxt(
                path,
                delimiter=header.sep,
                skiprows=header.skip,
                usecols=columns,
                dtype=float,
                comments=None,
                ndmin=2,
                encoding="utf-8-sig",
            )
        return data, []
    except (ValueError, IndexError):
        pass
    except OSError as e:
        raise LogError(f"{path}: cannot read the file ({e.strerror})") from None
    return _read_carefully(header, columns)


def _read_carefully(header: Header, columns: list[int]):
    """The slow path: every cell checked, the first bad one named; a trailing run of
    unreadable rows (a write cut short) dropped with a message."""
    path = header.path
    rows: list[list[float]] = []
    bad: list[tuple[int, str, str]] = []  # (row, column, value) of unreadable rows
    width = len(header.names)
    with open(path, encoding="utf-8-sig", newline="") as f:
        for _ in range(header.skip):
            f.readline()
        for r, line in enumerate(csv.reader(f, delimiter=header.sep), start=1):
            if not any(c.strip() for c in line):
                continue
            problem = None
            values = []
            if len(line) < width and len(line) <= max(columns):
                problem = (
                    r,
                    header.names[min(len(line), width - 1)],
                    "(row ends early)",
                )
            else:
                for j in columns:
                    cell = line[j].strip()
                    if not cell:
                        values.append(math.nan)
                    elif _NUMBER.fullmatch(cell):
                        values.append(float(cell))
                    else:
                        problem = (r, header.names[j], cell)
                        break
            if problem is None and bad:
                # an unreadable row followed by readable ones: not a cut-off end
                r0, col, value = bad[0]
                raise LogError(
                    f"{path}: column {col!r}, row {r0}: {value!r} is not a number"
                )
            if problem is not None:
                bad.append(problem)
            else:
                rows.append(values)
    if not rows:
        if bad:
            r0, col, value = bad[0]
            raise LogError(
                f"{path}: column {col!r}, row {r0}: {value!r} is not a number"
            )
        raise LogError(f"{path}: the file has a header but no data rows")
    messages = []
    if bad:
        r0, col, value = bad[0]
        messages.append(
            f"{path.name}: dropped the last {len(bad)} row(s) from row {r0} on: "
            f"unreadable (column {col!r}: {value!r}), a write cut short"
        )
    return np.asarray(rows, float).reshape(-1, len(columns)), messages
