"""The command line, run in-process (typer's runner) and once as the installed script."""

import json
import subprocess
import sys

import numpy as np
from typer.testing import CliRunner

import diffpegasus as dp
from diffpegasus._cli import app


runner = CliRunner()


def test_simulate_writes_log_sidecar_and_plot(tmp_path):
    out = tmp_path / "f.csv"
    result = runner.invoke(
        app,
        [
            "simulate",
            "--seed",
            "2",
            "--out",
            str(out),
            "--duration",
            "6",
            "--sample-rate",
            "100",
            "--hidden",
            "sensor_bias:az=0.25",
            "--hidden",
            "pitch_damping=-300",
            "--perturb",
        ],
    )
    assert result.exit_code == 0, result.output
    log = dp.read_log(out)
    assert log.has_truth and log.t[-1] == 6.0
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["seed"] == 2
    assert meta["hidden_effects"] == {"sensor_bias:az": 0.25, "pitch_damping": -300.0}
    assert set(meta["perturbation"]) == {
        "lift",
        "drag",
        "moment",
        "mass",
        "thrust",
        "cg_shift",
    }
    assert meta["noise_sigmas"]["az"] == 0.05
    png = out.with_suffix(".png")
    assert png.exists() and png.read_bytes()[:4] == b"\x89PNG"
    # the perturbation was applied
    assert abs(log["mass"][0] - 18_505.0) > 1.0


def test_bad_hidden_effect_is_one_line(tmp_path):
    result = runner.invoke(
        app, ["simulate", "--out", str(tmp_path / "f.csv"), "--hidden", "wind=3"]
    )
    assert result.exit_code == 2
    assert "unknown effect 'wind'" in result.output
    assert "Traceback" not in result.output


def test_check_reports_bad_log_in_one_line(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("t,de\n0,0\n0.1,0\n")
    result = runner.invoke(app, ["check", str(path)])
    assert result.exit_code == 2
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert (
        len(lines) == 1
        and lines[0].startswith("error:")
        and "missing channel" in lines[0]
    )


def test_effects_listing():
    result = runner.invoke(app, ["effects", "--json"])
    assert result.exit_code == 0
    names = {r["effect"] for r in json.loads(result.output)}
    assert "sensor_bias:<channel>" in names and "vertical_wind" in names


def test_installed_script_help():
    # one new process checks the `python -m diffpegasus` entry (each costs ~1.5
    # CPU-s of imports); the subcommands' help is the same app, parsed in-process
    out = subprocess.run(
        [sys.executable, "-m", "diffpegasus", "--help"], capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    assert "Usage" in out.stdout
    for args in [["simulate", "--help"], ["check", "--help"]]:
        result = runner.invoke(app, args)
        assert result.exit_code == 0, result.output
        assert "Usage" in result.output


def test_input_names_all_build():
    import jax

    from diffpegasus._simulate._inputs import excitation, EXCITATION_NAMES

    t = jax.numpy.linspace(0, 20, 2001)
    for name in EXCITATION_NAMES:
        de = np.asarray(jax.vmap(excitation(name))(t))
        assert np.all(np.isfinite(de))
        if name != "none":
            assert np.max(np.abs(de)) > 0
