"""The numbers of a flight computer's CSV file, fast where the file is clean and
exact about where it is not.

A file is read once for all the columns its streams need: one pass over its bytes
counts every line's cells, then numpy's C parser reads the wanted columns (a million
rows of a 67-column AltOS export in about 2 CPU-s); a file that fails the count or
the parser goes through a line-by-line pass that names the first bad cell, or drops
a block of corrupt rows at the end of the file (a flight computer losing power while
writing) with a message.
"""

import csv
import datetime
import math
import pathlib
import re
import warnings

import numpy as np

from .._errors import LogError
from ._fastcsv import marks_per_line


# ASCII decimal with optional exponent, nan, inf (what a flight computer writes);
# Python's float() also takes "1_000" and non-ASCII digits, which are not data.
_NUMBER = re.compile(
    r"\s*[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf|infinity)\s*",
    re.IGNORECASE | re.ASCII,
)
_CLOCK = re.compile(
    r"\s*(?:(\d{4})-(\d\d)-(\d\d)[T ])?(\d{1,2}):(\d\d):(\d\d(?:\.\d*)?)"
    r"\s*(Z|[+-]\d\d:?\d\d)?\s*",
    re.ASCII,
)
_SEPARATORS = (",", ";", "\t")
_SNIFF_LINES = 400  # a preamble longer than this needs "header_row" in the map
_ENCODINGS = ("utf-8-sig", "cp1252", "latin-1")  # Windows exports write cp1252
_EPOCH = datetime.date(1970, 1, 1).toordinal()
_SPOKEN = {"utf-8-sig": "UTF-8", "cp1252": "Windows-1252", "latin-1": "Latin-1"}


