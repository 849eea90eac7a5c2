"""The broken variants a user hits on the rocket-log reader's layout features
(units row, semicolons with decimal commas and Windows-1252, clock times), each
written from the simulated flight of tests/rocket_layouts.py, read with
`read_rocket_log`, and the outcome printed as one line: `error` (the LogError's
line), `read` (rows, the largest altitude error against the simulation, the
reader's messages) or `TRACEBACK` (an exception that is not a LogError).

Run: PYTHONPATH=src python experiments/broken_rocket_logs.py
"""

import pathlib
import sys
import tempfile

import numpy as np


sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from tests.rocket_layouts import flight, LAYOUTS  # noqa: E402

from diffpegasus import LogError, read_rocket_log  # noqa: E402


TRUTH = flight()


def _base(folder, name):
    files, cmap, _, t0 = LAYOUTS[name](folder, TRUTH)
    return files[0], cmap, t0


def _lines(path, encoding="utf-8"):
    return path.read_bytes().decode(encoding).splitlines()


def _write(path, lines, end="\n", encoding="utf-8"):
    path.write_bytes((end.join(lines) + end).encode(encoding))


def truncated(path, enc, end):
    raw = path.read_bytes().rstrip(b"\r\n")
    path.write_bytes(raw[: raw.rfind(end.encode()) + len(end) + 5])


def header_only(path, enc, end, keep):
    _write(path, _lines(path, enc)[:keep], end, enc)


def column_empty(path, enc, end, sep, j):
    lines = _lines(path, enc)
    out = []
    for k, line in enumerate(lines):
        cells = line.split(sep)
        if k >= 2 or (k >= 1 and sep == ";"):
            cells[j] = ""
        out.append(sep.join(cells))
    _write(path, out, end, enc)


def mixed_decimal(path, enc, end):
    lines = _lines(path, enc)
    lines[200] = lines[200].replace(",", ".")
    _write(path, lines, end, enc)


def restarted(path, enc, end, head):
    lines = _lines(path, enc)
    _write(path, lines[:600] + lines[:head] + lines[600:], end, enc)


def restarted_at_top(path, enc, end):
    lines = _lines(path, enc)
    _write(path, lines[:1] + lines, end, enc)


def second_header(path, enc, end, new):
    lines = _lines(path, enc)
    _write(path, lines[:600] + new + lines[600:], end, enc)


def bom(path, enc, end):
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())


def nul_bytes(path, enc, end, where):
    raw = path.read_bytes()
    k = where if where >= 0 else len(raw) // 2
    k = raw.find(b"\n", k) + 1
    path.write_bytes(raw[:k] + b"\x00" * 512 + raw[k:])


def nul_tail(path, enc, end):
    path.write_bytes(path.read_bytes() + b"\x00" * 4096)


def mixed_ends(path, enc, end):
    lines = _lines(path, enc)
    text = "".join(ln + ("\r\n" if k % 2 else "\n") for k, ln in enumerate(lines))
    path.write_bytes(text.encode(enc))


def long_line(path, enc, end, sep):
    lines = _lines(path, enc)
    lines[500] = lines[500] + sep + "9" * 2_000_000
    _write(path, lines, end, enc)


def late_cp1252(path, enc, end):
    lines = _lines(path, enc)
    lines.insert(700, "# Zündung, Höhe in ft")
    _write(path, lines, end, "cp1252")


def joined_rows(path, enc, end):
    lines = _lines(path, enc)
    lines[500:502] = [lines[500] + lines[501]]
    _write(path, lines, end, enc)


def comma_decimal(path, enc, end):
    lines = _lines(path, enc)
    cells = lines[300].split(",")
    lines[300] = ",".join(cells[:2] + [cells[2].replace(".", ",")] + cells[3:])
    _write(path, lines, end, enc)


def thousands(path, enc, end):
    lines = _lines(path, enc)
    cells = lines[900].split(";")
    whole, frac = cells[1].split(",")
    cells[1] = f"{whole[:-3]}.{whole[-3:]},{frac}"
    lines[900] = ";".join(cells)
    _write(path, lines, end, enc)


def bom_utf8(path, enc, end):
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes().decode(enc).encode())


def clock_back(path, enc, end):
    lines = _lines(path, enc)
    lines[600] = lines[600].replace("04:20:", "04:19:", 1)
    _write(path, lines, end, enc)


