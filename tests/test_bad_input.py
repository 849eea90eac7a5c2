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
    path = _write(tmp_path, content, {"skip_checks": ["coefficients"]})
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
        "diffpegasus._vehicle._pegasus._simulator.simulate_pegasus_log",
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
    import diffpegasus._diagnose as discrepancy

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
