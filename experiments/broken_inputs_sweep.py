"""A mutation sweep over every file a user gives the command line: aircraft logs (CSV,
FVSysID `.asc`, MATLAB `.mat` v5 and v7.3, HDF5), column maps, model files, options,
and a rocket's `rocket.toml`, thrust curve, drag curve and flight log. Each case
damages one thing in a good input, runs the command a user would
(`python -m diffpegasus ...`, in a fresh process, with a timeout), and classifies
the outcome:

- `error`: exit 2 with one line `error: ...` naming the damaged file (or option);
- `error-vague`: exit 2 with one line that does not name it;
- `traceback`: a Python traceback, or any other exit code but 0, 2 and 3;
- `accepted-same`: exit 0 with the good input's numbers (the damage did not matter:
  an unused column, a blank line);
- `accepted-close` / `accepted-DIFFERENT`: exit 0 with numbers within 1 % of the
  good input's / further off; `accepted` where there are no numbers to compare;
- `fit-failed`: exit 3 (the input was read; the fit did not converge);
- `hang`: no answer within the timeout.

A failing run given `--out DIR` must leave no file there: `partial` lists any.

Run: PYTHONPATH=src DIFFPEGASUS_SHARED=/work/shared \
    nice -n 10 python experiments/broken_inputs_sweep.py [--only PREFIX] [--label L]
(SWEEP_SRC=DIR runs the commands from another copy of src, for the "before" run.)
Writes experiments/results/broken_inputs_sweep.json.
"""

import argparse
import json
import math
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
SHARED = pathlib.Path(os.environ.get("DIFFPEGASUS_SHARED", ROOT.parent / "shared"))
DATA = SHARED / "data"
HFB = DATA / "hfb320" / "hfb320_1_10.asc"
UNSTABLE = DATA / "unstable_aircraft" / "unStabAC_sim.asc"
CAVOUR = DATA / "rockets" / "cavour"
ANDROMEDA = DATA / "rockets" / "andromeda"
RESULTS = ROOT / "experiments" / "results" / "broken_inputs_sweep.json"
TIMEOUT = 180.0

HFB_MAP = {
    "t": "T",
    "de": "DELV",
    "thrust": "THRUST",
    "V": "TASCG",
    "alpha": "ALFCG",
    "q": "Q",
    "qdot": "QDOT",
    "az": "AZCG",
    "theta": "THE",
    "ax": "AXCG",
    "qbar": "PDYN",
}


# ------------------------------------------------------------------ running


def run(args, cwd, out=None, timeout=TIMEOUT):
    """`(returncode or None on timeout, stdout, stderr, seconds)`."""
    env = {**os.environ, "PYTHONPATH": os.environ.get("SWEEP_SRC", str(ROOT / "src"))}
    start = time.perf_counter()
    try:
        p = subprocess.run(
            [sys.executable, "-m", "diffpegasus", *map(str, args)],
            cwd=cwd,
            env=env,
            capture_output=True,
            text=True,
            timeout=timeout,
            stdin=subprocess.DEVNULL,
        )
    except subprocess.TimeoutExpired as e:
        return None, e.stdout or "", e.stderr or "", time.perf_counter() - start
    return p.returncode, p.stdout, p.stderr, time.perf_counter() - start


def numbers(kind, stdout):
    """The numbers to compare with the good input's, from a command's JSON."""
    try:
        d = json.loads(stdout)
    except (json.JSONDecodeError, TypeError):
        return None
    if kind == "check":
        got = {
            f"{c}.{k}": v
            for c, row in (d.get("channels") or {}).items()
            if isinstance(row, dict)
            for k, v in row.items()
            if k in ("min_si", "max_si") and isinstance(v, int | float)
        }
        samples = str(d.get("summary", "")).split(" ")[0]
        got["samples"] = float(samples) if samples.isdigit() else None
        return got
    if kind == "fit":
        return d.get("estimates")
    if kind == "rocket":
        return {
            k: d.get(k)
            for k in ("apogee_reconstructed_m", "apogee_predicted_m", "thrust_scale")
        }
    return None


def compare(a, b):
    """Largest relative difference between two dicts of numbers (inf if they differ
    in keys or a number is missing)."""
    if not a or not b or set(a) != set(b):
        return math.inf
    worst = 0.0
    for k in a:
        x, y = a[k], b[k]
        if x is None or y is None:
            if x is not y:
                return math.inf
            continue
        worst = max(worst, abs(x - y) / max(abs(y), 1e-9))
    return worst


def classify(rc, stdout, stderr, where, kind, baseline):
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("error:")]
    if rc is None:
        return "hang", ""
    if "Traceback (most recent call last)" in stderr or rc not in (0, 2, 3):
        tail = lines[-1] if lines else f"exit {rc}"
        return "traceback", tail[:300]
    if rc == 2:
        message = errors[-1] if errors else (lines[-1] if lines else "")
        named = any(w in message for w in where)
        one = len(errors) == 1
        return ("error" if named and one else "error-vague"), message[:400]
    if rc == 3:
        return "fit-failed", (errors[-1] if errors else "")[:300]
    got = numbers(kind, stdout)
    if baseline is None or got is None:
        return "accepted", ""
    d = compare(got, baseline)
    warn = "; ".join(ln for ln in lines if ln.startswith("warning"))[:300]
    if d < 1e-9:
        return "accepted-same", warn
    if d < 0.01:
        return "accepted-close", f"largest relative difference {d:.2g}; {warn}"
    return "accepted-DIFFERENT", f"largest relative difference {d:.3g}; {warn}"


# ------------------------------------------------------------------ tables


def asc_table(path):
    """`(names, units, rows of str)` of an FVSysID `.asc` file."""
    lines = path.read_text().splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.split()[:1] == ["T"])
    names, units = lines[i].split(), lines[i + 1].split()
    rows = [ln.split() for ln in lines[i + 2 :] if ln.strip()]
    return names, units, rows


def write_csv(path, names, rows, sep=",", encoding="utf-8", newline="\n"):
    text = newline.join([sep.join(names), *(sep.join(r) for r in rows)]) + newline
    path.write_bytes(text.encode(encoding))


def write_asc(path, names, units, rows):
    out = [
        "Date file: broken",
        f"{len(names) - 1} Variables plus time, with {len(rows)} values each",
        "",
        " ".join(f"{n:>15}" for n in names),
        " ".join(f"{u:>15}" for u in units),
    ]
    out += [" ".join(f"{c:>15}" for c in r) for r in rows]
    path.write_text("\n".join(out) + "\n")


def floats(rows):
    return np.array([[float(c) for c in r] for r in rows])


