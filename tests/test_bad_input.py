"""Bad input never becomes a traceback or a silently wrong number (issue 19).

A table of crafted logs, sidecars and output paths, each run through the command
line in-process: exit code 2, one `error:` line holding the expected fragment, no
traceback. The logs start from `plausible_channels`, a flight that obeys the
kinematics and the standard atmosphere exactly, so each case fails only for the fault
planted in it; `test_the_clean_log_passes` keeps that premise honest.
"""

import json
import os
import stat

import numpy as np
import pytest
from typer.testing import CliRunner

import diffpegasus as dp
from diffpegasus._cli import app

from .test_log import plausible_channels


runner = CliRunner()
N = 200  # 2 s at 100 Hz: enough motion for the kinematic checks to judge
DEG = 180.0 / np.pi


def _csv(channels: dict[str, np.ndarray], extra: dict[str, list[str]] | None = None):
    names = list(channels) + list(extra or {})
    rows = [",".join(names)]
    for i in range(len(channels["t"])):
        cells = [repr(float(channels[c][i])) for c in channels]
        cells += [extra[c][i] for c in extra or {}]
        rows.append(",".join(cells))
    return "\n".join(rows) + "\n"


def _mutated(_flight=None, **changes) -> str:
    """The clean log as CSV text, with columns replaced by `changes[name](column)`."""
    c = plausible_channels(N, **(_flight or {}))
    for name, f in changes.items():
        c[name] = f(c[name])
    return _csv(c)


def _cell(row: int, column: str, text: str) -> str:
    """The clean log with one cell (1-based data row) replaced by raw text."""
    c = plausible_channels(N)
    lines = _csv(c).splitlines()
    cells = lines[row].split(",")
    cells[list(c).index(column)] = text
    lines[row] = ",".join(cells)
    return "\n".join(lines) + "\n"


def _one(i, v):
    def f(x):
        x = x.copy()
        x[i] = v
        return x

    return f


CLEAN = _csv(plausible_channels(N))

# (case id, CSV content (str or bytes), sidecar (dict, raw str or None), fragment)
CASES = [
    ("empty file", "", None, "the file is empty"),
    ("blank lines only", "\n \n\n", None, "the file is empty"),
    (
        "bom and missing alpha",
        "\ufeff" + CLEAN.replace("alpha", "alfa"),
        None,
        "missing channel(s) 'alpha'",
    ),
    ("header only", CLEAN.splitlines()[0] + "\n", None, "only 0 samples"),
    ("no header", "\n".join(CLEAN.splitlines()[1:]) + "\n", None, "no header row"),
    ("semicolons", CLEAN.replace(",", ";"), None, "separated by ';'"),
    ("binary garbage", bytes(range(256)) * 40, None, "not a UTF-8 text CSV"),
    ("upper-case T", CLEAN.replace("t,de", "T,de", 1), None, "case-sensitive"),
    (
        "duplicate column",
        CLEAN.replace(",xcp", ",xcg", 1),
        None,
        "column 'xcg' appears more than once",
    ),
    (
        "ragged row",
        CLEAN.replace("\n", ",1.0\n", 4).replace(",1.0", "", 3),
        None,
        "row 3 has 19 values, the header has 18",
    ),
    (
        "underscore number",
        _cell(7, "qbar", "23_000"),
        None,
        "column 'qbar', row 7: '23_000' is not a number",
    ),
    (
        "full-width digit",
        _cell(4, "V", "２５０"),
        None,
        "column 'V', row 4: '２５０' is not a number",
    ),
    ("empty cell", _cell(9, "az", ""), None, "column 'az', row 9: the cell is empty"),
    (
        "text in a channel",
        _cell(5, "ax", "n/a"),
        None,
        "column 'ax', row 5: 'n/a' is not a number",
    ),
    ("nan", _mutated(q=_one(16, np.nan)), None, "column 'q', row 17: value nan"),
    (
        "time backwards",
        _mutated(t=_one(10, 0.05)),
        None,
        "column 't', row 11: time 0.05 is not after 0.09",
    ),
    (
        "theta in degrees, small attitude",
        _mutated({"theta0": 0.02, "theta_amplitude": 0.03}, theta=lambda x: x * DEG),
        None,
        "theta looks like degrees",
    ),
    ("q in deg/s", _mutated(q=lambda x: x * DEG), None, "column 'q'"),
    (
        "q in deg/s below the rate limit",
        _mutated(q=lambda x: x * DEG / 10, qdot=lambda x: x / 10),
        None,
        "'theta' changes 0.1745 times",
    ),
    (
        "qdot in deg/s^2",
        _mutated(qdot=lambda x: x * DEG),
        None,
        "qdot looks like deg/s^2",
    ),
    (
        "negative qbar sample",
        _mutated(qbar=_one(42, -150.0)),
        None,
        "column 'qbar', row 43: value -150.0 is negative",
    ),
    ("qbar in kPa", _mutated(qbar=lambda x: x / 1000), None, "qbar looks like kPa"),
    (
        "qbar in psf",
        _mutated(qbar=lambda x: x / 47.880259),
        None,
        "qbar looks like lbf/ft^2",
    ),
    ("V in knots", _mutated(V=lambda x: x * 1.943844), None, "V looks like knots"),
    ("h in feet", _mutated(h=lambda x: x / 0.3048), None, "h (geometric, m)"),
    ("mach in percent", _mutated(mach=lambda x: x * 100), None, "column 'mach'"),
    (
        "accelerations 10x",
        _mutated(ax=lambda x: 10 * x, az=lambda x: 10 * x),
        None,
        "ax and az look 10 times too large",
    ),
    (
        "accelerations in g",
        _mutated(ax=lambda x: x / 9.80665, az=lambda x: x / 9.80665),
        None,
        "ax and az look like units of g",
    ),
    ("az positive up", _mutated(az=lambda x: -x), None, "az looks positive up"),
    ("mass 10x", _mutated(mass=lambda x: 10 * x), None, "the forces imply |CZ|"),
    ("thrust 100x", _mutated(thrust=lambda x: 100 * x), None, "the forces imply |CX|"),
    ("alpha in degrees", _mutated(alpha=lambda x: x * DEG), None, "column 'alpha'"),
    (
        "thrust in lbf logged as N",
        _mutated(thrust=lambda x: x / 4.4482216),
        None,
        "the forces imply a drag of",
    ),
    (
        "ax alone in g",
        _mutated(ax=lambda x: x / 9.80665),
        None,
        "'ax'",
    ),
    (
        "sample rate a word",
        CLEAN,
        {"sample_rate_hz": "fast"},
        'sample_rate_hz must be a positive number of Hz, got "fast"',
    ),
    (
        "S_ref true",
        CLEAN,
        {"S_ref": True},
        "S_ref must be a positive number of m^2, got true",
    ),
    ("S_ref string", CLEAN, {"S_ref": "13.5"}, "S_ref must be a positive number"),
    (
        "c_ref null",
        CLEAN,
        {"c_ref": None},
        "c_ref must be a positive number of m, got null",
    ),
    (
        "S_ref NaN",
        CLEAN,
        '{"S_ref": NaN}',
        "S_ref must be a positive number of m^2, got NaN",
    ),
    ("S_ref zero", CLEAN, {"S_ref": 0}, "S_ref must be a positive number"),
    ("seed fraction", CLEAN, {"seed": 1.5}, "seed must be an integer, got 1.5"),
    ("vehicle number", CLEAN, {"vehicle": 3}, "vehicle must be a string"),
    (
        "negative noise sigma",
        CLEAN,
        {"noise_sigmas": {"az": -1}},
        "noise_sigmas must be",
    ),
    ("hidden effects list", CLEAN, {"hidden_effects": [1]}, "hidden_effects must be"),
    ("unknown check", CLEAN, {"skip_checks": ["units"]}, "skip_checks must be a list"),
    ("sidecar not an object", CLEAN, "[1, 2]", "expected a JSON object"),
    ("sidecar not json", CLEAN, "{S_ref: 2", "not valid JSON"),
    (
        "sidecar rate disagrees",
        CLEAN,
        {"sample_rate_hz": 50},
        "sample_rate_hz 50 disagrees with the time column",
    ),
    ("c_ref in mm", CLEAN, {"c_ref": 2480.0}, "do not belong to one vehicle"),
    ("S_ref in cm^2", CLEAN, {"S_ref": 135000.0, "c_ref": 248.0}, "mass / S_ref"),
    (
        "S_ref a thousand times too small",
        CLEAN,
        {"S_ref": 0.0135, "c_ref": 0.0248},
        "mass / S_ref",
    ),
]