class Header:
    """A CSV file's column names, where its data start, its separator.

    The header is the first non-blank line when the data follow it (after any
    comment lines starting with '#'); otherwise the layout is found from the data:
    the first two rows of numbers with as many cells as each other (cells split at
    ',', ';', tab or whitespace; with ';' or tab a decimal comma is read as a
    point), the header the top one of the rows of as many cells directly above them
    (a preamble before it, a blank row or a summary block, is skipped), and any rows
    between header and data unit rows (`,(deg),(m),(m/s)`: each column's unit). A
    column map may say where the header is (`header_row`, the line's number from
    1), the separator (`delimiter`: ",", ";", "tab" or "whitespace") and the
    decimal mark (`decimal`: "." or ",")."""

    def __init__(
        self,
        path: pathlib.Path,
        header_row: int | None = None,
        delimiter: str | None = None,
        decimal: str | None = None,
    ):
        self.path = path
        self.units: list[str] = []
        lines, self.encoding = _first_lines(path, _SNIFF_LINES + (header_row or 0))
        # only ASCII in the sniffed lines: a byte further on that is not UTF-8 makes
        # the file Windows-1252, as it would be had the byte come early
        self.ascii = all(line.isascii() for line in lines)
        try:
            self._sniff(lines, header_row, delimiter, decimal)
        except csv.Error as e:
            limit = csv.field_size_limit()
            k = next((k for k, line in enumerate(lines) if len(line) > limit), None)
            if k is None:  # pragma: no cover: the csv module's other errors
                raise LogError(f"{path}: not a readable CSV file ({e})") from None
            raise LogError(
                f"{path}: line {k + 1}: a line of {len(lines[k]):,} characters "
                f"({_shown(lines[k])}), not a row of cells ({e})"
            ) from None

    def _sniff(self, lines, header_row, delimiter, decimal) -> None:
        path = self.path
        if not any(line.strip() for line in lines):
            raise LogError(f"{path}: the file is empty")
        forced = _delimiter(delimiter, path)
        self.decimal = decimal or "."
        if header_row is not None:
            if not 1 <= header_row <= len(lines) or not lines[header_row - 1].strip():
                raise LogError(
                    f"{path}: header_row {header_row}: "
                    + (
                        "that line is blank"
                        if 1 <= header_row <= len(lines)
                        else f"the file's first {len(lines)} lines do not reach it"
                    )
                )
            h = header_row - 1
            line = lines[h]
            self.sep = forced if forced is not None else _best_sep(line)
            data = _data_start(lines, h + 1, self.sep, decimal)
            if decimal is None and data is not None:
                self.decimal = data[2]
            start = data[0] if data is not None else h + 1
            self._set(lines, h, start)
            return
        first = next(k for k, line in enumerate(lines) if line.strip())
        line = lines[first]
        sep = forced if forced is not None else _best_sep(line)
        if forced is None and line.count(sep) == 0 and len(line.split()) > 1:
            sep = None  # maybe whitespace-separated; decided by the data below
        width = len(_split(line, sep)) if sep is not None else 0
        data = _data_start(lines, first + 1, sep, decimal) if sep else None
        if (
            data is not None
            and not _numeric(_split(line, sep), data[2])
            and all(
                len(_split(lines[k], sep)) == width
                and not lines[k].lstrip().startswith("#")
                for k in range(first + 1, data[0])
                if lines[k].strip()
            )
        ):
            # the header on the first line, the data right after (or after rows of
            # units): every layout the readers knew before
            self.sep, self.decimal = sep, decimal or data[2]
            self._set(lines, first, data[0])
            return
        found = _find_layout(lines, forced, decimal)
        if found is None:
            if sep is not None and _numeric(_split(line, sep), decimal or "."):
                raise LogError(
                    f"{path}: the first line is numbers, not a header of column "
                    "names; give the columns by number in a column map (from 1)"
                )
            if sep is None or line.count(sep) == 0:
                raise LogError(
                    f"{path}: the first line has no ',', ';' or tab: not a CSV file "
                    "with a header row"
                )
            # a header with no readable data below it (past rows of units): the
            # careful reader names the first bad cell
            self.sep, self.decimal = sep, decimal or "."
            k = first + 1
            while k < len(lines) and _units_row(lines[k], sep, width):
                k += 1
            self._set(lines, first, k)
            return
        start, self.sep, self.decimal, width = found
        # the header: the top of the rows of names directly above the data (no cell
        # a number; the rows under it are units), past comments between them
        h = start - 1
        while h >= 0 and _blank(lines[h], self.sep):
            h -= 1
        block = []
        while h >= 0 and not _blank(lines[h], self.sep):
            cells = _split(lines[h], self.sep)
            if len(cells) != width and lines[h].lstrip().startswith("#"):
                h -= 1  # a comment between header and data (a simulator's event)
                continue
            if (
                len(cells) != width
                or any(_NUMBER.fullmatch(c) for c in cells)
                or 2 * sum(not c.strip() for c in cells) > width
            ):
                break  # numbers, or a title padded with empty cells (a spreadsheet)
            block.append(h)
            h -= 1
        if block:
            self._set(lines, block[-1], start)
            return
        head = _split(line, self.sep)
        if (
            len(head) == width
            and not any(_NUMBER.fullmatch(c) for c in head)
            and all(
                len(_split(lines[k], self.sep)) == width
                for k in range(first + 1, start)
                if lines[k].strip()
            )
        ):
            # the header on the first line and rows of its width right below it
            # that are not all numbers: bad data rows, which the careful reader names
            k = first + 1
            while k < start and _units_row(lines[k], self.sep, width):
                k += 1
            self._set(lines, first, k)
            return
        raise LogError(
            f"{path}: no header row of {width} column names above the data "
            f"(line {start + 1}); give the columns by number in a column map "
            '(from 1), or the header\'s line as "header_row"'
        )

    def _set(self, lines: list[str], h: int, start: int) -> None:
        cells = _split(lines[h], self.sep)
        names = _names(cells)
        if names and len(names) > 1:
            # 'Data: (Time, Altitude, ..., Voltage)': a label and a parenthesised list
            m = re.match(r"^[A-Za-z ]*:\s*\((.*)$", names[0])
            if m and names[-1].endswith(")"):
                names[0], names[-1] = m.group(1).strip(), names[-1][:-1].strip()
        # a name written twice (AltOS: baro and GPS 'altitude') gets ' (2)', ' (3)'
        seen: dict[str, int] = {}
        self.names = []
        self.raw_names = names
        for n in names:
            seen[n] = seen.get(n, 0) + 1
            self.names.append(n if seen[n] == 1 else f"{n} ({seen[n]})")
        units = [""] * len(self.names)
        for k in range(h + 1, start):
            if lines[k].strip() and not lines[k].lstrip().startswith("#"):
                row = _split(lines[k], self.sep)
                if _names(row) == names:
                    continue  # the header written twice (a logger restarted)
                units = [
                    (u or row[j].strip().strip("()[]").strip()) if j < len(row) else u
                    for j, u in enumerate(units)
                ]
        self.units = units
        self.header_line = h + 1
        self.skip = start
        if start < len(lines):
            row = _split(lines[start], self.sep)
            extra = [c for c in row[len(self.names) :] if c.strip()]
            if extra and _numeric(row, self.decimal):
                raise LogError(
                    f"{self.path}: the header (line {h + 1}) has {len(self.names)} "
                    f"names, the data from line {start + 1} have {len(row)} cells "
                    f"({lines[start].strip()[:60]!r}): a column without a name, "
                    "or decimal commas in a comma-separated file, which cannot be "
                    "told from its separators (export it with ';' or quoted cells)"
                )

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

    def split(self, line: str) -> list[str]:
        """The cells of one data line."""
        return _split(line, self.sep)