def write_mat(path, names, rows, version="5", extra=None):
    a = floats(rows)
    d = {n: a[:, k] for k, n in enumerate(names)}
    d.update(extra or {})
    if version == "5":
        import scipy.io

        scipy.io.savemat(path, d)
    else:
        write_h5(path, names, rows, extra=extra, mat73=True)


def write_h5(path, names, rows, extra=None, mat73=False):
    import h5py

    a = floats(rows)
    with h5py.File(path, "w", userblock_size=512 if mat73 else 0) as f:
        for k, n in enumerate(names):
            f[n] = a[:, k][None, :] if mat73 else a[:, k]
        for n, v in (extra or {}).items():
            if isinstance(v, str) and v == "GROUP":
                f.create_group(n).create_dataset("x", data=a[:, 0])
            else:
                f[n] = v
    if mat73:
        with open(path, "r+b") as f:
            f.write(b"MATLAB 7.3 MAT-file".ljust(116, b" ") + b"\0" * 8 + b"\x00\x02IM")


# ------------------------------------------------------------------ mutations
# A table mutation takes (names, units, rows) and returns the damaged triple (rows
# are lists of str). "fine" says the result is legitimately readable (the numbers
# must not change); otherwise the command must refuse it or keep the numbers.


def _set(rows, i, j, value):
    rows = [list(r) for r in rows]
    rows[i][j] = value
    return rows


def _col(names, name):
    return names.index(name)


def cell(name, value, row=100):
    def f(names, units, rows):
        return names, units, _set(rows, row, _col(names, name), value)

    return f


def scale_column(name, factor):
    def f(names, units, rows):
        j = _col(names, name)
        rows = [list(r) for r in rows]
        for r in rows:
            r[j] = repr(float(r[j]) * factor)
        return names, units, rows

    return f


def rename(name, new):
    def f(names, units, rows):
        return [new if n == name else n for n in names], units, rows

    return f


def drop(name):
    def f(names, units, rows):
        j = _col(names, name)
        keep = [k for k in range(len(names)) if k != j]
        return (
            [names[k] for k in keep],
            [units[k] for k in keep],
            [[r[k] for k in keep] for r in rows],
        )

    return f


def duplicate_row(i=50):
    return lambda n, u, r: (n, u, r[: i + 1] + [list(r[i])] + r[i + 1 :])


def swap_rows(i=50):
    return lambda n, u, r: (n, u, r[:i] + [r[i + 1], r[i]] + r[i + 2 :])


def duplicate_column(name):
    def f(names, units, rows):
        j = _col(names, name)
        return names + [name], units + [units[j]], [r + [r[j]] for r in rows]

    return f


def constant(name, value="0.0"):
    def f(names, units, rows):
        j = _col(names, name)
        return names, units, [r[:j] + [value] + r[j + 1 :] for r in rows]

    return f


def ragged(i=60):
    return lambda n, u, r: (n, u, _extend(r, i))


def _extend(rows, i):
    rows = [list(r) for r in rows]
    rows[i] = rows[i] + ["1.0"]
    return rows


def short_rows(k):
    return lambda n, u, r: (n, u, r[:k])


def keep(n, u, r):
    return n, u, r


TABLE_MUTATIONS = [
    # (id, mutation, fine)
    ("nan cell in a mapped column", cell("Q", "nan"), False),
    ("NaN cell in a mapped column", cell("Q", "NaN"), False),
    ("inf cell in a mapped column", cell("Q", "inf"), False),
    ("-inf cell in the time column", cell("T", "-inf"), False),
    ("empty cell", cell("Q", ""), False),
    ("text cell", cell("Q", "abc"), False),
    ("decimal comma cell", cell("Q", "0,01"), False),
    ("huge value 1e300", cell("AZCG", "1e300"), False),
    ("corrupt value 1e12", cell("AZCG", "1e12"), False),
    ("nan in an unmapped column", cell("AYCG", "nan"), True),
    ("text in an unmapped column", cell("AYCG", "x"), True),
    ("column renamed", rename("Q", "QB"), False),
    ("column renamed to lower case", rename("Q", "q_rate"), False),
    ("column missing", drop("Q"), False),
    ("time column missing", drop("T"), False),
    ("duplicate time row", duplicate_row(), False),
    ("time not monotonic (two rows swapped)", swap_rows(), False),
    ("time in ms", scale_column("T", 1000.0), False),
    ("q in deg/s, map says rad/s", scale_column("Q", 180 / math.pi), False),
    ("alpha in deg, map says rad", scale_column("ALFCG", 180 / math.pi), False),
    ("V in knots, map says m/s", scale_column("TASCG", 1.943844), False),
    ("az in g, map says m/s^2", scale_column("AZCG", 1 / 9.80665), False),
    ("qbar in kPa, map says Pa", scale_column("PDYN", 1e-3), False),
    ("a column duplicated", duplicate_column("Q"), False),
    ("an output constant (dead sensor)", constant("Q"), False),
    ("a ragged row", ragged(), False),
    ("two rows only", short_rows(2), False),
    ("header only", short_rows(0), False),
]


def text_damage(kind):
    """Byte-level damage of a written file."""

    def f(path):
        b = path.read_bytes()
        if kind == "truncated":
            path.write_bytes(b[: int(len(b) * 0.6)])
        elif kind == "truncated at a row end":
            cut = b[: int(len(b) * 0.6)]
            path.write_bytes(cut[: cut.rfind(b"\n") + 1])
        elif kind == "empty":
            path.write_bytes(b"")
        elif kind == "binary":
            path.write_bytes(np.random.default_rng(0).bytes(4000))
        elif kind == "utf-16":
            path.write_bytes(b.decode().encode("utf-16"))
        elif kind == "latin-1 byte in the header":
            path.write_bytes(b.replace(b"T", b"T\xe9", 1))
        elif kind == "NUL bytes":
            path.write_bytes(b[:5000] + b"\0" * 64 + b[5000:])
        elif kind == "CRLF line ends":
            path.write_bytes(b.replace(b"\n", b"\r\n"))
        elif kind == "UTF-8 byte-order mark":
            path.write_bytes(b"\xef\xbb\xbf" + b)
        elif kind == "trailing blank lines":
            path.write_bytes(b + b"\n\n\n")
        elif kind == "a directory":
            path.unlink()
            path.mkdir()
        elif kind == "missing":
            path.unlink()
        elif kind == "gzip-compressed under the plain name":
            import gzip

            path.write_bytes(gzip.compress(b))
        else:
            raise ValueError(kind)

    return f


