"""The damages a logger, a card or a spreadsheet does to a rocket log, written on
the layouts of tests/rocket_layouts.py: one list shared by
tests/test_rocket_broken_files.py (which asserts the outcomes) and
experiments/broken_rocket_logs.py (which prints them), so both damage the same
rows. Each damage is `damage(path, layout)` and rewrites the file in place."""

import re


U, X, F = "units_row", "excel_semicolon", "flysight_track"


def _enc(layout):
    return "cp1252" if layout == X else "utf-8"


def _end(layout):
    return "\r\n" if layout == X else "\n"


def edit(fn):
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
    return edit(lambda lines: lines[:k] + [fn(lines[k])] + lines[k + 1 :])


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
        edit(lambda x: x[:1]),
        r"the file has a header \(line 1\) but no data rows",
    ),
    (
        "header only, semicolons",
        X,
        edit(lambda x: x[:1]),
        r"the file has a header \(line 1\) but no data rows",
    ),
    (
        "units row, no data",
        U,
        edit(lambda x: x[:2]),
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
        _swap(600, lambda s: s.replace("T04:21:", "T04:20:", 1)),
        # 04:20:04.96 after 04:21:04.94: the seconds since 1970 shown in full, not
        # as 1.61889e+09 twice
        r"column 'time', row 599: time 1618892404\.96 s is before the previous "
        r"row's 1618892464\.94 s",
    ),
    (
        "a time of day with 77 seconds",
        F,
        _swap(600, lambda s: s.replace("T04:21:04.960", "T04:20:77.000", 1)),
        r"column 'time', row 599: '2021-04-20T04:20:77\.000Z' is not a time of day",
    ),
    (
        "a time in seconds that jumps a day",
        U,
        edit(
            lambda x: (
                x[:600]
                + [
                    f"{float(s.split(',')[0]) + 86400:.2f}," + s.split(",", 1)[1]
                    for s in x[600:]
                ]
            )
        ),
        r"column 'time', row 599: the time jumps \+24\.0 h from row 598",
    ),
    (
        "clock date jumps a day",
        F,
        edit(lambda x: x[:600] + [s.replace("-20T", "-21T") for s in x[600:]]),
        r"column 'time', row 599: the clock jumps \+24\.0 h from row 598",
    ),
    (
        "header again mid-file",
        U,
        edit(lambda x: x[:600] + x[:2] + x[600:]),
        r"row 599 repeats the header \(line 1\): the logger restarted",
    ),
    (
        "header again mid-file, semicolons",
        X,
        edit(lambda x: x[:600] + x[:1] + x[600:]),
        r"row 600 repeats the header \(line 1\): the logger restarted",
    ),
    (
        "a second header, other columns",
        U,
        edit(
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
        edit(
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
        edit(lambda x: [*x[:300], "# apogee", *x[300:601], "-5" + x[601], *x[602:]]),
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
        edit(lambda x: x[:500] + [x[500] + x[501]] + x[502:]),
        r"row 499 has 9 cells, the header 5 \(an extra cell '\d+\.\d'\): two rows run "
        r"together \(a line end lost\), or a decimal comma",
    ),
    (
        "two rows run together, semicolons",
        X,
        edit(lambda x: x[:500] + [x[500] + x[501]] + x[502:]),
        r"row 500 has 9 cells, the header 5 \(an extra cell '\d+,\d\d'\)",
    ),
    (
        "two rows run together, whitespace",
        "whitespace_logger",
        edit(lambda x: x[:300] + [x[300] + x[301]] + x[302:]),
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
        edit(_quoted),
        r"column 'Zeit \[s\]', row 1: '0,00' has a decimal comma; give the file's "
        r'stream "decimal": ","',
    ),
]


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
        r"1 cell, the header 5: it ends before column 'altitude'",
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
        edit(lambda x: x[:1] + x),
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
        edit(lambda x: [s + "," for s in x]),
        None,
        {},
    ),
    (
        "every data row ends with a separator, the header not",
        U,
        edit(lambda x: x[:2] + [s + "," for s in x[2:]]),
        None,
        {},
    ),
    (
        "every cell quoted",
        U,
        edit(lambda x: [",".join(f'"{c}"' for c in s.split(",")) for s in x]),
        None,
        {},
    ),
    (
        "quoted decimal commas, the map says so",
        X,
        edit(_quoted),
        None,
        {"decimal": ","},
    ),
]


def no_altitude(lines):
    return lines[:2] + [re.sub(r"^([^,]*),[^,]*,", r"\1,,", s) for s in lines[2:]]


# Probe-only variants (not in the tests): other layouts for the same damages,
# (id, layout, damage, column map changes); experiments/broken_rocket_logs.py runs
# them after REFUSED and READ.
MORE = [
    ("column all empty", U, edit(no_altitude), {}),
    (
        "column all empty, semicolons",
        X,
        edit(lambda x: x[:1] + [re.sub(r"^([^;]*);[^;]*;", r"\1;;", s) for s in x[1:]]),
        {},
    ),
    ("NUL bytes mid-file, semicolons", X, _swap(600, lambda s: "\x00" * 512 + s), {}),
    ("NUL padding at the end, semicolons", X, _bytes(lambda b: b + b"\x00" * 4096), {}),
    (
        "an extremely long line, semicolons",
        X,
        _swap(500, lambda s: s + ";" + "9" * 2_000_000),
        {},
    ),
]