def _write(tmp_path, content, sidecar):
    path = tmp_path / "flight.csv"
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    if sidecar is not None:
        text = sidecar if isinstance(sidecar, str) else json.dumps(sidecar)
        path.with_suffix(".json").write_text(text)
    return path


def _assert_one_error(result, *fragments):
    err = result.stderr
    assert result.exit_code == 2, (result.exit_code, result.output)
    assert "Traceback" not in result.output + err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    return lines[0]


@pytest.mark.parametrize(
    "content, sidecar, fragment",
    [c[1:] for c in CASES],
    ids=[c[0] for c in CASES],
)
def test_bad_log_is_one_error_line(tmp_path, content, sidecar, fragment):
    path = _write(tmp_path, content, sidecar)
    line = _assert_one_error(runner.invoke(app, ["check", str(path)]), fragment)
    assert str(path.with_suffix("")) in line  # the log, or its sidecar
    assert "np.float64" not in line


def test_qbar_in_psi_hint_states_the_ratio(tmp_path):
    path = _write(tmp_path, _mutated(qbar=lambda x: x / 6894.757293168), None)
    line = _assert_one_error(
        runner.invoke(app, ["check", str(path)]), "qbar looks like psi"
    )
    # 1 psi = 6894.757 Pa: a qbar in psi reads 1/6894.757 = 0.000145 of 0.5 rho V^2
    assert "value 3.46" in line and "is 0.000145 times 0.5 rho V^2" in line


def test_the_clean_log_passes(tmp_path):
    path = _write(tmp_path, CLEAN, None)
    result = runner.invoke(app, ["check", str(path)])
    assert result.exit_code == 0, result.output
    # a BOM, an extra text column, an extra numeric column and a valid sidecar
    # (with a BOM of its own) change nothing
    c = plausible_channels(N)
    extra = {"comment": ["pilot: ok"] * N, "gps_lat": ["52.1"] * N}
    path = _write(tmp_path, "\ufeff" + _csv(c, extra), None)
    path.with_suffix(".json").write_text(
        "\ufeff" + json.dumps({"S_ref": 13.5, "c_ref": 2.48, "sample_rate_hz": 100})
    )
    result = runner.invoke(app, ["check", str(path)])
    assert result.exit_code == 0, result.output
    log = dp.read_log(path)
    assert "comment" not in log.channels and log["gps_lat"][0] == 52.1
    np.testing.assert_array_equal(log["qbar"], c["qbar"])


def test_skip_checks_lets_known_good_data_through(tmp_path):
    content = _mutated(mass=lambda x: 10 * x)
    # (a mass 10 times too large is seen by two checks: the coefficients, and the
    # drag it implies, which pushes)
    path = _write(tmp_path, content, {"skip_checks": ["coefficients", "drag"]})
    assert runner.invoke(app, ["check", str(path)]).exit_code == 0


def test_other_commands_read_through_the_same_checks(tmp_path):
    path = _write(tmp_path, CLEAN, {"sample_rate_hz": "fast"})
    for cmd in (["estimate", "lse"], ["estimate", "oem"], ["compare"], ["diagnose"]):
        _assert_one_error(runner.invoke(app, [*cmd, str(path)]), "sample_rate_hz")


def test_missing_file_and_folder_as_log(tmp_path):
    _assert_one_error(
        runner.invoke(app, ["check", str(tmp_path / "no.csv")]), "no such file"
    )
    _assert_one_error(runner.invoke(app, ["check", str(tmp_path)]), "is a folder")


# --out: every problem refused before any work, in one line


def _out_cases(tmp_path):
    afile = tmp_path / "afile.csv"
    afile.write_text("x")
    folder = tmp_path / "folder"
    folder.mkdir()
    return afile, folder


@pytest.mark.parametrize(
    "command", [["estimate", "lse"], ["estimate", "oem"], ["estimate", "nn"]]
)
def test_estimate_out_problems(tmp_path, command):
    afile, _ = _out_cases(tmp_path)
    log = _write(tmp_path, CLEAN, None)
    _assert_one_error(
        runner.invoke(app, [*command, str(log), "--out", str(afile)]),
        "is an existing file, not a folder",
    )
    _assert_one_error(
        runner.invoke(app, [*command, str(log), "--out", str(afile / "sub")]),
        "is a file, so nothing can be created under it",
    )