def _first_lines(
    path: pathlib.Path, count: int = _SNIFF_LINES
) -> tuple[list[str], str]:
    """The file's first `count` lines (without line ends) and the encoding that
    reads them."""
    for encoding in _ENCODINGS:
        try:
            with open(path, encoding=encoding, newline="") as f:
                lines = []
                for line in f:
                    lines.append(line.rstrip("\r\n"))
                    if len(lines) >= count:
                        break
            nul = next((k for k, line in enumerate(lines) if "\x00" in line), None)
            if encoding != "utf-8-sig" and nul is not None:
                raise LogError(
                    f"{path}: line {nul + 1}: NUL bytes, in a file that is not UTF-8: "
                    "not a text file, or a block the logger never wrote (the power "
                    "lost, or a card fault)"
                )
            if encoding != "utf-8-sig" and lines:
                # a UTF-8 byte-order mark on a file whose text is not UTF-8
                lines[0] = lines[0].removeprefix("\u00ef\u00bb\u00bf")
            return lines, encoding
        except OSError as e:
            raise LogError(f"{path}: cannot read the file ({e.strerror})") from None
        except UnicodeDecodeError:
            continue
    raise LogError(f"{path}: not a UTF-8 text file")  # pragma: no cover: latin-1


def _delimiter(delimiter: str | None, path) -> str | None:
    names = {",": ",", ";": ";", "tab": "\t", "\t": "\t", "whitespace": " "}
    if delimiter is None:
        return None
    if delimiter not in names:
        raise LogError(
            f"{path}: delimiter {delimiter!r}: give ',', ';', 'tab' or 'whitespace'"
        )
    return names[delimiter]


def _best_sep(line: str) -> str:
    return max(_SEPARATORS, key=line.count)


def _blank(line: str, sep: str | None) -> bool:
    """No text, or only empty cells (a spreadsheet pads blank rows: `,,,`)."""
    return not line.strip() or not any(c.strip() for c in _split(line, sep))


def _split(line: str, sep: str | None) -> list[str]:
    if sep == " " or sep is None:
        return line.split()
    return next(csv.reader([line], delimiter=sep))


def _numeric(cells: list[str], decimal: str) -> bool:
    """All cells numbers (or clock times) or empty, at least one not empty."""
    cells = [c.strip() for c in cells]
    if decimal == ",":
        cells = [c.replace(",", ".") for c in cells]
    return any(cells) and all(
        not c or _NUMBER.fullmatch(c) or _CLOCK.fullmatch(c) for c in cells
    )


def _units_row(line: str, sep: str | None, width: int) -> bool:
    """A row of units under the header: as many cells, each empty or a short word
    (`(deg)`, `m/s^2`, `°C`), no number among them."""
    cells = [c.strip() for c in _split(line, sep)]
    return (
        len(cells) == width
        and any(cells)
        and all(
            not c
            or (
                len(c) <= 12
                and not _NUMBER.fullmatch(c)
                and re.search(r"[^\W\d_]|%", c) is not None
            )
            for c in cells
        )
    )


def _data_start(lines, begin, sep, decimal):
    """(line index, separator, decimal, width) of the data that start at or after
    `begin` with this separator: the first of two rows of numbers with as many
    cells, past at most two rows of units; None if other rows come first."""
    rows = [
        k
        for k in range(begin, len(lines))
        if lines[k].strip() and not lines[k].lstrip().startswith("#")
    ]
    decimals = [decimal] if decimal else ([".", ","] if sep != "," else ["."])
    for n, k in enumerate(rows[:3]):
        cells = _split(lines[k], sep)
        dec = next((d for d in decimals if _numeric(cells, d)), None)
        if dec is None:
            if _units_row(lines[k], sep, len(cells)) and n < 2:
                continue
            return None
        nxt = _split(lines[rows[n + 1]], sep) if n + 1 < len(rows) else cells
        if len(nxt) == len(cells) and _numeric(nxt, dec):
            if decimal is None:
                dec = _later_decimal(lines, rows[n:], sep, dec)
            return k, sep, dec, len(cells)
        return None
    return None


