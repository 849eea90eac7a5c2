"""Data files read through a column map: CSV with a header, FVSysID `.asc` column
text, and plain numeric tables with no header (columns numbered from 1).

[`open_table`][] reads only the header (names, or the width of a headerless table);
[`Table.read`][] then reads just the columns a map asks for. A CSV whose cells are all
plain numbers is parsed in C in blocks (`_fastcsv`), in time linear in its size and
memory of the kept columns; any other file, or a CSV with a problem, goes through a
streaming reader that names the line, column and value of the first problem.
"""

import array
import csv
import dataclasses
import os
import pathlib
import re

import numpy as np

from .._errors import LogError
from ._fastcsv import read_numeric_csv
from ._matfile import SUFFIXES as MATRIX_SUFFIXES


# What a number in a data file may look like: ASCII decimal, optional exponent, nan,
# inf. Python's float() also takes "1_000" and non-ASCII digits, which are not data.
NUMBER = re.compile(
    r"\s*[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf|infinity)\s*",
    re.IGNORECASE | re.ASCII,
)
# A number written with a decimal comma ("-2,5"), as spreadsheets in many locales do.
_DECIMAL_COMMA = re.compile(r"^[+-]?\d+,\d+(?:[eE][+-]?\d+)?$", re.ASCII)
# Files above this size are refused before reading (see docs: limits for large files).
MAX_TABLE_BYTES = 4 * 2**30
_HEAD_BYTES = 1 << 16


def _decode_problem(path: pathlib.Path, data: bytes, offset: int = 0) -> str | None:
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        return (
            f"{path}: the file is UTF-16 text; save it as UTF-8 (most editors: "
            "'Save as', encoding UTF-8)"
        )
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as e:
        if e.start >= len(data) - 4 and e.reason == "unexpected end of data":
            return None  # a character cut by the end of the block read
        return (
            f"{path}: not UTF-8 text (byte {offset + e.start} is {data[e.start]:#04x}; "
            "a Latin-1 or Windows-1252 file?): save it as UTF-8"
        )
    return None


def _check_file(path: pathlib.Path) -> bytes:
    """The first bytes of a readable, not too large, UTF-8 text file."""
    if not path.exists():
        raise LogError(f"{path}: no such file")
    if path.is_dir():
        raise LogError(f"{path}: is a folder, not a data file")
    try:
        size = path.stat().st_size
        with open(path, "rb") as f:
            head = f.read(_HEAD_BYTES)
    except OSError as e:
        raise LogError(f"{path}: cannot read the file ({e.strerror})") from None
    if size > MAX_TABLE_BYTES:
        raise LogError(
            f"{path}: the file is {size / 2**30:.1f} GiB; data files above "
            f"{MAX_TABLE_BYTES / 2**30:g} GiB are refused to keep memory bounded; "
            "split or decimate it"
        )
    if b"\x00" in head and not head.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise LogError(f"{path}: a binary file, not a text table")
    if (problem := _decode_problem(path, head)) is not None:
        raise LogError(problem)
    if head.startswith(b"\xef\xbb\xbf"):
        head = head[3:]
    return head


@dataclasses.dataclass(frozen=True)
class Table:
    """A data file's layout: `names` of its columns (`"1"`, `"2"`, ... for a table
    with no header), where the numbers start, how they are separated."""

    path: pathlib.Path
    names: tuple[str, ...]
    kind: str  # "csv", "numbers" (no header) or "asc"
    skip_lines: int  # lines before the first row of numbers
    skip_bytes: int
    delimiter: str | None  # "," or None (blanks)

    @property
    def numbered(self) -> bool:
        return self.kind == "numbers"

    def listing(self) -> str:
        if self.numbered:
            return f"numbered 1 to {len(self.names)}, the file has no header"
        return ", ".join(self.names)

    def read(self, columns=None) -> dict[str, np.ndarray]:
        """The named columns (default: every numeric column) as float64 arrays."""
        wanted = list(self.names) if columns is None else list(dict.fromkeys(columns))
        for name in wanted:
            if self.names.count(name) > 1:
                raise LogError(
                    f"{self.path}: column {name!r} appears more than once in the header"
                )
        index = [self.names.index(n) for n in wanted]
        data = None
        try:
            if self.delimiter == ",":
                data = read_numeric_csv(
                    self.path, self.skip_bytes, len(self.names), index, self.skip_lines
                )
            if data is None:
                return self._read_carefully(wanted, index, drop_text=columns is None)
        except OSError as e:
            raise LogError(
                f"{self.path}: cannot read the file ({e.strerror})"
            ) from None
        except UnicodeDecodeError as e:
            raise LogError(
                f"{self.path}: not UTF-8 text (a byte {e.object[e.start]:#04x} past "
                "the header; a Latin-1 or Windows-1252 file?): save it as UTF-8"
            ) from None
        if len(data) == 0:
            raise LogError(f"{self.path}: no rows of data after the header")
        return {n: data[:, k] for k, n in enumerate(wanted)}

    def _rows(self, f):
        if self.delimiter == ",":
            return csv.reader(f)
        return (line.split() for line in f)

    def _read_carefully(self, wanted, index, drop_text):
        """Streams the file row by row: the first problem in a wanted column is one
        `LogError` naming the line, column and value; with `drop_text`, a column
        whose first value is text is dropped instead (a comment column)."""
        values = [array.array("d") for _ in wanted]
        text = set()
        width = len(self.names)
        first = self.skip_lines + 1
        with open(self.path, encoding="utf-8-sig", newline="") as f:
            for _ in range(self.skip_lines):
                f.readline()
            for line_no, row in enumerate(self._rows(f), start=first):
                if not any(cell.strip() for cell in row):
                    continue
                if len(row) != width:
                    raise LogError(
                        f"{self.path}: line {line_no} has {len(row)} values, the "
                        f"{'first line' if self.numbered else 'header'} {width}"
                    )
                for k, (name, j) in enumerate(zip(wanted, index, strict=True)):
                    if k in text:
                        continue
                    cell = row[j]
                    if NUMBER.fullmatch(cell):
                        values[k].append(float(cell))
                        continue
                    if drop_text and not values[k]:
                        text.add(k)
                        continue
                    raise LogError(
                        f"{self.path}: line {line_no}, column {name!r}: "
                        + _not_a_number(cell)
                    )
        if not any(len(v) for v in values):
            raise LogError(f"{self.path}: no rows of data after the header")
        return {
            n: np.frombuffer(v, float)
            for k, (n, v) in enumerate(zip(wanted, values, strict=True))
            if k not in text
        }


