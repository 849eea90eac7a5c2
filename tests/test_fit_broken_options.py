"""Options and model files that `experiments/broken_inputs_sweep.py` found ending in a
traceback, a singular fit or a garbled message: a shooting interval far beyond the
record, one output's bias asked for twice, a model file with a syntax error."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from diffpegasus._cli import app


MODEL = """
import diffpegasus as dp

model = dp.Model(
    states=("q",),
    inputs=("de",),
    outputs=("q",),
    parameters={"Mq": -1.5, "Mde": -8.0},
    rates=lambda t, x, u, p: p["Mq"] * x + p["Mde"] * u,
    observe=lambda t, x, u, p: x,
)
"""


@pytest.fixture
def flight(tmp_path):
    """A 4 s pitch-rate record (q' = -2 q - 10 de, exact steps) and its model file."""
    dt, n = 0.02, 200
    t = np.arange(n) * dt
    de = 0.05 * np.sign(np.sin(2.0 * t))
    q = np.zeros(n)
    a = np.exp(-2.0 * dt)
    for k in range(n - 1):
        q[k + 1] = a * q[k] + (1 - a) * (-10.0 / 2.0) * de[k]
    q += np.random.default_rng(0).normal(0.0, 1e-3, n)
    rows = "\n".join(
        f"{a:.3f},{b:.6f},{c:.6f}" for a, b, c in zip(t, de, q, strict=True)
    )
    (tmp_path / "flight.csv").write_text("t,de,q\n" + rows + "\n")
    (tmp_path / "model.py").write_text(MODEL)
    return tmp_path


def _fit(folder, *extra):
    return CliRunner().invoke(
        app,
        ["fit", str(folder / "flight.csv"), "--model", str(folder / "model.py")]
        + ["--json", *extra],
    )


def test_a_shooting_interval_beyond_the_record_is_one_segment(flight):
    """Before: --shooting-interval 1e9 asked for 149 GiB (a MemoryError traceback).
    An interval past the record's end is one segment, as 8 s on this 4 s record."""
    far = _fit(flight, "--shooting-interval", "1e9")
    assert far.exit_code == 0, far.output
    near = _fit(flight, "--shooting-interval", "8")
    got = json.loads(far.stdout)["estimates"]
    want = json.loads(near.stdout)["estimates"]
    assert got == pytest.approx(want, rel=1e-9)


def test_one_bias_given_twice_is_refused(flight, tmp_path):
    """Before: two biases on one output made a singular fit (exit 3) and a report."""
    res = _fit(flight, "--bias", "q", "--bias", "q", "--out", str(tmp_path / "out"))
    assert res.exit_code == 2
    assert res.output.strip().splitlines()[-1] == (
        "error: bias on 'q' given twice; give each output once"
    )
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_a_syntax_error_names_its_line(flight):
    """Before: `model.py:: SyntaxError at import` (no line, a doubled colon)."""
    path = flight / "model.py"
    path.write_text(MODEL.replace("import diffpegasus as dp", "import diffpegasus as"))
    res = _fit(flight)
    assert res.exit_code == 2
    last = res.output.strip().splitlines()[-1]
    assert last.startswith(f"error: {path}: line 2: SyntaxError at import"), last


def test_check_refuses_a_record_too_short_to_fit(tmp_path):
    """`check --columns` on two rows: before, `ok; 2 samples`, which `fit` refuses."""
    (tmp_path / "log.csv").write_text("time,QB\n0.0,0.1\n0.1,0.2\n")
    (tmp_path / "map.json").write_text('{"t": "time", "q": "QB"}')
    res = CliRunner().invoke(
        app,
        ["check", str(tmp_path / "log.csv"), "--columns", str(tmp_path / "map.json")],
    )
    assert res.exit_code == 2
    assert res.output.strip().splitlines() == [
        f"error: {tmp_path / 'log.csv'}: only 2 sample(s); a record needs at least 3 "
        "(two steps of the dynamics)"
    ]