@pytest.mark.parametrize(
    "option, value, fragment",
    [
        ("--parameters", "hybird", "--parameters must be one of hybrid, linear"),
        ("--axes", "stability", "--axes must be body or wind"),
        ("--shooting", "triple", "--shooting must be single or multiple"),
    ],
)
def test_estimate_oem_options_refused_before_any_work(
    tmp_path, option, value, fragment
):
    # the log does not exist: a refused option is said first, before reading it
    missing = str(tmp_path / "never_read.csv")
    line = _assert_one_error(
        runner.invoke(app, ["estimate", "oem", missing, option, value]), fragment
    )
    assert repr(value) in line


def test_simulate_out_problems(tmp_path):
    afile, folder = _out_cases(tmp_path)
    _assert_one_error(
        runner.invoke(app, ["simulate", "--out", str(folder)]), "is a folder"
    )
    _assert_one_error(
        runner.invoke(app, ["simulate", "--out", str(afile / "f.csv")]),
        "is a file, so nothing can be created under it",
    )
    _assert_one_error(
        runner.invoke(app, ["simulate", "--out", str(afile / "a" / "b" / "f.csv")]),
        "is a file",
    )


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_unwritable_out(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        _assert_one_error(
            runner.invoke(app, ["simulate", "--out", str(locked / "f.csv")]),
            "no permission",
        )
        log = _write(tmp_path, CLEAN, None)
        _assert_one_error(
            runner.invoke(
                app, ["estimate", "lse", str(log), "--out", str(locked / "o")]
            ),
            "no permission",
        )
    finally:
        locked.chmod(0o700)


@pytest.mark.skipif(
    os.access("/proc/sys", os.W_OK), reason="/proc/sys is writable here"
)
def test_out_in_a_place_no_one_may_write(tmp_path):
    """Even root may not create files in /proc/sys: refused before simulating."""
    _assert_one_error(
        runner.invoke(app, ["simulate", "--out", "/proc/sys/flight.csv"]),
        "no permission to create anything in /proc/sys",
    )
    log = _write(tmp_path, CLEAN, None)
    _assert_one_error(
        runner.invoke(app, ["estimate", "lse", str(log), "--out", "/proc/sys/out"]),
        "no permission",
    )


def test_write_error_after_the_checks_is_one_line(tmp_path, monkeypatch):
    """A write that fails although the path looked fine (a full disk, a race) is
    still one line: here the log writer itself raises."""
    import diffpegasus._log._format as log_module

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied", str(tmp_path / "f.csv"))

    monkeypatch.setattr(log_module, "write_log", refuse)
    monkeypatch.setattr(
        "diffpegasus._registry._pegasus_simulator.simulate_pegasus_log",
        lambda *a, **k: object(),
    )
    _assert_one_error(
        runner.invoke(app, ["simulate", "--out", str(tmp_path / "f.csv")]),
        "f.csv: cannot write (Permission denied)",
    )


# Files the commands write get the user's permissions


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_written_files_follow_the_umask(tmp_path, umask):
    from .test_log import _log

    old = os.umask(umask)
    try:
        path = dp.write_log(tmp_path / "f.csv", _log())
    finally:
        os.umask(old)
    for p in (path, path.with_suffix(".json")):
        assert stat.S_IMODE(p.stat().st_mode) == 0o666 & ~umask


def test_rewriting_keeps_the_file_mode(tmp_path):
    from .test_log import _log

    path = dp.write_log(tmp_path / "f.csv", _log())
    path.chmod(0o640)
    dp.write_log(path, _log())
    assert stat.S_IMODE(path.stat().st_mode) == 0o640


# A failed fit says so and reports nothing


def _failed_oem(converged):
    import jax.numpy as jnp

    from diffpegasus._estimate import Estimates

    n = len(converged)
    ok = jnp.asarray(converged)
    values = jnp.where(ok[:, None], jnp.ones((n, 6)), jnp.nan)
    return Estimates(
        method="oem",
        window_start=jnp.arange(n) * 0.5,
        window_end=jnp.arange(n) * 0.5 + 0.5,
        values=values,
        stderr=values * 0.1,
        valid=ok,
        flags={"converged": ok, "iterations": jnp.full(n, 30)},
    )


@pytest.mark.parametrize("as_json", [True, False])
def test_oem_that_did_not_converge_says_so(tmp_path, monkeypatch, as_json):
    import diffpegasus._estimate as estimators

    monkeypatch.setattr(
        estimators, "estimate_oem", lambda log, **k: _failed_oem([False] * 3)
    )
    path = _write(tmp_path, CLEAN, None)
    args = ["estimate", "oem", str(path)] + (["--json"] if as_json else [])
    result = runner.invoke(app, args)
    assert result.exit_code == 3, result.output
    assert "error: the oem fit did not converge after 30 iterations" in result.stderr
    assert "Traceback" not in result.output
    if as_json:
        d = json.loads(result.stdout.strip().splitlines()[-1])
        assert "did not converge" in d["message"]
        assert all(v is None for col in d["estimates"].values() for v in col)
        assert all(v is None for col in d["stderr"].values() for v in col)
    else:
        rows = result.stdout.splitlines()[2:]
        assert len(rows) == 3
        assert all(row.split(" s ")[1].split() == ["-"] * 6 for row in rows)


def test_oem_with_some_failed_windows_nulls_them(tmp_path, monkeypatch):
    import diffpegasus._estimate as estimators

    monkeypatch.setattr(
        estimators, "estimate_oem", lambda log, **k: _failed_oem([True, False, True])
    )
    path = _write(tmp_path, CLEAN, None)
    result = runner.invoke(app, ["estimate", "oem", str(path), "--json"])
    assert result.exit_code == 0, result.output
    assert "warning: 1 of 3 windows did not converge" in result.stderr
    d = json.loads(result.stdout.strip().splitlines()[-1])
    assert d["estimates"]["CLa"] == [1.0 * np.pi / 180, None, 1.0 * np.pi / 180]


def test_compare_that_did_not_converge_reports_no_derivatives(tmp_path, monkeypatch):
    import diffpegasus._report._runs as discrepancy

    def failed(entry, log, out, **kwargs):
        (out / "compare.md").write_text("# compare\n| CLa | 4.1 |\n")
        return {
            "cost": 1.0,
            "converged": False,
            "iterations": 40,
            "channels": {},
            "localise": {"worst": []},
            "derivatives": [{"mach": 0.8, "CLa": [4.1, 0.1]}],
        }, None

    monkeypatch.setattr(discrepancy, "run_compare", failed)
    path = _write(tmp_path, CLEAN, None)
    out = tmp_path / "report"
    out.mkdir()
    result = runner.invoke(app, ["compare", str(path), "--json", "--out", str(out)])
    assert result.exit_code == 3, result.output
    assert "did not converge after 40 iterations" in result.stderr
    d = json.loads(result.stdout.strip().splitlines()[-1])
    assert d["derivatives"] is None and "did not converge" in d["message"]
    assert (out / "compare.md").read_text().startswith("> **the output-error fit")


# Very large logs: linear, streaming, or refused up front


def test_careful_reader_streams_in_blocks(tmp_path, monkeypatch):
    """A log with a text column takes the careful reader; with a tiny block size it
    still reads every row in order (the blocks are concatenated, not lost)."""
    import diffpegasus._log._format as log_module

    monkeypatch.setattr(log_module, "_BLOCK", 7)
    c = plausible_channels(N)
    path = _write(tmp_path, _csv(c, {"note": ["x"] * N}), None)
    log = dp.read_log(path)
    np.testing.assert_array_equal(log["t"], c["t"])
    assert "note" not in log.channels


def test_oversized_log_is_refused_before_reading(tmp_path, monkeypatch):
    import diffpegasus._log._format as log_module

    monkeypatch.setattr(log_module, "MAX_LOG_BYTES", 1000)
    path = _write(tmp_path, CLEAN, None)
    _assert_one_error(
        runner.invoke(app, ["check", str(path)]), "are refused", "split or decimate it"
    )


# Model files, column maps, data files and options of `fit --model`: a crafted case
# per class of mistake, each refused in one line before any fit is compiled.

SP_MODEL = """
import jax.numpy as jnp
import diffpegasus as dp

def rates(t, x, u, p):
    w, q = x
    return jnp.stack([p["Zw"] * w + 43.5 * q + p["Zde"] * u[0],
                      p["Mw"] * w + p["Mq"] * q + p["Mde"] * u[0]])

def observe(t, x, u, p):
    w, q = x
    return jnp.stack([p["Zw"] * w - 1.5 * q + p["Zde"] * u[0], w, q])

model = dp.Model(states=("w", "q"), inputs=("de",), outputs=("az", "w", "q"),
                 parameters={"Zw": -1.0, "Zde": -3.0, "Mw": -0.03, "Mq": -2.0,
                             "Mde": -12.0},
                 rates=rates, observe=observe)
"""
SP_MAP = {
    "t": "TIME",
    "de": {"column": "ELEV", "unit": "deg"},
    "az": "NZ",
    "w": "W",
    "q": {"column": "QB", "unit": "deg/s"},
}


def _sp_channels(n=60, dt=0.05):
    """A short-period response to an elevator doublet (Euler steps: the numbers only
    have to look like a flight, no case here is fitted)."""
    t = dt * np.arange(n)
    de = np.where(
        (t > 0.5) & (t < 1.0), 0.02, np.where((t >= 1.0) & (t < 1.5), -0.02, 0)
    )
    w, q = np.zeros(n), np.zeros(n)
    for i in range(n - 1):
        w[i + 1] = w[i] + dt * (-1.0 * w[i] + 43.5 * q[i] - 3.0 * de[i])
        q[i + 1] = q[i] + dt * (-0.03 * w[i] - 2.0 * q[i] - 12.0 * de[i])
    az = -1.0 * w - 1.5 * q - 3.0 * de
    return {"TIME": t, "ELEV": np.degrees(de), "NZ": az, "W": w, "QB": np.degrees(q)}


def _sp_csv(sep=",", **changes) -> str:
    c = _sp_channels()
    for k, f in changes.items():
        c[k] = f(c[k])
    rows = [sep.join(c)]
    rows += [sep.join(repr(float(c[k][i])) for k in c) for i in range(len(c["TIME"]))]
    return "\n".join(rows) + "\n"


SP_CSV = _sp_csv()


def _sp_lines(edit) -> str:
    lines = SP_CSV.splitlines()
    edit(lines)
    return "\n".join(lines) + "\n"


def _cell_of(row: int, column: str, text: str):
    def edit(lines):
        cells = lines[row].split(",")
        cells[lines[0].split(",").index(column)] = text
        lines[row] = ",".join(cells)

    return edit


def _numbers(sep=" ", decimal=".") -> str:
    c = _sp_channels()
    rows = []
    for i in range(len(c["TIME"])):
        rows.append(sep.join(f"{float(c[k][i]):.6f}".replace(".", decimal) for k in c))
    return "\n".join(rows) + "\n"


def _model(text: str) -> str:
    return SP_MODEL + text


# (id, files {name: str | bytes | dict (JSON)}, argv after `fit` with {d} the
# folder, fragments of the one error line)
FIT_CASES = [
    # column maps
    (
        "map in Latin-1",
        {
            "map.json": '{"t": "TIME", "de": {"column": "ELEV", "unit": "deg"}, '
            '"az": "NZ", "w": "W", "q": {"column": "QB", "unit": "deg/s"}} '
            "\n".replace("}} ", '}, "_c": "\xe9"}').encode("latin-1")
        },
        None,
        ["map.json: the column map is not UTF-8 text", "Latin-1"],
    ),
    (
        "map in UTF-16",
        {"map.json": json.dumps(SP_MAP).encode("utf-16")},
        None,
        ["map.json: the column map is UTF-16 text"],
    ),
    (
        "map names AZ in g, the file has az",
        {
            "data.csv": SP_CSV.replace("NZ", "az", 1),
            "map.json": {**SP_MAP, "az": {"column": "AZ", "unit": "g"}},
        },
        None,
        ["no column 'AZ' for channel 'az'", "the file has 'az'", "case-sensitive"],
    ),
    (
        "map names a column the file lacks, the channel's own name is there",
        {
            "data.csv": SP_CSV.replace("NZ", "az", 1),
            "map.json": {**SP_MAP, "az": {"column": "ACC_Z", "unit": "g"}},
        },
        None,
        ["no column 'ACC_Z' for channel 'az'", "although it has a column 'az'"],
    ),
    (
        "two channels on one column",
        {"map.json": {**SP_MAP, "w": "NZ"}},
        None,
        ["channels 'az' and 'w' both read column 'NZ'"],
    ),
    (
        "a JSON key twice",
        {"map.json": json.dumps(SP_MAP)[:-1] + ', "w": "QB"}'},
        None,
        ["map.json: key 'w' is given twice"],
    ),
    (
        "a time column and a step",
        {"map.json": {**SP_MAP, "t": {"column": "TIME", "step": 0.04}}},
        None,
        ["channel 't' has both a column ('TIME') and a step (0.04)"],
    ),
    (
        "a step the file's time column disagrees with",
        {
            "data.csv": SP_CSV.replace("TIME", "t", 1),
            "map.json": {**SP_MAP, "t": {"step": 0.04}},
        },
        None,
        ["a step of 0.04 s", "steps by 0.05 s"],
    ),
    (
        "an unknown unit",
        {"map.json": {**SP_MAP, "q": {"column": "QB", "unit": "deg/sec"}}},
        None,
        ["channel 'q': unknown unit 'deg/sec'"],
    ),
    (
        "scale zero",
        {"map.json": {**SP_MAP, "w": {"column": "W", "scale": 0}}},
        None,
        ["channel 'w': scale 0 is not usable"],
    ),
    ("map is a folder", {"map.json/x": "{}"}, None, ["cannot read the column map"]),
    (
        "a TOML key twice",
        {"map.toml": 't = "TIME"\nt = "T"\n'},
        ["{d}/data.csv", "--model", "{d}/m.py", "--columns", "{d}/map.toml"],
        ["map.toml: not a valid column map"],
    ),
    # data files
    (
        "decimal commas, blanks between columns",
        {"data.csv": _numbers(" ", ","), "map.json": {"t": {"step": 0.05}}},
        None,
        ["the numbers have decimal commas", "line 1"],
    ),
    (
        "decimal commas, semicolons between columns",
        {"data.csv": _sp_csv(";").replace(".", ",")},
        None,
        ["decimal commas"],
    ),
    (
        "semicolons between columns",
        {"data.csv": _sp_csv(";")},
        None,
        ["the columns are separated by ';'"],
    ),
    ("data in UTF-16", {"data.csv": SP_CSV.encode("utf-16")}, None, ["UTF-16"]),
    (
        "data in Latin-1",
        {"data.csv": SP_CSV.replace("QB", "Q\xb0", 1).encode("latin-1")},
        None,
        ["data.csv: not UTF-8 text", "Latin-1"],
    ),
    (
        "a Latin-1 byte past the first block",
        {"data.csv": (SP_CSV + "0,0,0,0,\xb5\n" * 20000).encode("latin-1")},
        None,
        ["data.csv: not UTF-8 text"],
    ),
    ("binary data", {"data.csv": bytes(range(256)) * 8}, None, ["binary file"]),
    (
        "az of 1e300",
        {"data.csv": _sp_csv(NZ=lambda x: np.where(np.arange(len(x)) == 9, 1e300, x))},
        None,
        ["column 'NZ' (channel 'az') row 10: value 1e+300 is too large"],
    ),
    (
        "a corrupt spike",
        {"data.csv": _sp_lines(_cell_of(20, "W", "3.5e12"))},
        None,
        ["column 'W' (channel 'w') row 20", "90th-percentile spread", "a corrupt cell"],
    ),
    (
        "two samples",
        {"data.csv": "\n".join(SP_CSV.splitlines()[:3]) + "\n"},
        None,
        ["only 2 sample(s)"],
    ),
    (
        "a record of zeros",
        {
            "data.csv": _sp_csv(
                ELEV=lambda x: 0 * x,
                NZ=lambda x: 0 * x,
                W=lambda x: 0 * x,
                QB=lambda x: 0 * x,
            )
        },
        None,
        ["column 'NZ' (output 'az') is 0 in all 60 rows"],
    ),
    (
        "time that stands still",
        {"data.csv": _sp_csv(TIME=lambda x: 0 * x)},
        None,
        ["time is not increasing at row 2"],
    ),
    ("data file is a folder", {"data.csv/x": "1"}, None, ["is a folder"]),
    ("empty data file", {"data.csv": ""}, None, ["the file is empty"]),
    (
        "header only",
        {"data.csv": SP_CSV.splitlines()[0] + "\n"},
        None,
        ["no rows of data after the header"],
    ),
    (
        "ragged row",
        {"data.csv": _sp_lines(lambda ls: ls.__setitem__(7, ls[7] + ",1.0"))},
        None,
        ["line 8 has 6 values, the header 5"],
    ),
    (
        "text in a mapped column",
        {"data.csv": _sp_lines(_cell_of(12, "NZ", "n/a"))},
        None,
        ["line 13, column 'NZ': 'n/a' is not a number"],
    ),
    (
        "a decimal comma in one cell",
        {"data.csv": _sp_lines(_cell_of(12, "NZ", '"-2,5"'))},
        None,
        ["line 13, column 'NZ'", "decimal comma"],
    ),
    (
        "a blank cell (NumPy's parser reads it as -1)",
        {"data.csv": _sp_lines(_cell_of(12, "W", " "))},
        None,
        ["line 13, column 'W': the cell is empty"],
    ),
    (
        "nan in a mapped column",
        {"data.csv": _sp_lines(_cell_of(5, "W", "nan"))},
        None,
        ["column 'W' (channel 'w') row 5: value nan is not finite"],
    ),
    (
        "one file twice by two spellings",
        {},
        [
            "{d}/data.csv",
            "{d}/./data.csv",
            "--model",
            "{d}/m.py",
            "--columns",
            "{d}/map.json",
        ],
        ["the same file as", "given twice"],
    ),
    (
        "a copy of the same record",
        {"copy.csv": SP_CSV},
        [
            "{d}/data.csv",
            "{d}/copy.csv",
            "--model",
            "{d}/m.py",
            "--columns",
            "{d}/map.json",
        ],
        ["copy.csv: the same inputs and outputs as", "data.csv"],
    ),
    # model files
    (
        "sys.exit(0) at import",
        {"m.py": _model("import sys\nsys.exit(0)\n")},
        None,
        ["m.py: line 19: the file calls sys.exit(0) at import"],
    ),
    (
        "an argument parser at import",
        {
            "m.py": _model(
                "import argparse\np = argparse.ArgumentParser()\n"
                "p.add_argument('--gain', required=True)\np.parse_args()\n"
            )
        },
        None,
        ["the file calls sys.exit(2) at import", "--gain"],
    ),
    (
        "input() at import",
        {"m.py": _model("input('gain? ')\n")},
        None,
        ["m.py: line 18: EOFError at import"],
    ),
    (
        "an exception at import",
        {"m.py": _model("x = 1 / 0\n")},
        None,
        ["m.py: line 18: ZeroDivisionError at import"],
    ),
    ("a syntax error", {"m.py": _model("def (:\n")}, None, ["SyntaxError"]),
    (
        "parameters={}",
        {
            "m.py": _model(
                "model = model.replace(parameters=(), start=(), fixed=())\n"
            ).replace(
                'parameters={"Zw": -1.0, "Zde": -3.0, "Mw": -0.03, "Mq": -2.0,\n'
                '                             "Mde": -12.0}',
                "parameters={}",
            )
        },
        None,
        ["the model has no parameters"],
    ),
    (
        "a NaN start value",
        {"m.py": SP_MODEL.replace('"Mw": -0.03', '"Mw": float("nan")')},
        None,
        ["parameter 'Mw' starts at nan"],
    ),
    (
        "an infinite start value",
        {"m.py": SP_MODEL.replace('"Mq": -2.0', '"Mq": float("inf")')},
        None,
        ["parameter 'Mq' starts at inf"],
    ),
    (
        "candidates names an unknown parameter",
        {"m.py": _model('candidates = ("Mqq",)\n')},
        None,
        ["candidates names 'Mqq', not a parameter of the model"],
    ),
    (
        "rates of the wrong length",
        {
            "m.py": SP_MODEL.replace(
                'return jnp.stack([p["Zw"] * w + 43.5 * q + p["Zde"] * u[0],\n'
                '                      p["Mw"]',
                'return jnp.stack([p["Mw"]',
            )
        },
        None,
        ["m.py: line 5: rates(t, x, u, p) returns 1 value(s); the model has 2"],
    ),
    (
        "x0 with NaN",
        {"m.py": _model('x0 = (0.0, float("nan"))\n')},
        None,
        ["x0 must be finite numbers"],
    ),
    (
        "process noise on an unknown state",
        {"m.py": _model('process_noise = ("theta",)\n')},
        None,
        ["process_noise names 'theta', not a state"],
    ),
    (
        "the model file's columns a list",
        {"m.py": _model('columns = ["TIME", "ELEV"]\n')},
        ["{d}/data.csv", "--model", "{d}/m.py"],
        ["m.py: columns: a column map is a dict", "got list"],
    ),
    (
        "the model file's columns with a bad unit",
        {"m.py": _model('columns = {"q": {"column": "QB", "unit": "degs"}}\n')},
        ["{d}/data.csv", "--model", "{d}/m.py"],
        ["m.py: columns: channel 'q': unknown unit 'degs'"],
    ),
    (
        "model file is a folder",
        {"m.py/x": "1"},
        None,
        ["m.py: is a folder, not a model file"],
    ),
    (
        "model file in Latin-1",
        {"m.py": ("# \xe9\n" + SP_MODEL).encode("latin-1")},
        None,
        ["the model file is not UTF-8 text"],
    ),
    (
        "read() that exits",
        {"m.py": _model("import sys\ndef read(path):\n    sys.exit(1)\n")},
        ["{d}/data.csv", "--model", "{d}/m.py"],
        ["m.py: line 20: the file calls sys.exit(1) in read("],
    ),
    # options
    (
        "--fix NAME=nan",
        {},
        [*("{d}/data.csv", "--model", "{d}/m.py"), "--fix", "Mw=nan"],
        ["--fix Mw=nan: 'nan' is not a finite number"],
    ),
    (
        "--fix twice for one parameter",
        {},
        [*("{d}/data.csv", "--model", "{d}/m.py"), "--fix", "Mw=0", "--fix", "Mw"],
        ["--fix is given twice for 'Mw'"],
    ),
    (
        "--fix an unknown parameter",
        {},
        [
            *("{d}/data.csv", "--model", "{d}/m.py", "--columns", "{d}/map.json"),
            "--fix",
            "Cmq=0",
        ],
        ["--fix Cmq=0: 'Cmq' is not a parameter"],
    ),
    (
        "--vehicle beside --model",
        {},
        ["{d}/data.csv", "--model", "{d}/m.py", "--vehicle", "hfb320"],
        ["--model", "and --vehicle hfb320 both say what to fit"],
    ),
    (
        "--shooting-interval 0",
        {},
        ["{d}/data.csv", "--model", "{d}/m.py", "--shooting-interval", "0"],
        ["--shooting-interval 0.0: must be a positive finite number"],
    ),
    (
        "--shooting-interval shorter than two samples",
        {},
        [
            *("{d}/data.csv", "--model", "{d}/m.py", "--columns", "{d}/map.json"),
            "--shooting-interval",
            "0.001",
        ],
        ["shooting interval 0.001 s is shorter than two sample steps (0.1 s)"],
    ),
    (
        "--process-noise with a NaN intensity",
        {},
        [
            *("{d}/data.csv", "--model", "{d}/m.py"),
            "--method",
            "fem",
            "--process-noise",
            "q=nan",
        ],
        ["--process-noise q=nan: 'nan' is not a finite number"],
    ),
]


def _fill(tmp_path, files):
    (tmp_path / "data.csv").write_text(SP_CSV)
    (tmp_path / "m.py").write_text(SP_MODEL)
    (tmp_path / "map.json").write_text(json.dumps(SP_MAP))
    for name, content in files.items():
        path = tmp_path / name
        for p in (path, *path.parents):
            if p == tmp_path:
                break
            if p.is_file():
                p.unlink()
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, dict):
            content = json.dumps(content)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")