BYTE_DAMAGES = [
    ("truncated mid-row", text_damage("truncated"), False),
    ("truncated at a row end", text_damage("truncated at a row end"), False),
    ("empty file", text_damage("empty"), False),
    ("binary file", text_damage("binary"), False),
    ("UTF-16 text", text_damage("utf-16"), False),
    ("latin-1 byte in the header", text_damage("latin-1 byte in the header"), False),
    ("NUL bytes", text_damage("NUL bytes"), False),
    ("CRLF line ends", text_damage("CRLF line ends"), True),
    ("UTF-8 byte-order mark", text_damage("UTF-8 byte-order mark"), True),
    ("trailing blank lines", text_damage("trailing blank lines"), True),
    ("a directory instead of the file", text_damage("a directory"), False),
    ("the file missing", text_damage("missing"), False),
    (
        "gzip bytes under the plain name",
        text_damage("gzip-compressed under the plain name"),
        False,
    ),
]


# ------------------------------------------------------------------ cases


class Case:
    """One damaged input: `build(tmp)` writes it and returns the command's arguments
    and the names its error line should give; `base` the group whose good input
    the numbers are compared with (by default its own)."""

    def __init__(
        self, group, mutation, build, fine=False, kind="check", out=False, base=None
    ):
        self.group, self.mutation, self.build = group, mutation, build
        self.fine, self.kind, self.out = fine, kind, out
        self.base = base or group


def hfb_cases():
    """`check FILE --columns map.json --json` on the HFB-320 record, as CSV, .asc,
    .mat and HDF5."""
    names, units, rows = asc_table(HFB)
    cases = []

    def writer(fmt):
        def write(tmp, n, u, r, extra=None):
            path = tmp / f"flight.{fmt}"
            if fmt == "csv":
                write_csv(path, n, r)
            elif fmt == "asc":
                write_asc(path, n, u, r)
            elif fmt == "mat":
                write_mat(path, n, r, extra=extra)
            elif fmt == "mat73":
                path = tmp / "flight.mat"
                write_mat(path, n, r, version="7.3", extra=extra)
            else:
                write_h5(path, n, r, extra=extra)
            return path

        return write

    def table_case(fmt, mutation, fine, byte=None, mapping=HFB_MAP):
        def build(tmp):
            n, u, r = mutation(names, units, rows)
            path = writer(fmt)(tmp, n, u, r)
            (tmp / "map.json").write_text(json.dumps(mapping))
            if byte is not None:
                byte(path)
            return ["check", path.name, "--columns", "map.json", "--json"], [path.name]

        return build

    for fmt in ("csv", "asc"):
        cases.append(
            Case(f"aircraft {fmt}", "(good input)", table_case(fmt, keep, True))
        )
        for mid, m, fine in TABLE_MUTATIONS:
            cases.append(Case(f"aircraft {fmt}", mid, table_case(fmt, m, fine), fine))
        for mid, d, fine in BYTE_DAMAGES:
            cases.append(
                Case(f"aircraft {fmt}", mid, table_case(fmt, keep, fine, d), fine)
            )
    binary_ok = {
        "nan cell in a mapped column",
        "inf cell in a mapped column",
        "huge value 1e300",
        "corrupt value 1e12",
        "nan in an unmapped column",
        "column renamed",
        "column missing",
        "duplicate time row",
        "time not monotonic (two rows swapped)",
        "q in deg/s, map says rad/s",
        "an output constant (dead sensor)",
        "two rows only",
    }
    for fmt in ("mat", "mat73", "h5"):
        cases.append(
            Case(f"aircraft {fmt}", "(good input)", table_case(fmt, keep, True))
        )
        for mid, m, fine in TABLE_MUTATIONS:
            if mid in binary_ok:
                cases.append(
                    Case(f"aircraft {fmt}", mid, table_case(fmt, m, fine), fine)
                )
        for mid, d, fine in BYTE_DAMAGES[:4]:
            cases.append(
                Case(f"aircraft {fmt}", mid, table_case(fmt, keep, fine, d), fine)
            )

        def structural(fmt, what, extra, mapping):
            def build(tmp):
                path = writer(fmt)(tmp, names, units, rows, extra=extra)
                (tmp / "map.json").write_text(json.dumps(mapping))
                return ["check", path.name, "--columns", "map.json", "--json"], [
                    path.name
                ]

            return Case(f"aircraft {fmt}", what, build)

        n = len(rows)
        three = np.zeros((n, 2, 2))
        cases.append(
            structural(
                fmt,
                "a 3-D array where a column is mapped",
                {"Q3": three},
                {**HFB_MAP, "q": "Q3"},
            )
        )
        cases.append(
            structural(
                fmt,
                "a matrix (N x 3) mapped by its bare name",
                {"QM": np.zeros((n, 3))},
                {**HFB_MAP, "q": "QM"},
            )
        )
        cases.append(
            structural(
                fmt,
                "a vector of another length",
                {"QS": np.zeros(n - 7)},
                {**HFB_MAP, "q": "QS"},
            )
        )
        cases.append(
            structural(
                fmt,
                "a scalar where a column is mapped",
                {"QK": 3.0},
                {**HFB_MAP, "q": "QK"},
            )
        )
        cases.append(
            structural(
                fmt,
                "complex numbers",
                {"QC": np.ones(n) * (1 + 2j)},
                {**HFB_MAP, "q": "QC"},
            )
        )
        if fmt == "mat":
            cases.append(
                structural(
                    fmt,
                    "a struct where a column is mapped",
                    {"S": {"a": np.zeros(n)}},
                    {**HFB_MAP, "q": "S"},
                )
            )
            cases.append(
                structural(
                    fmt,
                    "a cell array where a column is mapped",
                    {"CELL": np.array([[1.0], "x"], dtype=object)},
                    {**HFB_MAP, "q": "CELL"},
                )
            )
            cases.append(
                structural(
                    fmt,
                    "text where a column is mapped",
                    {"TXT": "hello"},
                    {**HFB_MAP, "q": "TXT"},
                )
            )
        else:
            cases.append(
                structural(
                    fmt,
                    "a group where a dataset is mapped",
                    {"G": "GROUP"},
                    {**HFB_MAP, "q": "G"},
                )
            )
            cases.append(
                structural(
                    fmt,
                    "a string dataset where a column is mapped",
                    {"TXT": np.array([b"a"] * n)},
                    {**HFB_MAP, "q": "TXT"},
                )
            )
    return cases