def _later_decimal(lines, rows, sep, dec):
    """`","` where the rows after the first two of whole numbers (a zeroed pad, a
    spreadsheet writing 0 for 0,00) read as numbers with a decimal comma alone."""
    if dec != "." or sep == ",":
        return dec
    for k in rows[:_SNIFF_LINES]:
        cells = _split(lines[k], sep)
        if not _numeric(cells, ".") and _numeric(cells, ","):
            return ","
    return dec


def _find_layout(lines, forced, decimal):
    """The first two rows of numbers, as (line index, separator, decimal, width):
    the separator that splits them into the most cells."""
    seps = [forced] if forced is not None else [",", ";", "\t", " "]
    rows = [
        k
        for k, line in enumerate(lines)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    for a, b in zip(rows, rows[1:], strict=False):
        best = None
        for sep in seps:
            decimals = (
                [decimal]
                if decimal
                else ([".", ","] if sep in (";", "\t", " ") else ["."])
            )
            ca, cb = _split(lines[a], sep), _split(lines[b], sep)
            if len(ca) != len(cb) or len(ca) < 2:
                continue
            for dec in decimals:
                if _numeric(ca, dec) and _numeric(cb, dec):
                    if decimal is None:
                        dec = _later_decimal(
                            lines, [r for r in rows if r >= a], sep, dec
                        )
                    if best is None or len(ca) > best[3]:
                        best = (a, sep, dec, len(ca))
                    break
        if best is not None:
            return best
    return None


def read_columns(
    header: Header, columns: list[int], clocks: frozenset[int] = frozenset()
) -> tuple[np.ndarray, list[str]]:
    """The float values of `columns` (0-based), shape `(rows, len(columns))`; empty
    cells are nan. Columns in `clocks` (time columns) may hold clock times
    (`12:07:53.25`, `2024-04-20T12:07:53.25Z`), read as seconds (since midnight, or
    since 1970 with a date). Returns the array and messages about rows dropped or
    clock times read."""
    path = header.path
    columns = sorted(set(columns))
    notes: list[str] = []
    if header.decimal == "," and header.sep == ",":
        # decimal commas in quoted cells: only the careful reader splits them right
        data, more = _read_carefully(header, columns, clocks)
        return data, notes + more
    try:
        if _regular(header):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # "input contained no data": below
                data = np.loadtxt(
                    path if header.decimal == "." else _points(header),
                    delimiter=None if header.sep == " " else header.sep,
                    skiprows=header.skip,
                    usecols=columns,
                    dtype=float,
                    comments="#",
                    quotechar='"',
                    ndmin=2,
                    encoding=header.encoding,
                )
            if len(data):
                return data, notes
    except UnicodeDecodeError:
        if header.encoding == "utf-8-sig" and header.ascii:
            notes.append(_read_as_cp1252(header))
            data, more = read_columns(header, columns, clocks)
            return data, notes + more
    except (ValueError, IndexError):
        pass
    except OSError as e:
        raise LogError(f"{path}: cannot read the file ({e.strerror})") from None
    data, more = _read_carefully(header, columns, clocks)
    return data, notes + more


def _read_as_cp1252(header: Header) -> str:
    """Switch `header` to Windows-1252 (its first lines were ASCII, a later byte is
    not UTF-8) and say so."""
    header.encoding = "cp1252"
    return (
        f"{header.path.name}: read as Windows-1252 text (a byte past the first "
        f"{_SNIFF_LINES} lines is not UTF-8)"
    )


_NEWLINE = ord("\n")
_BLANKS = np.frombuffer(b" \t\r\n\v\f", np.uint8)


def _regular(header: Header) -> bool:
    """Whether every data line has the header's number of cells (NumPy's reader
    reads the asked-for columns of a row with more cells without a word: a decimal
    comma in a comma-separated file, two rows run together), its decimal mark and
    no NUL byte; blank lines and comments aside. Empty cells past the header's width
    (a logger that ends every row with its separator) and separators inside quoted
    cells do not count. Read in blocks of 8 MiB."""
    width = len(header.names)
    with open(header.path, "rb") as f:
        for _ in range(header.skip):
            f.readline()
        rest = b""
        while True:
            chunk = f.read(8 * 2**20)
            block = rest + chunk
            if not chunk:
                block += b"\n"
            cut = block.rfind(b"\n") + 1
            block, rest = block[:cut], block[cut:]
            if b"\x00" in block:
                return False
            if header.decimal == "," and b"." in block:
                return False  # a point where commas are the decimal mark
            shape = _fits(block, header.sep, width)
            if shape is None:
                return False
            ends, fits = shape
            starts = np.concatenate([[0], ends[:-1] + 1])
            for k in np.flatnonzero(~fits):
                line = block[starts[k] : ends[k]].strip()
                if line and not line.startswith(b"#"):
                    return False
            if not chunk:
                return True


_QUOTE = ord('"')


def _fits(block: bytes, sep: str, width: int):
    """Each line's end offset in `block` (whole lines) and whether it has `width`
    cells; a line with more whose extra cells are all empty fits. None where a line's
    quotes are unbalanced."""
    raw = np.frombuffer(block, np.uint8)
    ends = np.flatnonzero(raw == _NEWLINE)
    if sep == " ":
        # cells separated by runs of blanks: count where each cell starts
        blank = np.isin(raw, _BLANKS)
        marks = np.flatnonzero(~blank & np.concatenate([[True], blank[:-1]]))
        return ends, marks_per_line(marks, ends) == width
    is_sep = raw == ord(sep)
    if b'"' in block:
        quote = raw == _QUOTE
        if np.any(marks_per_line(np.flatnonzero(quote), ends) % 2):
            return None
        is_sep &= np.cumsum(quote) % 2 == 0  # outside quoted cells
    marks = np.flatnonzero(is_sep)
    cells = marks_per_line(marks, ends) + 1
    wide = cells > width
    if not np.any(wide):
        return ends, cells == width
    # the separators after a line's last byte that holds anything end empty cells
    content = np.flatnonzero(~np.isin(raw, _BLANKS) & ~is_sep)
    last = np.searchsorted(content, ends) - 1
    starts = np.concatenate([[0], ends[:-1] + 1])
    last_at = np.where(last >= 0, content[np.maximum(last, 0)], -1)
    last_at = np.maximum(last_at, starts - 1)  # a line of separators only
    trailing = np.searchsorted(marks, ends) - np.searchsorted(marks, last_at, "right")
    return ends, (cells == width) | (wide & (cells - trailing <= width))


def _points(header: Header):
    """The file's lines with the decimal comma as a point (the separator is not a
    comma), for NumPy's reader."""
    with open(header.path, encoding=header.encoding, newline="") as f:
        for line in f:
            yield line.replace(",", ".")


def _names(cells: list[str]) -> list[str]:
    """A row's cells as column names: blanks and a leading `#` (a commented header)
    stripped."""
    return [c.strip().lstrip("#").strip() for c in cells]


def clock_seconds(cell: str) -> float | None:
    """A clock time as seconds: `hh:mm:ss(.f)` since midnight; with a date
    (`YYYY-MM-DD` and `T` or a space before it) since 1970-01-01 UTC, less a
    `+hh:mm` offset. None if the cell is not one (minutes past 59, say)."""
    m = _CLOCK.fullmatch(cell)
    if m is None:
        return None
    year, month, day, hh, mm, ss, zone = m.groups()
    if int(hh) > 23 or int(mm) > 59 or float(ss) >= 61.0:  # 60: a leap second
        return None
    seconds = int(hh) * 3600 + int(mm) * 60 + float(ss)
    if year is not None:
        try:
            days = datetime.date(int(year), int(month), int(day)).toordinal()
        except ValueError:
            return None
        seconds += (days - _EPOCH) * 86400
    if zone and zone != "Z":
        sign = -1 if zone[0] == "+" else 1
        seconds += sign * (int(zone[1:3]) * 3600 + int(zone[-2:]) * 60)
    return seconds


def _decoded(raw: bytes, header: Header, notes: list[str]) -> str:
    """A line's bytes as text in the file's encoding; Windows-1252 from here on if
    the file's first lines were ASCII and these are not UTF-8 (with a note). Raises
    `UnicodeDecodeError` for bytes neither reads."""
    try:
        return raw.decode(header.encoding)
    except UnicodeDecodeError:
        if not (header.encoding == "utf-8-sig" and header.ascii):
            raise
    notes.append(_read_as_cp1252(header))
    return raw.decode(header.encoding)


def _undecodable(header: Header, r: int, raw: bytes, e: UnicodeDecodeError) -> str:
    """The error line for row `r`'s bytes `raw` that the file's encoding cannot read."""
    byte = f"byte 0x{raw[e.start]:02x}"
    if header.ascii:  # the encoding was this reader's guess from ASCII lines
        return f"{header.path}: row {r}: {byte} is neither UTF-8 nor Windows-1252 text"
    spoken = _SPOKEN.get(header.encoding, header.encoding)
    return (
        f"{header.path}: row {r}: {byte} is not {spoken} text like the rows before it"
    )


# A number written with a decimal comma ("-2,5", "1,5e3").
_DECIMAL_COMMA = re.compile(r"\s*[+-]?\d*,\d+(?:[eE][+-]?\d+)?\s*", re.ASCII)
_SHOWN = 40  # characters of a bad cell or row shown in a message


def _shown(text: str) -> str:
    text = text.strip()
    return repr(text if len(text) <= _SHOWN else text[:_SHOWN] + "...")


def _problem(
    header: Header,
    r: int,
    text: str,
    line: list[str],
    raw: list[str],
    columns: list[int],
    clocks: frozenset[int],
):
    """Why data row `r` (its `line` of cells, decimal marks made points, and the
    `raw` cells) cannot be read, as the text after the file's name; None if it can
    (then `line` is read)."""
    width = len(header.names)
    if _names(raw) == header.raw_names:
        return (
            f"row {r} repeats the header (line {header.header_line}): the logger "
            "restarted; split the file there, one file per run"
        )
    filled = [c.strip() for c in raw if c.strip()]
    if len(filled) > 1 and not any(
        _NUMBER.fullmatch(c) or _CLOCK.fullmatch(c) or _DECIMAL_COMMA.fullmatch(c)
        for c in filled
    ):
        return (
            f"row {r} is words, not numbers ({_shown(text)}): another header (the "
            "logger restarted with other columns?); split the file there"
        )
    if len(line) > width and any(c.strip() for c in line[width:]):
        extra = next(c for c in raw[width:] if c.strip())
        return (
            f"row {r} has {len(line)} cells, the header {width} (an extra cell "
            f"{_shown(extra)}): two rows run together (a line end lost)"
            + (
                ", or a decimal comma in a comma-separated file"
                if header.sep == ","
                else ""
            )
        )
    if len(line) < width and len(line) <= max(columns):
        return (
            f"row {r} has {len(line)} cell{'' if len(line) == 1 else 's'}, the header {width}: it ends before "
            f"column {header.names[len(line)]!r}"
        )
    if header.decimal == ",":
        for j in columns:
            if "." in raw[j] and not (j in clocks and _CLOCK.fullmatch(raw[j])):
                return (
                    f"column {header.names[j]!r}, row {r}: {_shown(raw[j])} has a "
                    "decimal point in a file whose numbers have decimal commas (a "
                    "thousands separator, or rows from another program?); write "
                    "every number with the one decimal mark"
                )
    for j in columns:
        cell = line[j].strip()
        if not cell or _NUMBER.fullmatch(cell):
            continue
        if j in clocks and clock_seconds(cell) is not None:
            continue
        if _word(cell):
            continue  # read as an empty cell, with a message
        where = f"column {header.names[j]!r}, row {r}: {_shown(raw[j])}"
        if j in clocks and _CLOCK.fullmatch(cell):
            return (
                f"{where} is not a time of day (hours 0-23, minutes and seconds 0-59)"
            )
        if header.decimal == "." and _DECIMAL_COMMA.fullmatch(cell):
            return (
                f"{where} has a decimal comma; give the file's stream "
                '"decimal": "," in the column map, or export it with decimal points'
            )
        return f"{where} is not a number"
    return None


def _word(cell: str) -> bool:
    """A cell with no digit in it (`-`, `Drogue`, `n/a`): a logger's word where a
    number would be (an event name moved into another column), not a number
    mistyped (`12O.5`)."""
    return not any(c.isdigit() for c in cell)


def _read_carefully(
    header: Header, columns: list[int], clocks: frozenset[int] = frozenset()
):
    """The slow path: every cell checked, the first bad one named; a trailing run of
    unreadable rows (a write cut short) dropped with a message."""
    path = header.path
    rows: list[list[float]] = []
    numbers: list[int] = []  # each read row's number
    bad: list[tuple[int, str]] = []  # (row, why) of unreadable rows
    clocked: set[int] = set()
    words: dict[int, list] = {}  # column: [count, first row, first word]
    notes: list[str] = []
    with open(path, "rb") as f:
        for _ in range(header.skip):
            f.readline()
        r = 0  # rows counted from 1 for the first data row, comments and blanks aside
        for data in f:
            try:
                text = _decoded(data, header, notes)
            except UnicodeDecodeError as e:
                raise LogError(_undecodable(header, r + 1, data, e)) from None
            if text.lstrip().startswith("#"):
                continue  # a comment (a simulator's event line)
            text = text.rstrip("\r\n")
            if "\x00" in text:
                r += 1
                problem = (
                    f"row {r}: NUL bytes (a block the logger never wrote: the power "
                    "lost, or a card fault)"
                )
                bad.append((r, problem))
                continue
            try:
                raw = header.split(text)
            except csv.Error as e:
                r += 1
                problem = (
                    f"row {r}: a line of {len(text):,} characters ({_shown(text)}), "
                    f"not a row of cells ({e})"
                )
            else:
                line = (
                    [c.replace(",", ".") for c in raw] if header.decimal == "," else raw
                )
                if not any(c.strip() for c in line):
                    continue
                r += 1
                problem = _problem(header, r, text, line, raw, columns, clocks)
            if problem is None and bad:
                # an unreadable row followed by readable ones: not a cut-off end
                raise LogError(f"{path}: {bad[0][1]}")
            if problem is not None:
                bad.append((r, problem))
                continue
            values = []
            for j in columns:
                cell = line[j].strip()
                if not cell:
                    values.append(math.nan)
                elif _NUMBER.fullmatch(cell):
                    values.append(float(cell))
                elif j in clocks and clock_seconds(cell) is not None:
                    values.append(clock_seconds(cell))
                    clocked.add(j)
                else:  # a word (`_problem` let no other cell through)
                    values.append(math.nan)
                    words.setdefault(j, [0, r, raw[j]])[0] += 1
            rows.append(values)
            numbers.append(r)
    if not rows:
        if bad:
            raise LogError(f"{path}: {bad[0][1]}")
        units = " and units" if header.skip > header.header_line else ""
        raise LogError(
            f"{path}: the file has a header{units} (line {header.header_line}) but "
            "no data rows"
        )
    messages = notes + [
        f"{path.name}: column {header.names[j]!r}: clock times read as seconds"
        for j in sorted(clocked)
    ]
    messages += [
        f"{path.name}: column {header.names[j]!r}: {n} cell(s) hold a word, not a "
        f"number ({_shown(w)} at row {r} first; the logger wrote another column's "
        "text there?), read as empty"
        for j, (n, r, w) in sorted(words.items())
    ]
    if bad:
        messages.append(
            f"{path.name}: dropped the last {len(bad)} row(s) from row {bad[0][0]} "
            f"on, a write cut short: {bad[0][1]}"
        )
    out = np.asarray(rows, float).reshape(-1, len(columns))
    for j in sorted(clocked):
        v = out[:, columns.index(j)]
        if np.nanmax(v) < 86400.0:  # times of day without a date
            # a log that runs past midnight: its clock starts again at 0
            wraps = np.concatenate([[0], np.cumsum(np.diff(v) < -43200.0)])
            if wraps[-1]:
                v += 86400.0 * wraps
                messages.append(
                    f"{path.name}: column {header.names[j]!r}: the clock passes "
                    "midnight; a day added to the times after it"
                )
        jump = np.flatnonzero(np.abs(np.diff(v)) >= 43200.0)
        if jump.size:
            k = int(jump[0]) + 1
            raise LogError(
                f"{path}: column {header.names[j]!r}, row {numbers[k]}: the clock "
                f"jumps {(v[k] - v[k - 1]) / 3600:+.1f} h from row {numbers[k - 1]} "
                "(a date or clock reset mid-flight); a flight's log runs minutes, "
                "correct the times or split the file there"
            )
    return out, messages