@pytest.mark.parametrize(
    "files, argv, fragments", [c[1:] for c in FIT_CASES], ids=[c[0] for c in FIT_CASES]
)
def test_fit_input_mistakes_are_one_error_line(tmp_path, files, argv, fragments):
    _fill(tmp_path, files)
    if argv is None:
        columns = "map.toml" if "map.toml" in files else "map.json"
        argv = ["{d}/data.csv", "--model", "{d}/m.py", "--columns", f"{{d}}/{columns}"]
    args = ["fit", *(a.format(d=tmp_path) for a in argv), "--json"]
    result = runner.invoke(app, args)
    _assert_one_error(result, *fragments)
    assert result.stdout.strip() == ""  # --json: nothing but the one JSON object


def test_a_short_input_on_a_still_column_is_read_a_lone_spike_is_not(tmp_path):
    """The corrupt-cell rule on a column that is still (to rounding) but for a
    doublet shorter than a tenth of the record, as simulated inputs are: its
    90th-percentile spread is the rounding, the doublet a million times that, and
    it spans several samples, so it is read; one value alone is refused."""
    from diffpegasus._cli._runners import load_records
    from diffpegasus._estimate._modelfile import load_model_file

    elev = np.zeros(60)
    elev[[20, 30, 45]] = [1e-30, -5e-16, 2e-17]  # what the input sums leave
    elev[10:12], elev[13:15] = 1.5, -1.5  # 4 of 60 samples, deg
    (tmp_path / "data.csv").write_text(_sp_csv(ELEV=lambda x: elev))
    (tmp_path / "m.py").write_text(SP_MODEL)
    (tmp_path / "map.json").write_text(json.dumps(SP_MAP))
    spec = load_model_file(tmp_path / "m.py")
    (rec,) = load_records(spec, [tmp_path / "data.csv"], tmp_path / "map.json")
    np.testing.assert_allclose(rec.inputs[:, 0], np.radians(elev), rtol=1e-15)
    spike = elev.copy()
    spike[40] = 1.5
    (tmp_path / "data.csv").write_text(_sp_csv(ELEV=lambda x: spike))
    with pytest.raises(dp.LogError, match="row 41: value 1.5 .* a corrupt cell"):
        load_records(spec, [tmp_path / "data.csv"], tmp_path / "map.json")