def _not_a_number(cell: str) -> str:
    shown = cell.strip()
    if not shown:
        return "the cell is empty"
    if _DECIMAL_COMMA.match(shown):
        return (
            f"{shown!r} has a decimal comma; write numbers with a decimal point "
            "(e.g. 2.5, not 2,5)"
        )
    return f"{shown!r} is not a number" + (
        " (write plain digits, no '_' separators)" if "_" in shown else ""
    )


def _decimal_comma_line(line: str) -> bool:
    """Whether `line` is numbers with decimal commas separated by blanks, ';' or
    tabs ("0,00;-2,5" or "0,00 -2,5"), which a comma-separated reader would split."""
    cells = [c for c in re.split(r"[;\s]+", line.strip()) if c]
    return (len(cells) > 1 or ";" in line) and any(
        _DECIMAL_COMMA.match(c) for c in cells
    )


def open_table(path: str | os.PathLike) -> Table:
    """The layout of a data file (its header), checking it is readable UTF-8 text.

    **Raises:** [`LogError`][] naming the file: missing, a folder, binary, not UTF-8,
    empty, decimal commas, no header an `.asc` file needs.
    """
    path = pathlib.Path(path)
    if path.suffix.lower() in MATRIX_SUFFIXES:
        from ._matfile import MatrixFileTable

        return MatrixFileTable.open(path)  # type: ignore[return-value]
    head = _check_file(path)
    text = head.decode("utf-8", errors="ignore")
    lines = text.splitlines(keepends=True)
    if len(head) == _HEAD_BYTES and lines:
        lines = lines[:-1]  # the last line may be cut by the block read
    skip, skip_bytes = 0, len(head) - len(head.lstrip(b"\xef\xbb\xbf"))
    for line in lines:
        if line.strip():
            break
        skip += 1
        skip_bytes += len(line.encode())
    else:
        raise LogError(f"{path}: the file is empty")
    first = lines[skip]
    data_lines = [ln for ln in lines[skip:] if ln.strip()]
    if any(_decimal_comma_line(ln) for ln in data_lines[:3]):
        raise LogError(
            f"{path}: the numbers have decimal commas (line {skip + 1}: "
            f"{first.strip()[:40]!r}); save the table with decimal points and ',' "
            "or blanks between columns"
        )
    if ";" in first and "," not in first:
        raise LogError(
            f"{path}: the columns are separated by ';'; save the table with ',' "
            "between columns and decimal points"
        )
    cells = first.replace(",", " ").split()
    if all(NUMBER.fullmatch(c) for c in cells):
        delimiter = "," if "," in first else None
        width = len(first.split(",")) if delimiter else len(cells)
        return Table(
            path,
            tuple(str(k + 1) for k in range(width)),
            "numbers",
            skip,
            skip_bytes,
            delimiter,
        )
    if path.suffix.lower() == ".asc" or "," not in first:
        return _asc_table(path, lines, skip)
    names = [n.strip() for n in next(csv.reader([first]))]
    return Table(
        path, tuple(names), "csv", skip + 1, skip_bytes + len(first.encode()), ","
    )


def _asc_table(path, lines, skip) -> Table:
    for i, line in enumerate(lines[skip:], start=skip):
        row = line.split()
        if row and row[0] == "T":
            # the names, then a row of units
            return Table(path, tuple(row), "asc", i + 2, -1, None)
    raise LogError(
        f"{path}: no header row starting with 'T' (the time channel), and no "
        "commas: not a CSV, an .asc column file, or a table of numbers"
    )