def map_cases():
    """Column-map damage, `check flight.csv --columns MAP --json`."""
    names, units, rows = asc_table(HFB)
    good = json.dumps(HFB_MAP)
    bad = {
        "invalid JSON": ("map.json", good[:-3]),
        "empty map file": ("map.json", ""),
        "map is a JSON list": ("map.json", "[1, 2]"),
        "map is a JSON number": ("map.json", "3"),
        "unknown unit": (
            "map.json",
            json.dumps({**HFB_MAP, "q": {"column": "Q", "unit": "furlong"}}),
        ),
        "unit of the wrong type (a number)": (
            "map.json",
            json.dumps({**HFB_MAP, "q": {"column": "Q", "unit": 5}}),
        ),
        "scale zero": (
            "map.json",
            json.dumps({**HFB_MAP, "q": {"column": "Q", "scale": 0}}),
        ),
        "scale as a string": (
            "map.json",
            json.dumps({**HFB_MAP, "q": {"column": "Q", "scale": "2"}}),
        ),
        "scale true": (
            "map.json",
            json.dumps({**HFB_MAP, "q": {"column": "Q", "scale": True}}),
        ),
        "column 0": ("map.json", json.dumps({**HFB_MAP, "q": 0})),
        "column 1.5": ("map.json", json.dumps({**HFB_MAP, "q": 1.5})),
        "column as a list": ("map.json", json.dumps({**HFB_MAP, "q": ["Q"]})),
        "column null": ("map.json", json.dumps({**HFB_MAP, "q": None})),
        "entry without column": (
            "map.json",
            json.dumps({**HFB_MAP, "q": {"unit": "rad/s"}}),
        ),
        "misspelt entry key (colum)": (
            "map.json",
            json.dumps({**HFB_MAP, "q": {"colum": "Q"}}),
        ),
        "misspelt channel key": ("map.json", json.dumps({**HFB_MAP, "qq": "Q"})),
        "two channels one column": ("map.json", json.dumps({**HFB_MAP, "qdot": "Q"})),
        "a mapped column not in the file": (
            "map.json",
            json.dumps({**HFB_MAP, "q": "QXX"}),
        ),
        "unit deg/s on q (wrong unit)": (
            "map.json",
            json.dumps({**HFB_MAP, "q": {"column": "Q", "unit": "deg/s"}}),
        ),
        "step with a time column": (
            "map.json",
            json.dumps({**HFB_MAP, "t": {"column": "T", "step": 0.1}}),
        ),
        "step zero": (
            "map.json",
            json.dumps(
                {k: v for k, v in HFB_MAP.items() if k != "t"} | {"t": {"step": 0}}
            ),
        ),
        "step negative": (
            "map.json",
            json.dumps(
                {k: v for k, v in HFB_MAP.items() if k != "t"} | {"t": {"step": -0.1}}
            ),
        ),
        "step wrong (0.2 for 0.1)": (
            "map.json",
            json.dumps(
                {k: v for k, v in HFB_MAP.items() if k != "t"} | {"t": {"step": 0.2}}
            ),
        ),
        "duplicate key": ("map.json", good[:-1] + ', "q": "QDOT"}'),
        "TOML syntax error": ("map.toml", 't = "T"\nq = \n'),
        "TOML value of the wrong type (a date)": (
            "map.toml",
            't = "T"\nq = 1979-05-27\n',
        ),
        "TOML nested table": ("map.toml", 't = "T"\n[q]\ncolumn = "Q"\n[q.x]\ny = 1\n'),
        "latin-1 map": ("map.json", None),
        "map is a directory": ("map.json", "DIR"),
        "map missing": ("map.json", "MISSING"),
        "binary map": ("map.json", "BINARY"),
        "unknown extension (.yaml)": ("map.yaml", "t: T\n"),
    }
    cases = []
    for mid, (name, text) in bad.items():

        def build(tmp, name=name, text=text):
            write_csv(tmp / "flight.csv", names, rows)
            p = tmp / name
            if text == "DIR":
                p.mkdir()
            elif text == "MISSING":
                pass
            elif text == "BINARY":
                p.write_bytes(np.random.default_rng(1).bytes(300))
            elif text is None:
                p.write_bytes(
                    json.dumps({**HFB_MAP, "q": "Q"})
                    .replace("Q", "Q\u00e9")
                    .encode("latin-1")
                )
            else:
                p.write_text(text)
            # the map's problem may show in the data it reads: either file named
            return ["check", "flight.csv", "--columns", name, "--json"], [
                name,
                "flight.csv",
            ]

        cases.append(Case("column map", mid, build))
    return cases


MODEL_SRC = (ROOT / "examples" / "unstable_aircraft.py").read_text()