def clock_day(path, enc, end):
    lines = _lines(path, enc)
    lines[600:] = [ln.replace("2021-04-20", "2021-04-21", 1) for ln in lines[600:]]
    _write(path, lines, end, enc)


def quoted_decimal_comma(path, enc, end):
    lines = _lines(path, enc)
    out = [lines[0].replace(";", ",")]
    out += [",".join(f'"{c}"' for c in ln.split(";")) for ln in lines[1:]]
    _write(path, out, end, enc)


U, X, F = "units_row", "excel_semicolon", "flysight_track"
CASES = [
    ("truncated last line (units row)", U, truncated, ()),
    ("truncated last line (semicolons)", X, truncated, ()),
    ("header only (units row layout)", U, header_only, (1,)),
    ("header only (semicolons)", X, header_only, (1,)),
    ("units row, no data", U, header_only, (2,)),
    ("column all empty (units row)", U, column_empty, (",", 1)),
    ("column all empty (semicolons)", X, column_empty, (";", 1)),
    ("mixed decimal separators", X, mixed_decimal, ()),
    ("clock time backwards", F, clock_back, ()),
    ("clock date jumps a day", F, clock_day, ()),
    ("logger restarted: header again (units row)", U, restarted, (2,)),
    ("logger restarted: header again (semicolons)", X, restarted, (1,)),
    (
        "second header, other columns",
        U,
        second_header,
        (["time,altitude,pressure", "(s),(ft),(mbar)"],),
    ),
    ("header written twice at the top", U, restarted_at_top, ()),
    ("BOM (units row)", U, bom, ()),
    ("BOM (semicolons, cp1252)", X, bom, ()),
    ("BOM (clock times)", F, bom, ()),
    ("NUL bytes mid-file (units row)", U, nul_bytes, (-1,)),
    ("NUL bytes mid-file (semicolons)", X, nul_bytes, (-1,)),
    ("NUL padding at the end (units row)", U, nul_tail, ()),
    ("NUL padding at the end (semicolons)", X, nul_tail, ()),
    ("CRLF and LF mixed (units row)", U, mixed_ends, ()),
    ("CRLF and LF mixed (semicolons)", X, mixed_ends, ()),
    ("extremely long line (units row)", U, long_line, (",",)),
    ("extremely long line (semicolons)", X, long_line, (";",)),
    ("cp1252 byte after line 400 (comment line)", U, late_cp1252, ()),
    ("two rows run together (units row)", U, joined_rows, ()),
    ("two rows run together (semicolons)", X, joined_rows, ()),
    ("unquoted decimal comma in a comma file", U, comma_decimal, ()),
    ("thousands separator in a decimal-comma file", X, thousands, ()),
    ("BOM (semicolons, UTF-8)", X, bom_utf8, ()),
    ("quoted decimal commas, comma-separated", X, quoted_decimal_comma, ()),
    (
        'quoted decimal commas, "decimal": "," in the map',
        X,
        quoted_decimal_comma,
        (),
        {"decimal": ","},
    ),
]


def run(label, layout, fn, args, changes=None):
    with tempfile.TemporaryDirectory() as tmp:
        path, cmap, t0 = _base(pathlib.Path(tmp), layout)
        enc = "cp1252" if layout == X and fn is not late_cp1252 else "utf-8"
        end = "\r\n" if layout == X else "\n"
        fn(path, enc, end, *args)
        if changes:
            cmap = {**(cmap or {}), **changes}
        try:
            log = read_rocket_log([path], column_map=cmap)
        except LogError as e:
            text = str(e).replace(str(path), path.name)
            return f"error: {text[:230]}"
        except Exception as e:  # noqa: BLE001 (what the probe is for)
            return f"TRACEBACK {type(e).__name__}: {str(e)[:150]}"
        said = " | ".join(m for m in log.messages if "unit" not in m)
        said = said.replace(str(path.parent) + "/", "")[:200]
        if "altitude" not in log.channels:
            return f"read without altitude: {sorted(log.channels)}; {said}"
        c = log["altitude"]
        offset = next(iter(log.time_offsets.values())) - t0
        truth = np.interp(c.t + offset, TRUTH["t"], TRUTH["altitude"])
        datum = 150.0 if layout == F else 0.0
        err = np.max(
            np.abs(c.values + log.pad.get("altitude_offset", 0) - truth - datum)
        )
        return f"read {len(c.t)} rows, altitude off {err:.3g} m; {said}"


if __name__ == "__main__":
    for case in CASES:
        print(f"{case[0]}: {run(*case)}", flush=True)
