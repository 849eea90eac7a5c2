"""The broken files a user hits on the rocket-log reader's layout features (a units
row; semicolons with decimal commas in Windows-1252; clock times), each written from
the simulated flight of tests/rocket_layouts.py and damaged as a logger, a card or a
spreadsheet damages it: either one error line naming the file and the row (and the
column and cell where there is one), or the channels of the undamaged rows against
the simulation within the layout's rounding, with a message where rows were dropped
or the file read otherwise than it says."""

import re

import numpy as np
import pytest

from diffpegasus import LogError, read_rocket_log

from .rocket_layouts import flight, LAYOUTS


TRUTH = flight()
U, X, F = "units_row", "excel_semicolon", "flysight_track"


def _enc(layout):
    return "cp1252" if layout == X else "utf-8"


def _end(layout):
    return "\r\n" if layout == X else "\n"


def _edit(fn):
    """A damage written on the file's lines (line ends and encoding kept)."""

    def damage(path, layout):
        lines = path.read_bytes().decode(_enc(layout)).splitlines()
        end = _end(layout)
        path.write_bytes((end.join(fn(lines)) + end).encode(_enc(layout)))

    return damage


def _bytes(fn):
    def damage(path, layout):
        path.write_bytes(fn(path.read_bytes()))

    return damage


def _byte_in(k, byte):
    """A byte put into line `k` (from 0) after its 20th byte."""

    def put(b):
        lines = b.split(b"\n")
        lines[k] = lines[k][:20] + byte + lines[k][20:]
        return b"\n".join(lines)

    return _bytes(put)


def _swap(k, fn):
    return _edit(lambda lines: lines[:k] + [fn(lines[k])] + lines[k + 1 :])


def _quoted(lines):
    return [lines[0].replace(";", ",")] + [
        ",".join(f'"{c}"' for c in ln.split(";")) for ln in lines[1:]
    ]


def _thousands(line):
    cells = line.split(";")
    whole, frac = cells[1].split(",")
    cells[1] = f"{whole[:-3]}.{whole[-3:]},{frac}"
    return ";".join(cells)


def _comma_in(line):
    cells = line.split(",")
    return ",".join([*cells[:2], cells[2].replace(".", ","), *cells[3:]])