def model_cases():
    """Model-file and option damage: `fit unstable.csv --model model.py --out out
    --json` (a fit of a few seconds)."""
    names, units, rows = asc_table(UNSTABLE)

    def edit(old, new):
        assert old in MODEL_SRC, old
        return MODEL_SRC.replace(old, new)

    bad = {
        "(good input)": MODEL_SRC,
        "syntax error": MODEL_SRC.replace("def rates", "def rates(", 1),
        "raises at import": MODEL_SRC + "\nraise RuntimeError('boom')\n",
        "no model variable": edit("model = dp.Model(", "other = dp.Model("),
        "model is a number": MODEL_SRC + "\nmodel = 5\n",
        "NaN start value": edit('"Mq": -2.70670', '"Mq": float("nan")'),
        "start value a string": edit('"Mq": -2.70670', '"Mq": "-2.7"'),
        "rates returns three values": edit(
            'p["Mw"] * w + p["Mq"] * q + p["Mde"] * u[0],\n        ]',
            'p["Mw"] * w + p["Mq"] * q + p["Mde"] * u[0],\n            q,\n        ]',
        ),
        "rates returns NaN": edit(
            'return jnp.stack(\n        [\n            p["Zw"]',
            'return jnp.nan + jnp.stack(\n        [\n            p["Zw"]',
        ),
        "observe uses an unknown parameter": edit(
            'p["Zw"] * w + p["Zq"] * q + p["Zde"] * u[0], w',
            'p["Zx"] * w + p["Zq"] * q + p["Zde"] * u[0], w',
        ),
        "columns names a missing column": edit('"q": "Q"}', '"q": "QQ"}'),
        "columns is a list": edit(
            'columns = {"t": "T", "de": "DE", "az": "AZ", "w": "W", "q": "Q"}',
            'columns = ["T", "DE"]',
        ),
        "x0 of the wrong length": edit("x0 = (0.0, 0.0)", "x0 = (0.0, 0.0, 0.0)"),
        "x0 NaN": edit("x0 = (0.0, 0.0)", "x0 = (float('nan'), 0.0)"),
        "x0 a string": edit("x0 = (0.0, 0.0)", "x0 = 'zero'"),
        "shooting a string": edit(
            "shooting = dp.MultipleShooting(interval=1.0)", "shooting = 'multiple'"
        ),
        "shooting interval negative": edit("interval=1.0", "interval=-1.0"),
        "fixed names an unknown parameter": edit('fixed=("Zq",)', 'fixed=("Zqq",)'),
        "sys.exit at import": MODEL_SRC + "\nimport sys\nsys.exit(0)\n",
        "input() at import": MODEL_SRC + "\ninput()\n",
        "read raises": MODEL_SRC + "\ndef read(path):\n    raise ValueError('no')\n",
        "read returns NaN": MODEL_SRC
        + "\nimport numpy as np\ndef read(path):\n    t = np.arange(0, 10, 0.05)\n"
        "    return {'t': t, 'de': np.sin(t), 'az': t * np.nan, 'w': t, 'q': t}\n",
        "read returns a list": MODEL_SRC + "\ndef read(path):\n    return [1, 2]\n",
        "read returns ragged channels": MODEL_SRC
        + "\nimport numpy as np\ndef read(path):\n    t = np.arange(0, 10, 0.05)\n"
        "    return {'t': t, 'de': t[:5], 'az': t, 'w': t, 'q': t}\n",
        "candidates names an unknown parameter": MODEL_SRC + "\ncandidates = ['Zqq']\n",
        "process_noise negative": MODEL_SRC + "\nprocess_noise = {'w': -1.0}\n",
        "latin-1 model file": None,
        "empty model file": "",
    }
    cases = []
    for mid, src in bad.items():

        def build(tmp, src=src, mid=mid):
            write_csv(tmp / "flight.csv", names, rows)
            p = tmp / "model.py"
            if src is None:
                p.write_bytes(("# caf\u00e9\n" + MODEL_SRC).encode("latin-1"))
            else:
                p.write_text(src)
            args = [
                "fit",
                "flight.csv",
                "--model",
                "model.py",
                "--out",
                "out",
                "--json",
            ]
            if mid == "read raises" or mid.startswith("read returns"):
                p.write_text(src.replace("columns = {", "_columns = {"))
            # read() and the file's columns speak of the data file they read
            return args, ["model.py", "flight.csv"]

        good = mid == "(good input)"
        cases.append(Case("model file", mid, build, good, kind="fit", out=True))

    for what in ("directory", "missing", "binary"):

        def build(tmp, what=what):
            write_csv(tmp / "flight.csv", names, rows)
            p = tmp / "model.py"
            if what == "directory":
                p.mkdir()
            elif what == "binary":
                p.write_bytes(np.random.default_rng(2).bytes(500))
            return [
                "fit",
                "flight.csv",
                "--model",
                "model.py",
                "--out",
                "out",
                "--json",
            ], ["model.py"]

        cases.append(
            Case("model file", f"model file {what}", build, kind="fit", out=True)
        )

    options = {
        "(good input)": [],
        "--max-iter 0": ["--max-iter", "0"],
        "--max-iter -3": ["--max-iter", "-3"],
        "--fix unknown parameter": ["--fix", "Zqq=1"],
        "--fix Zw=inf": ["--fix", "Zw=inf"],
        "--fix Zw=abc": ["--fix", "Zw=abc"],
        "--bias unknown output": ["--bias", "qq"],
        "--bias twice": ["--bias", "az", "--bias", "az"],
        "--initial-state bogus": ["--initial-state", "bogus"],
        "--method bogus": ["--method", "bogus"],
        "--add unknown effect": ["--add", "no_such_effect"],
        "--shooting-interval 0": ["--shooting-interval", "0"],
        "--shooting-interval 1e9": ["--shooting-interval", "1e9"],
        "--shooting-interval nan": ["--shooting-interval", "nan"],
        "--process-noise without fem": ["--process-noise", "w=1"],
        "--method fem --process-noise unknown state": [
            "--method",
            "fem",
            "--process-noise",
            "zz=1",
        ],
        "--columns missing": ["--columns", "nomap.json"],
        "--out an existing file": ["OUTFILE"],
        "--vehicle and --model": ["--vehicle", "pegasus"],
        "same log twice": ["flight.csv"],
        "--knots on a model file": ["--knots", "3"],
        "--rate on a model file": ["--rate", "-5"],
    }
    for mid, extra in options.items():

        def build(tmp, extra=extra):
            write_csv(tmp / "flight.csv", names, rows)
            (tmp / "model.py").write_text(MODEL_SRC)
            args = ["fit", "flight.csv", "--model", "model.py", "--json"]
            if extra == ["OUTFILE"]:
                (tmp / "taken").write_text("x")
                return args + ["--out", "taken"], ["--out", "taken"]
            if extra == ["flight.csv"]:
                return args + ["--out", "out", "./flight.csv"], ["flight.csv"]
            flags = [e for e in extra if e.startswith("--")] or ["flight.csv"]
            values = [repr(e) for e in extra if not e.startswith("--")]
            return args + ["--out", "out", *extra], flags + values + ["nomap.json"]

        cases.append(Case("options", mid, build, fine=not extra, kind="fit", out=True))
    return cases