def test_the_clean_fit_input_reads(tmp_path):
    """The premise of the table: the files every case starts from are fine."""
    from diffpegasus._cli._runners import load_records
    from diffpegasus._estimate._modelfile import load_model_file

    _fill(tmp_path, {})
    spec = load_model_file(tmp_path / "m.py")
    (rec,) = load_records(spec, [tmp_path / "data.csv"], tmp_path / "map.json")
    c = _sp_channels()
    np.testing.assert_allclose(rec.inputs[:, 0], np.radians(c["ELEV"]), rtol=1e-15)
    np.testing.assert_allclose(rec.measured[:, 2], np.radians(c["QB"]), rtol=1e-15)
    # a candidate the model would estimate is held, as diagnose_model holds it (it
    # was a ValueError after a whole fit)
    (tmp_path / "c.py").write_text(_model('candidates = ("Mq",)\n'))
    spec = load_model_file(tmp_path / "c.py")
    assert "Mq" in spec.model.fixed and spec.candidates == ("Mq",)


# Options: refused while the command line is parsed, before any file is read
OPTION_CASES = [
    (["simulate", "--duration", "-5"], "--duration -5.0: must be a positive"),
    (["simulate", "--duration", "inf"], "--duration inf: must be a positive"),
    (["simulate", "--sample-rate", "nan"], "--sample-rate nan: must be a positive"),
    (["simulate", "--sample-rate", "0"], "--sample-rate 0.0: must be a positive"),
    (
        ["simulate", "--hidden", "pitch_damping=nan"],
        "--hidden pitch_damping=nan: 'nan' is not a finite number",
    ),
    (["simulate", "--hidden", "pitch_damping"], "expected NAME=VALUE"),
    (["simulate", "--hidden", "=3"], "no name before '='"),
    (
        ["simulate", "--hidden", "pitch_damping=-800", "--hidden", "pitch_damping=1"],
        "--hidden is given twice for 'pitch_damping'",
    ),
    (
        ["fit", "{log}", "--add", "pitch_damping", "--rate", "0"],
        "--rate 0.0: must be a positive finite number",
    ),
    (
        ["fit", "{log}", "--add", "pitch_damping", "--node-interval", "-1"],
        "--node-interval -1.0: must be a positive",
    ),
    (["diagnose", "{log}", "--rate", "nan"], "--rate nan"),
    (["compare", "{log}", "--node-interval", "0"], "--node-interval 0.0"),
    (["demo", "--hidden", "actuator_delay=inf"], "'inf' is not a finite number"),
    (["demo", "--duration", "0"], "--duration 0.0: must be a positive"),
    (["estimate", "lse", "{log}", "--window", "0"], "--window 0.0: must be a positive"),
    (["estimate", "lse", "{log}", "--tol", "nan"], "--tol nan"),
    (
        ["estimate", "oem", "{log}", "--decimate", "0"],
        "--decimate 0: must be at least 1",
    ),
    (["estimate", "oem", "{log}", "--min-qbar", "nan"], "--min-qbar nan: not a finite"),
    (["estimate", "nn", "{log}", "--window", "-0.5"], "--window -0.5"),
    (["montecarlo", "--samples", "0"], "--samples 0: must be at least 1"),
    (["montecarlo", "--batch", "0"], "--batch 0: must be at least 1"),
    (["montecarlo", "--duration", "nan"], "--duration nan"),
    (
        ["fit", "{log}", "--vehicle", "hfb320", "--fix", "Cmq=1", "--fix", "Cmq=2"],
        "--fix is given twice for 'Cmq'",
    ),
]