# (id, layout, damage, the error's pattern after the file's name)
REFUSED = [
    (
        "header only",
        U,
        _edit(lambda x: x[:1]),
        r"the file has a header \(line 1\) but no data rows",
    ),
    (
        "header only, semicolons",
        X,
        _edit(lambda x: x[:1]),
        r"the file has a header \(line 1\) but no data rows",
    ),
    (
        "units row, no data",
        U,
        _edit(lambda x: x[:2]),
        r"the file has a header and units \(line 1\) but no data rows",
    ),
    (
        "decimal point among decimal commas",
        X,
        _swap(200, lambda s: s.replace(",", ".")),
        r"column 'Zeit \[s\]', row 200: '3\.98' has a decimal point in a file whose "
        r"numbers have decimal commas",
    ),
    (
        "thousands separator",
        X,
        _swap(900, _thousands),
        r"column 'Höhe \[m\]', row 900: '2\.\d{3},\d\d' has a decimal point",
    ),
    (
        "clock time backwards",
        F,
        _swap(600, lambda s: s.replace("04:20:", "04:19:", 1)),
        # 04:19:64.96 after 04:20:64.94 (the writer counts seconds past 59): the
        # seconds since 1970 shown in full, not as 1.61889e+09 twice
        r"column 'time', row 599: time 1618892404\.96 s is before the previous "
        r"row's 1618892464\.94 s",
    ),
    (
        "clock date jumps a day",
        F,
        _edit(lambda x: x[:600] + [s.replace("-20T", "-21T") for s in x[600:]]),
        r"column 'time', row 599: the clock jumps \+24\.0 h from row 598",
    ),
    (
        "header again mid-file",
        U,
        _edit(lambda x: x[:600] + x[:2] + x[600:]),
        r"row 599 repeats the header \(line 1\): the logger restarted",
    ),
    (
        "header again mid-file, semicolons",
        X,
        _edit(lambda x: x[:600] + x[:1] + x[600:]),
        r"row 600 repeats the header \(line 1\): the logger restarted",
    ),
    (
        "a second header, other columns",
        U,
        _edit(
            lambda x: x[:600] + ["time,altitude,pressure", "(s),(ft),(mbar)"] + x[600:]
        ),
        r"row 599 is words, not numbers \('time,altitude,pressure'\): another header",
    ),
    (
        "NUL bytes mid-file",
        U,
        _swap(600, lambda s: "\x00" * 512 + s),
        r"row 599: NUL bytes \(a block the logger never wrote",
    ),
    (
        # rows count from 1 for the first data row, a comment line not among them,
        # as in the messages about the values (time backwards, below)
        "NUL bytes after a comment line",
        U,
        _edit(
            lambda x: [
                *x[:300],
                "# apogee",
                *x[300:601],
                "\x00" * 64 + x[601],
                *x[602:],
            ]
        ),
        r"row 600: NUL bytes",
    ),
    (
        "time backwards after a comment line",
        U,
        _edit(lambda x: [*x[:300], "# apogee", *x[300:601], "-5" + x[601], *x[602:]]),
        r"column 'time', row 600: time -5",
    ),
    (
        "NUL bytes in the sniffed lines, Windows-1252",
        X,
        _swap(50, lambda s: "\x00" * 100 + s),
        r"line 51: NUL bytes, in a file that is not UTF-8: not a text file, or a "
        "block the logger never wrote",
    ),
    (
        "a header of 200,000 characters",
        U,
        _swap(0, lambda s: s + "," + "x" * 200_000),
        r"line 1: a line of 200,045 characters \('time,altitude,velocity,pressure,"
        r"accelera\.\.\.'\), not a row of cells",
    ),
    (
        "an extremely long line",
        U,
        _swap(500, lambda s: s + "," + "9" * 2_000_000),
        r"row 499: a line of 2,000,0\d\d characters \('[\d.,-]+\.\.\.'\), not a row",
    ),
    (
        "two rows run together",
        U,
        _edit(lambda x: x[:500] + [x[500] + x[501]] + x[502:]),
        r"row 499 has 9 cells, the header 5 \(an extra cell '\d+\.\d'\): two rows run "
        r"together \(a line end lost\), or a decimal comma",
    ),
    (
        "two rows run together, semicolons",
        X,
        _edit(lambda x: x[:500] + [x[500] + x[501]] + x[502:]),
        r"row 500 has 9 cells, the header 5 \(an extra cell '\d+,\d\d'\)",
    ),
    (
        "two rows run together, whitespace",
        "whitespace_logger",
        _edit(lambda x: x[:300] + [x[300] + x[301]] + x[302:]),
        r"row 298 has 13 cells, the header 7 \(an extra cell '0'\): two rows run "
        r"together \(a line end lost\)$",
    ),
    (
        "an unquoted decimal comma in a comma file",
        U,
        _swap(300, _comma_in),
        r"row 299 has 6 cells, the header 5 \(an extra cell '-?\d+'\): two rows run "
        r"together \(a line end lost\), or a decimal comma in a comma-separated file",
    ),
    (
        "a byte neither UTF-8 nor Windows-1252 past line 400, clock times",
        F,
        _byte_in(600, b"\x81"),
        r"row 599: byte 0x81 is neither UTF-8 nor Windows-1252 text",
    ),
    (
        "a byte neither UTF-8 nor Windows-1252 past line 400",
        U,
        _byte_in(600, b"\x9d"),
        r"row 599: byte 0x9d is neither UTF-8 nor Windows-1252 text",
    ),
    (
        "quoted decimal commas in a comma file",
        X,
        _edit(_quoted),
        r"column 'Zeit \[s\]', row 1: '0,00' has a decimal comma; give the file's "
        r'stream "decimal": ","',
    ),
]


@pytest.mark.parametrize(
    "layout, damage, pattern", [c[1:] for c in REFUSED], ids=[c[0] for c in REFUSED]
)
def test_a_broken_file_is_one_error_line(tmp_path, layout, damage, pattern):
    files, cmap, _, _ = LAYOUTS[layout](tmp_path, TRUTH)
    damage(files[0], layout)
    with pytest.raises(LogError) as e:
        read_rocket_log(files, column_map=cmap)
    line = str(e.value)
    assert "\n" not in line
    assert line.startswith(f"{files[0]}: "), line
    assert re.search(pattern, line), line


def _late_cp1252(path, layout):
    lines = path.read_text().splitlines()
    lines.insert(700, "# Zündung, Höhe in ft")  # a comment line in Windows-1252
    path.write_bytes(("\n".join(lines) + "\n").encode("cp1252"))