def rocket_cases():
    """`rocket fit rocket.toml --no-sensor-spread --out out --json` on Cavour (its
    .eng motor, drag curves and altimeter log) and Andromeda (a thrust CSV)."""
    cases = []

    def copy(tmp, src):
        dst = tmp / src.name
        shutil.copytree(src, dst, ignore=shutil.ignore_patterns("weather"))
        return dst

    def toml_case(mid, old, new, fine=False, flight=CAVOUR):
        def build(tmp):
            d = copy(tmp, flight)
            p = d / "rocket.toml"
            text = p.read_text()
            if old is not None:
                assert old in text, old
                text = text.replace(old, new, 1)
            else:
                text = new(text)
            p.write_text(text)
            return [
                "rocket",
                "fit",
                p,
                "--no-sensor-spread",
                "--out",
                tmp / "out",
                "--json",
            ], ["rocket.toml", *named(new)]

        return Case(f"rocket.toml ({flight.name})", mid, build, fine, "rocket", True)

    def named(new):
        """A file name the damaged key gives (a missing file is named as itself)."""
        if not isinstance(new, str) or '"' not in new:
            return []
        return [new.split('"')[1]]

    cases.append(toml_case("(good input)", None, lambda t: t, True))
    m = "mass_without_motor_kg = 8.219"
    r = "radius_m = 0.052"
    cases += [
        toml_case("negative mass", m, "mass_without_motor_kg = -8.219"),
        toml_case("zero mass", m, "mass_without_motor_kg = 0"),
        toml_case("mass as a string", m, 'mass_without_motor_kg = "8.219"'),
        toml_case("mass in grams", m, "mass_without_motor_kg = 8219"),
        toml_case("misspelt mass key", m, "mass_without_motr_kg = 8.219"),
        toml_case("negative radius", r, "radius_m = -0.052"),
        toml_case("radius in mm", r, "radius_m = 52"),
        toml_case("radius as diameter (0.104)", r, "radius_m = 0.104"),
        toml_case("radius nan", r, "radius_m = nan"),
        toml_case("radius inf", r, "radius_m = inf"),
        toml_case(
            "negative propellant mass",
            "propellant_initial_mass_kg = 1.913",
            "propellant_initial_mass_kg = -1.913",
        ),
        toml_case(
            "propellant mass 100x",
            "propellant_initial_mass_kg = 1.913",
            "propellant_initial_mass_kg = 191.3",
        ),
        toml_case("negative motor dry mass", "dry_mass_kg = 0.0", "dry_mass_kg = -3.0"),
        toml_case(
            "motor dry mass as a string", "dry_mass_kg = 0.0", 'dry_mass_kg = "0.5"'
        ),
        toml_case(
            "misspelt optional key (holddown_time)",
            "burn_time_s = 3.8",
            "burn_time_s = 3.8\nholddown_time = 1.0",
        ),
        toml_case(
            "negative holddown",
            "burn_time_s = 3.8",
            "burn_time_s = 3.8\nholddown_time_s = -1.0",
        ),
        toml_case("negative rail length", "rail_length_m = 12", "rail_length_m = -12"),
        toml_case(
            "rail length in feet (39.4)", "rail_length_m = 12", "rail_length_m = 39.4"
        ),
        toml_case("inclination 120", "inclination_deg = 84", "inclination_deg = 120"),
        toml_case(
            "inclination from vertical (6)",
            "inclination_deg = 84",
            "inclination_deg = 6",
        ),
        toml_case(
            "elevation in feet huge (1e6)", "elevation_m = 150", "elevation_m = 1e6"
        ),
        toml_case(
            "elevation negative (-500)", "elevation_m = 150", "elevation_m = -500"
        ),
        toml_case("elevation as a string", "elevation_m = 150", 'elevation_m = "150"'),
        toml_case("heading nan", "heading_deg = 133", "heading_deg = nan"),
        toml_case(
            "latitude 139", "latitude_deg = 39.388692", "latitude_deg = 139.388692"
        ),
        toml_case(
            "thrust_file a number",
            'thrust_file = "motor/Cesaroni_3618L995-P.eng"',
            "thrust_file = 5",
        ),
        toml_case(
            "thrust_file missing file",
            'thrust_file = "motor/Cesaroni_3618L995-P.eng"',
            'thrust_file = "motor/nope.eng"',
        ),
        toml_case(
            "thrust_file a directory",
            'thrust_file = "motor/Cesaroni_3618L995-P.eng"',
            'thrust_file = "motor"',
        ),
        toml_case(
            "drag file missing",
            'power_off_drag_file = "drag/drag_coefficient_power_off.csv"',
            'power_off_drag_file = "drag/nope.csv"',
        ),
        toml_case(
            "drag file a list",
            'power_off_drag_file = "drag/drag_coefficient_power_off.csv"',
            'power_off_drag_file = ["drag/drag_coefficient_power_off.csv"]',
        ),
        toml_case(
            "log file missing",
            'file = "logs/altimeter_cavour.csv"',
            'file = "logs/nope.csv"',
        ),
        toml_case(
            "log file a directory",
            'file = "logs/altimeter_cavour.csv"',
            'file = "logs"',
        ),
        toml_case(
            "log file a number", 'file = "logs/altimeter_cavour.csv"', "file = 3"
        ),
        toml_case("[rocket] missing", "[rocket]\n", "[rockett]\n"),
        toml_case(
            "[rocket] a value not a table",
            "[rocket]\nmass_without",
            "rocket = 1\n[rocketx]\nmass_without",
        ),
        toml_case(
            "temperature in Celsius",
            None,
            lambda t: t.replace(
                "[atmosphere]", "[atmosphere]\nsurface_temperature_K = 23"
            ),
        ),
        toml_case(
            "recorded apogee as a string",
            "recorded_apogee_agl_m = 2789",
            'recorded_apogee_agl_m = "2789"',
        ),
        toml_case("TOML syntax error", "radius_m = 0.052", "radius_m = 0.052 0.1"),
        toml_case(
            "duplicate key", "radius_m = 0.052", "radius_m = 0.052\nradius_m = 0.06"
        ),
        toml_case(
            "parachute with negative CdS",
            "[parachutes]\nnone = ",
            "[[parachutes]]\ncd_s_m2 = -1.0\n[x]\nnone = ",
        ),
        toml_case("empty rocket.toml", None, lambda t: ""),
    ]
    for mid, kind in (
        ("latin-1 rocket.toml", "latin"),
        ("binary rocket.toml", "binary"),
        ("rocket.toml a directory", "dir"),
        ("rocket.toml missing", "missing"),
    ):

        def build(tmp, kind=kind):
            d = copy(tmp, CAVOUR)
            p = d / "rocket.toml"
            if kind == "latin":
                p.write_bytes(
                    p.read_text()
                    .replace("Politecnico", "Polit\u00e9cnico")
                    .encode("latin-1")
                )
            elif kind == "binary":
                p.write_bytes(np.random.default_rng(3).bytes(2000))
            elif kind == "dir":
                p.unlink()
                p.mkdir()
            else:
                p.unlink()
            return [
                "rocket",
                "fit",
                p,
                "--no-sensor-spread",
                "--out",
                tmp / "out",
                "--json",
            ], ["rocket.toml"]

        cases.append(Case("rocket.toml (cavour)", mid, build, False, "rocket", True))

    def file_case(group, mid, rel, damage, fine=False, flight=CAVOUR):
        def build(tmp):
            d = copy(tmp, flight)
            p = d / rel
            damage(p)
            return [
                "rocket",
                "fit",
                d / "rocket.toml",
                "--no-sensor-spread",
                "--out",
                tmp / "out",
                "--json",
            ], [p.name]

        base = "rocket.toml (cavour)" if flight == CAVOUR else None
        return Case(group, mid, build, fine, "rocket", True, base)

    def lines_edit(fn):
        def damage(p):
            lines = p.read_text().splitlines()
            p.write_text("\n".join(fn(lines)) + "\n")

        return damage

    def column_edit(col, fn, start=1):
        def edit(lines):
            out = list(lines[:start])
            for ln in lines[start:]:
                parts = ln.replace(",", " ").split()
                if len(parts) > col:
                    parts[col] = fn(parts[col])
                    out.append(" ".join(parts) if "," not in ln else ",".join(parts))
                else:
                    out.append(ln)
            return out

        return lines_edit(edit)

    eng = "motor/Cesaroni_3618L995-P.eng"
    g = "motor .eng (cavour)"
    cases += [
        file_case(g, "zero thrust everywhere", eng, column_edit(1, lambda v: "0")),
        file_case(
            g, "negative thrust everywhere", eng, column_edit(1, lambda v: "-" + v)
        ),
        file_case(
            g,
            "one negative thrust point",
            eng,
            lines_edit(lambda ls: ls[:5] + [ls[5].split()[0] + " -50"] + ls[6:]),
        ),
        file_case(
            g,
            "thrust in lbf (x0.2248)",
            eng,
            column_edit(1, lambda v: repr(float(v) * 0.2248)),
        ),
        file_case(
            g, "time in ms", eng, column_edit(0, lambda v: repr(float(v) * 1000))
        ),
        file_case(
            g,
            "header with wrong fields",
            eng,
            lines_edit(lambda ls: ["L995 seventy-five long"] + ls[1:]),
        ),
        file_case(g, "header missing", eng, lines_edit(lambda ls: ls[1:])),
        file_case(
            g,
            "time not increasing",
            eng,
            lines_edit(lambda ls: ls[:3] + [ls[4], ls[3]] + ls[5:]),
        ),
        file_case(
            g, "a text point", eng, lines_edit(lambda ls: ls[:4] + ["0.1 abc"] + ls[5:])
        ),
        file_case(
            g, "a nan point", eng, lines_edit(lambda ls: ls[:4] + ["0.1 nan"] + ls[5:])
        ),
        file_case(
            g,
            "a huge point (1e30 N)",
            eng,
            lines_edit(lambda ls: ls[:4] + [ls[4].split()[0] + " 1e30"] + ls[5:]),
        ),
        file_case(
            g, "only the header and one point", eng, lines_edit(lambda ls: ls[:2])
        ),
        file_case(g, "truncated mid-row", eng, text_damage("truncated")),
        file_case(g, "empty .eng", eng, text_damage("empty")),
        file_case(g, "binary .eng", eng, text_damage("binary")),
        file_case(g, "UTF-16 .eng", eng, text_damage("utf-16")),
    ]
    drag = "drag/drag_coefficient_power_off.csv"
    g = "drag curve (cavour)"
    cases += [
        file_case(g, "negative CD", drag, column_edit(1, lambda v: "-" + v, start=0)),
        file_case(
            g,
            "CD 100x (percent)",
            drag,
            column_edit(1, lambda v: repr(float(v) * 100), start=0),
        ),
        file_case(
            g, "a nan CD", drag, lines_edit(lambda ls: ls[:4] + ["0.1,nan"] + ls[5:])
        ),
        file_case(
            g, "a text cell", drag, lines_edit(lambda ls: ls[:4] + ["0.1,abc"] + ls[5:])
        ),
        file_case(g, "one row", drag, lines_edit(lambda ls: ls[:1])),
        file_case(g, "empty drag file", drag, text_damage("empty")),
        file_case(g, "binary drag file", drag, text_damage("binary")),
        file_case(
            g,
            "Mach and CD swapped",
            drag,
            lines_edit(lambda ls: [",".join(reversed(ln.split(","))) for ln in ls]),
        ),
    ]
    log = "logs/altimeter_cavour.csv"
    g = "rocket log (cavour)"
    cases += [
        file_case(g, "truncated mid-row", log, text_damage("truncated")),
        file_case(g, "empty log", log, text_damage("empty")),
        file_case(g, "binary log", log, text_damage("binary")),
        file_case(g, "UTF-16 log", log, text_damage("utf-16")),
        file_case(
            g,
            "altitude column renamed",
            log,
            lines_edit(lambda ls: [ls[0].replace("altitude[m]", "hoehe")] + ls[1:]),
        ),
        file_case(
            g,
            "altitude in feet, header says m",
            log,
            column_edit(1, lambda v: repr(float(v) * 3.28084)),
        ),
        file_case(
            g,
            "a nan altitude",
            log,
            lines_edit(
                lambda ls: (
                    ls[:100]
                    + [
                        ",".join(
                            [ls[100].split(",")[0], "nan"] + ls[100].split(",")[2:]
                        )
                    ]
                    + ls[101:]
                )
            ),
        ),
        file_case(
            g,
            "a text altitude",
            log,
            lines_edit(
                lambda ls: (
                    ls[:100]
                    + [
                        ",".join(
                            [ls[100].split(",")[0], "abc"] + ls[100].split(",")[2:]
                        )
                    ]
                    + ls[101:]
                )
            ),
        ),
        file_case(
            g,
            "a huge altitude (1e300)",
            log,
            lines_edit(
                lambda ls: (
                    ls[:100]
                    + [
                        ",".join(
                            [ls[100].split(",")[0], "1e300"] + ls[100].split(",")[2:]
                        )
                    ]
                    + ls[101:]
                )
            ),
        ),
        file_case(
            g,
            "duplicate rows",
            log,
            lines_edit(lambda ls: ls[:50] + [ls[50]] + ls[50:]),
        ),
        file_case(
            g,
            "two rows swapped",
            log,
            lines_edit(lambda ls: ls[:50] + [ls[51], ls[50]] + ls[52:]),
        ),
        file_case(g, "header only", log, lines_edit(lambda ls: ls[:1])),
        file_case(
            g, "time column in ms", log, column_edit(0, lambda v: repr(float(v) * 1000))
        ),
    ]
    thrust = "motor/thrust_curve.csv"
    g = "motor thrust CSV (andromeda)"
    cases += [
        file_case(g, "(good input)", thrust, lambda p: None, True, ANDROMEDA),
        file_case(
            g,
            "zero thrust everywhere",
            thrust,
            column_edit(1, lambda v: "0"),
            flight=ANDROMEDA,
        ),
        file_case(
            g,
            "a text cell",
            thrust,
            lines_edit(lambda ls: ls[:10] + ["0.5,abc"] + ls[11:]),
            flight=ANDROMEDA,
        ),
        file_case(
            g,
            "one column only",
            thrust,
            lines_edit(lambda ls: [ln.split(",")[0] for ln in ls]),
            flight=ANDROMEDA,
        ),
        file_case(
            g, "empty thrust CSV", thrust, text_damage("empty"), flight=ANDROMEDA
        ),
    ]
    return cases