@pytest.mark.parametrize(
    "argv, fragment", OPTION_CASES, ids=[" ".join(c[0]) for c in OPTION_CASES]
)
def test_bad_option_is_one_error_line(tmp_path, argv, fragment):
    # the log does not exist: a refused option is said first, before reading it
    log = str(tmp_path / "never_read.csv")
    out = tmp_path / "out"
    args = [a.format(log=log) for a in argv]
    if args[0] in ("simulate",):
        args += ["--out", str(out / "f.csv")]
    if args[0] in ("demo", "montecarlo"):
        args += ["--out", str(out)]
    _assert_one_error(runner.invoke(app, args), fragment)
    assert not out.exists()


# Logs and their sidecars are written as consistent pairs


def test_interrupted_log_write_leaves_a_pair_check_refuses(tmp_path, monkeypatch):
    """Interrupted between the two renames (the sidecar is renamed in first), the
    old CSV sits beside the new sidecar: its hash names the CSV it belongs to, so
    `check` refuses the pair; no temporary file is left behind."""
    import diffpegasus._log._format as log_module

    from .test_log import _log

    path = dp.write_log(tmp_path / "f.csv", _log())
    assert runner.invoke(app, ["check", str(path), "--help"]).exit_code == 0
    old_csv = path.read_bytes()
    new = _log()
    new.channels["q"] = new.channels["q"] * 1.01
    real_commit = log_module.commit

    def interrupted(tmp, final):
        if str(final).endswith(".csv"):
            raise KeyboardInterrupt  # Ctrl-C at the moment the CSV is renamed in
        return real_commit(tmp, final)

    monkeypatch.setattr(log_module, "commit", interrupted)
    with pytest.raises(KeyboardInterrupt):
        dp.write_log(path, new)
    assert path.read_bytes() == old_csv
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.csv", "f.json"]
    with pytest.raises(dp.LogError, match="the sidecar belongs to another version"):
        dp.read_log(path, plausibility=False)