# (id, layout, damage, a message the read must give or None, column map changes)
READ = [
    (
        "last line cut short",
        U,
        _bytes(lambda b: b.rstrip(b"\n")[: b.rstrip(b"\n").rfind(b"\n") + 6]),
        r"dropped the last 1 row\(s\) from row 1201 on, a write cut short: row 1201 has "
        r"1 cells, the header 5: it ends before column 'altitude'",
        {},
    ),
    (
        "last line cut short, semicolons",
        X,
        _bytes(lambda b: b.rstrip(b"\r\n")[: b.rstrip(b"\r\n").rfind(b"\r\n") + 7]),
        r"dropped the last 1 row\(s\) from row 1201 on",
        {},
    ),
    (
        "NUL padding at the end",
        U,
        _bytes(lambda b: b + b"\x00" * 4096),
        r"dropped the last 1 row\(s\) from row 1202 on, a write cut short: row 1202: NUL "
        "bytes",
        {},
    ),
    ("BOM", U, _bytes(lambda b: b"\xef\xbb\xbf" + b), None, {}),
    (
        "the header written twice at the top",
        U,
        _edit(lambda x: x[:1] + x),
        None,  # the units row under the copy gives the units, as without it
        {},
    ),
    ("BOM on Windows-1252", X, _bytes(lambda b: b"\xef\xbb\xbf" + b), None, {}),
    (
        "BOM on UTF-8, semicolons",
        X,
        _bytes(lambda b: b"\xef\xbb\xbf" + b.decode("cp1252").encode()),
        None,
        {},
    ),
    (
        "BOM, clock times",
        F,
        _bytes(lambda b: b"\xef\xbb\xbf" + b),
        r"clock times read as seconds",
        {},
    ),
    ("CRLF and LF mixed", U, _bytes(lambda b: b.replace(b"0\n", b"0\r\n")), None, {}),
    (
        "CRLF and LF mixed, semicolons",
        X,
        _bytes(lambda b: b.replace(b"0\r\n", b"0\n")),
        None,
        {},
    ),
    (
        "Windows-1252 byte past line 400",
        U,
        _late_cp1252,
        r"track\.csv: read as Windows-1252 text \(a byte past the first 400 lines",
        {},
    ),
    (
        "every row ends with its separator",
        U,
        _edit(lambda x: [s + "," for s in x]),
        None,
        {},
    ),
    (
        "every data row ends with a separator, the header not",
        U,
        _edit(lambda x: x[:2] + [s + "," for s in x[2:]]),
        None,
        {},
    ),
    (
        "every cell quoted",
        U,
        _edit(lambda x: [",".join(f'"{c}"' for c in s.split(",")) for s in x]),
        None,
        {},
    ),
    (
        "quoted decimal commas, the map says so",
        X,
        _edit(_quoted),
        None,
        {"decimal": ","},
    ),
]


@pytest.mark.parametrize(
    "layout, damage, message, changes",
    [c[1:] for c in READ],
    ids=[c[0] for c in READ],
)
def test_a_damage_that_spares_the_data_reads_them(
    tmp_path, layout, damage, message, changes
):
    files, cmap, tol, t0 = LAYOUTS[layout](tmp_path, TRUTH)
    rows = len(files[0].read_bytes().splitlines()) - (2 if layout != X else 1)
    damage(files[0], layout)
    log = read_rocket_log(files, column_map={**(cmap or {}), **changes} or None)
    said = "\n".join(log.messages)
    if message is not None:
        assert re.search(message, said), said
    assert "dropped" in said or len(log["altitude"].t) == rows
    offset = next(iter(log.time_offsets.values())) - t0
    for name, eps in tol.items():
        if name.startswith("_"):
            continue
        c = log[name]
        truth = np.interp(c.t + offset, TRUTH["t"], TRUTH[name])
        values = c.values
        if name == "altitude":
            truth += tol.get("_datum", 0.0)
            values = values + log.pad.get("altitude_offset", 0.0)
        # the layout's rounding (0.1 ft, 0.01 m, 1 mm; 0.01 mbar; 1 mG) and no more
        assert np.max(np.abs(values - truth)) <= eps * (1 + 1e-6) + 1e-9, name


def _no_altitude(lines):
    return lines[:2] + [re.sub(r"^([^,]*),[^,]*,", r"\1,,", s) for s in lines[2:]]


def test_a_column_all_empty_is_not_used_with_a_message(tmp_path):
    files, _, _, _ = LAYOUTS[U](tmp_path, TRUTH)
    _edit(_no_altitude)(files[0], U)
    log = read_rocket_log(files)
    assert "altitude" not in log.channels and "pressure" in log.channels
    assert any(
        "column 'altitude': no values, channel 'altitude' not used" in m
        for m in log.messages
    )