def fit_table_cases():
    """Table damage through a fit: `fit flight.csv --model unstable_aircraft.py`."""
    names, units, rows = asc_table(UNSTABLE)
    mutations = [
        ("(good input)", keep, True),
        ("nan cell in an output", cell("AZ", "nan"), False),
        ("text cell in an input", cell("DE", "x"), False),
        ("an output constant (dead sensor)", constant("AZ"), False),
        ("an input constant (no excitation)", constant("DE"), False),
        ("two rows only", short_rows(2), False),
        ("three rows only", short_rows(3), False),
        ("q in deg/s, map says rad/s", scale_column("Q", 180 / math.pi), False),
        ("de in deg, map says rad", scale_column("DE", 180 / math.pi), False),
        ("time in ms", scale_column("T", 1000.0), False),
        ("corrupt value 1e12 in an input", cell("DE", "1e12"), False),
        ("duplicate time row", duplicate_row(), False),
        (
            "an unused column with text",
            lambda n, u, r: (n + ["NOTE"], u + ["-"], [x + ["ok"] for x in r]),
            True,
        ),
    ]
    cases = []
    for mid, m, fine in mutations:

        def build(tmp, m=m):
            n, u, r = m(names, units, rows)
            write_csv(tmp / "flight.csv", n, r)
            (tmp / "model.py").write_text(MODEL_SRC)
            return [
                "fit",
                "flight.csv",
                "--model",
                "model.py",
                "--out",
                "out",
                "--json",
            ], ["flight.csv"]

        cases.append(Case("aircraft fit (csv)", mid, build, fine, "fit", True))
    return cases