def test_sidecar_hash_catches_an_edited_csv_and_can_be_dropped(tmp_path):
    from .test_log import _log

    path = dp.write_log(tmp_path / "f.csv", _log())
    dp.read_log(path, plausibility=False)  # the pair as written reads
    lines = path.read_text().splitlines()
    lines[3] = lines[3].replace(",", ", ", 1)  # the same numbers, other bytes
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(dp.LogError, match="an interrupted write, or an edited CSV"):
        dp.read_log(path, plausibility=False)
    meta = json.loads(path.with_suffix(".json").read_text())
    del meta["csv_sha256"]
    path.with_suffix(".json").write_text(json.dumps(meta))
    dp.read_log(path, plausibility=False)


def test_a_log_with_nan_is_never_written(tmp_path):
    from .test_log import _log

    log = _log()
    log.channels["az"][5] = np.nan
    with pytest.raises(dp.LogError, match="channel 'az', row 6: value nan"):
        dp.write_log(tmp_path / "f.csv", log)
    assert list(tmp_path.iterdir()) == []


def test_interrupted_figure_leaves_no_file(tmp_path):
    """A figure interrupted while it is encoded appears neither truncated under its
    name nor as a temporary file."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from diffpegasus._files import save_figure

    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    path = tmp_path / "fit.png"
    save_figure(fig, path, dpi=50)
    good = path.read_bytes()
    assert good.startswith(b"\x89PNG")

    def half_then_stop(f, **kwargs):
        f.write(good[: len(good) // 2])
        raise KeyboardInterrupt

    fig.savefig = half_then_stop
    with pytest.raises(KeyboardInterrupt):
        save_figure(fig, path, dpi=50)
    plt.close(fig)
    assert path.read_bytes() == good
    assert [p.name for p in tmp_path.iterdir()] == ["fit.png"]


# Unit mistakes inside the old factor-2 rule, on the HFB-320 flight record


@pytest.mark.parametrize(
    "column, factor, fragment",
    [
        ("TASCG", 1.943844, "V looks like knots"),
        ("AXCG", 1 / 9.80665, "ax looks like units of g"),
        ("AZCG", 1 / 9.80665, "'az'"),
    ],
    ids=["airspeed in knots", "ax in g", "az in g"],
)
def test_hfb320_unit_mistakes_within_factor_two(tmp_path, column, factor, fragment):
    from .test_oem import _require, hfb320

    _require(hfb320.DEFAULT_DATA)
    data = dp.read_asc(hfb320.DEFAULT_DATA)
    data[column] = data[column] * factor
    path = tmp_path / "hfb.csv"
    names = list(data)
    np.savetxt(
        path,
        np.column_stack([data[n] for n in names]),
        delimiter=",",
        header=",".join(names),
        comments="",
        fmt="%.10g",
    )
    args = ["fit", str(path), "--vehicle", "hfb320", "--json"]
    line = _assert_one_error(runner.invoke(app, args), fragment)
    assert str(path) in line


def test_hfb320_record_passes_the_tightened_checks():
    from .test_oem import _require, hfb320

    _require(hfb320.DEFAULT_DATA)
    spec = dp.vehicle_spec("hfb320") if hasattr(dp, "vehicle_spec") else None
    if spec is None:
        from diffpegasus._registry import vehicle_spec

        spec = vehicle_spec("hfb320")
    rec = dp.load_record(spec.model, hfb320.DEFAULT_DATA, spec.columns)
    assert rec.t.shape == (601,)


# A model file that prints keeps --json valid; a fit without excitation says so


def test_json_stays_valid_whatever_the_model_file_prints(tmp_path):
    chatty = SP_MODEL.replace(
        "def rates(t, x, u, p):\n",
        "print('loading my model')\ndef rates(t, x, u, p):\n    print('tracing')\n",
    )
    _fill(tmp_path, {"m.py": chatty})
    args = ["fit", str(tmp_path / "data.csv"), "--model", str(tmp_path / "m.py")]
    args += ["--columns", str(tmp_path / "map.json"), "--json"]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)  # the whole of stdout is one JSON object
    assert report["converged"] and "loading my model" in result.stderr


def test_constant_inputs_are_named_as_no_excitation():
    from diffpegasus._cli._runners import excitation_note

    model = dp.Model(
        states=("q",),
        inputs=("de",),
        outputs=("q",),
        parameters={"Mq": -1.0},
        rates=lambda t, x, u, p: -x,
        observe=lambda t, x, u, p: x,
    )
    t = np.arange(10) * 0.1
    still = dp.Record(t, np.full(10, 0.01), np.sin(t))
    moving = dp.Record(t, np.sin(t), np.sin(t))
    assert "nothing excites the vehicle" in excitation_note(model, [still, still])
    assert excitation_note(model, [still, moving]) is None


def test_block_reader_agrees_with_the_careful_reader(tmp_path, monkeypatch):
    """Blocks of a few lines (cut mid-line), only the mapped columns converted: the
    same numbers as the row-by-row reader; a ragged row in a later block is still
    found and named by it."""
    import diffpegasus._log._fastcsv as fastcsv
    from diffpegasus._log._table import open_table

    monkeypatch.setattr(fastcsv, "_BLOCK_BYTES", 97)
    path = tmp_path / "d.csv"
    path.write_text(SP_CSV.rstrip("\n"))  # and no newline after the last row
    table = open_table(path)
    fast = table.read(["QB", "TIME"])
    careful = table._read_carefully(["QB", "TIME"], [4, 0], drop_text=False)
    for k in ("QB", "TIME"):
        np.testing.assert_array_equal(fast[k], careful[k])
    assert len(fast["TIME"]) == 60
    path.write_text(_sp_lines(lambda ls: ls.__setitem__(50, ls[50] + ",7")))
    with pytest.raises(dp.LogError, match="line 51 has 6 values, the header 5"):
        open_table(path).read(["TIME"])