def all_cases():
    return (
        hfb_cases() + fit_table_cases() + map_cases() + model_cases() + rocket_cases()
    )


def sweep(only=None, workdir=None):
    cases = [c for c in all_cases() if only is None or c.group.startswith(only)]
    baselines, rows = {}, []
    for c in cases:
        with tempfile.TemporaryDirectory(dir=workdir) as tmp:
            tmp = pathlib.Path(tmp)
            try:
                args, where = c.build(tmp)
            except Exception as e:  # noqa: BLE001 (a case that cannot be built)
                rows.append(
                    {
                        "group": c.group,
                        "mutation": c.mutation,
                        "outcome": "not-built",
                        "message": repr(e)[:200],
                    }
                )
                continue
            rc, out, err, secs = run(args, tmp)
            if c.mutation == "(good input)":
                baselines[c.group] = numbers(c.kind, out)
            outcome, message = classify(
                rc, out, err, where, c.kind, baselines.get(c.base)
            )
            partial = []
            # exit 3 writes its report on purpose (it says why nothing was
            # estimated); exit 2, a traceback or a hang must leave nothing (an
            # --out folder the command made and left empty is harmless)
            if c.out and rc not in (0, 3) and (tmp / "out").exists():
                partial = sorted(p.name for p in (tmp / "out").rglob("*"))
            command = " ".join(
                str(a).replace(str(tmp) + "/", "") for a in ["diffpegasus", *args]
            )
            row = {
                "group": c.group,
                "mutation": c.mutation,
                "command": command,
                "fine": c.fine,
                "outcome": outcome,
                "message": message.replace(str(tmp) + "/", ""),
                "seconds": round(secs, 1),
            }
            if rc == 0:
                row["numbers"] = numbers(c.kind, out)
            if partial:
                row["partial"] = partial
            rows.append(row)
            flag = " PARTIAL" if partial else ""
            print(
                f"{c.group} | {c.mutation}: {outcome}{flag} {row['message'][:160]}",
                flush=True,
            )
    return rows


def reclassify(rows):
    """Apply the current rule of "names the place" to stored rows (the places from
    building each case again, without running it)."""
    where = {}
    for c in all_cases():
        with tempfile.TemporaryDirectory() as tmp:
            try:
                where[c.group, c.mutation] = c.build(pathlib.Path(tmp))[1]
            except Exception:  # noqa: BLE001, S112 (a case that cannot be built)
                continue
    for r in rows:
        w = where.get((r["group"], r["mutation"]))
        if r["outcome"] in ("error", "error-vague") and w is not None:
            named = any(x in r["message"] for x in w)
            r["outcome"] = "error" if named else "error-vague"
        if r["outcome"] == "fit-failed" and "partial" in r:
            r["written"] = r.pop("partial")  # exit 3 writes its report on purpose
    return rows


def counts(rows):
    out = {}
    for r in rows:
        out[r["outcome"]] = out.get(r["outcome"], 0) + 1
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", help="run only groups starting with this")
    ap.add_argument("--label", default="after", help="key in the results file")
    ap.add_argument(
        "--reclassify", action="store_true", help="re-apply the rules to stored runs"
    )
    ap.add_argument(
        "--table", action="store_true", help="print the stored runs' counts (markdown)"
    )
    a = ap.parse_args()
    if a.table:
        runs = json.loads(RESULTS.read_text())["runs"]
        order = ["error", "error-vague", "traceback", "hang", "fit-failed"]
        order += ["accepted-same", "accepted-close", "accepted-DIFFERENT", "accepted"]
        order += ["not-built"]
        print("| outcome | " + " | ".join(runs) + " |")
        print("|---|" + "---|" * len(runs))
        for o in order:
            print(
                f"| {o} | "
                + " | ".join(str(r["counts"].get(o, 0)) for r in runs.values())
                + " |"
            )
        partial = [sum("partial" in c for c in r["cases"]) for r in runs.values()]
        print(
            "| of which left files in --out | " + " | ".join(map(str, partial)) + " |"
        )
        sys.exit(0)
    if a.reclassify:
        old = json.loads(RESULTS.read_text())
        for run in old["runs"].values():
            run["cases"] = reclassify(run["cases"])
            run["counts"] = counts(run["cases"])
        RESULTS.write_text(json.dumps(old, indent=1) + "\n")
        print({k: v["counts"] for k, v in old["runs"].items()})
        sys.exit(0)
    rows = sweep(a.only)
    old = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    runs = old.setdefault("runs", {})
    if a.only and a.label in runs:
        # the groups run again (after a change to them) replace theirs in the run
        kept = [r for r in runs[a.label]["cases"] if not r["group"].startswith(a.only)]
        rows = kept + rows
        order = {c.group: k for k, c in enumerate(reversed(all_cases()))}
        rows.sort(key=lambda r: -order.get(r["group"], 0))
    runs[a.label] = {"counts": counts(rows), "cases": rows}
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(old, indent=1) + "\n")
    print(json.dumps(counts(rows)))
