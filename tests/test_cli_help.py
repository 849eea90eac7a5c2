"""The command line as a new user meets it: help on one screen, one-line summaries,
the same option names everywhere, `check --columns`, and the report helpers every
output folder and the demo use (cheap: nothing here fits or compiles)."""

import json

import pytest
from typer.testing import CliRunner

import diffpegasus as dp
from diffpegasus._cli import app
from diffpegasus._report._markdown import planted_versus_found, write_index
from diffpegasus._report._runs import unexplained_channels


runner = CliRunner()


def _help(*args):
    result = runner.invoke(app, [*args, "--help"], env={"COLUMNS": "100"})
    assert result.exit_code == 0, result.output
    return result.output


def test_top_level_help_fits_one_screen_and_groups_commands():
    text = _help()
    lines = text.splitlines()
    # about 40 lines at 100 columns is one terminal screen
    assert len(lines) <= 40, text
    assert max(len(line) for line in lines) <= 100
    for panel in ("Fit and diagnose", "Logs and simulation", "Reference"):
        assert panel in text
    # the everyday commands come before the thesis's tools
    assert text.index(" fit ") < text.index(" montecarlo ")
    assert text.index(" demo ") < text.index(" design-input ")


def test_every_command_summary_is_one_line():
    import typer.main

    group = typer.main.get_command(app)
    for name, command in group.commands.items():
        summary = (command.help or "").strip().split("\n\n")[0]
        # one short line: the listing shows it beside the name
        assert "\n" not in summary.strip() or len(summary) <= 90, (name, summary)
        assert len(" ".join(summary.split())) <= 90, (name, summary)


def test_version():
    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0
    assert result.output.strip() == f"diffpegasus {dp.__version__}"


@pytest.mark.parametrize(
    "command",
    [("fit",), ("compare",), ("diagnose",), ("estimate", "oem"), ("montecarlo",)],
)
def test_max_iter_wherever_a_fit_runs(command):
    assert "--max-iter" in _help(*command)


def test_estimate_nn_names_its_network_network():
    text = _help("estimate", "nn")
    assert "--network" in text and "--save-network" in text
    # --model is a model file in fit/compare/diagnose; the old spelling is hidden
    options = [
        line.strip("│ ").split()[0] for line in text.splitlines() if "│ --" in line
    ]
    assert "--network" in options
    assert "--model" not in options and "--save-model" not in options


def test_thesis_tools_say_they_are_pegasus_s():
    for command in (("estimate",), ("design-input",), ("montecarlo",)):
        assert "Pegasus" in _help(*command)


def test_no_outside_paths_or_spec_sections_in_help():
    group_text = [_help()]
    import typer.main

    for name in typer.main.get_command(app).commands:
        group_text.append(_help(name))
    text = "\n".join(group_text)
    for bad in ("SPEC", "README", "../shared", "/work/"):
        assert bad not in text


def _mapped_log(tmp_path, alpha_deg):
    csv = tmp_path / "log.csv"
    rows = [f"{0.1 * i:.1f},{a},{0.5 * i}" for i, a in enumerate(alpha_deg)]
    csv.write_text("time,AOA,QB\n" + "\n".join(rows) + "\n")
    cmap = tmp_path / "map.json"
    cmap.write_text(
        json.dumps(
            {
                "t": "time",
                "alpha": {"column": "AOA", "unit": "deg"},
                "q": {"column": "QB", "unit": "deg/s"},
            }
        )
    )
    return csv, cmap


def test_check_columns_reads_through_the_map(tmp_path):
    csv, cmap = _mapped_log(tmp_path, [2.0 + 0.1 * i for i in range(20)])
    result = runner.invoke(app, ["check", str(csv), "--columns", str(cmap), "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert out["ok"] and "20 samples at 10 Hz" in out["summary"]
    alpha = out["channels"]["alpha"]
    assert alpha["column"] == "AOA" and alpha["unit"] == "deg"
    # 2 deg in SI, against numpy's own conversion
    assert alpha["min_si"] == pytest.approx(0.03490658503988659, rel=1e-12)


def test_check_columns_bad_cell_is_one_line(tmp_path):
    csv, cmap = _mapped_log(tmp_path, [2.0] * 5)
    csv.write_text(csv.read_text().replace("0.3,2.0", "0.3,nan"))
    result = runner.invoke(app, ["check", str(csv), "--columns", str(cmap)])
    assert result.exit_code == 2
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:"), result.output
    assert "AOA" in lines[0] and "row 4" in lines[0]


def test_index_page_lists_the_folder(tmp_path):
    for name in ("compare.md", "compare.png", "regimes.png", "oem_estimates.csv"):
        (tmp_path / name).write_text("x")
    (tmp_path / ".compare.md.123.tmp").write_text("staged")
    path = write_index(tmp_path, "compare: flight.csv")
    text = path.read_text()
    assert text.startswith("# compare: flight.csv")
    rows = [line for line in text.splitlines() if line.startswith("| [")]
    assert [r.split("]")[0][3:] for r in rows] == [
        "compare.md",
        "compare.png",
        "regimes.png",
        "oem_estimates.csv",
    ]
    assert "OEM derivative estimates" in text and ".tmp" not in text


def test_planted_versus_found_line():
    effects = {
        "actuator_delay": {"parameter": "tau", "estimate": 0.02003, "stderr": 0.0003}
    }
    (line,) = planted_versus_found({"actuator_delay": 0.02}, effects)
    assert line == (
        "hidden actuator_delay 0.02 s, found 0.02003 s ± 0.0003 s "
        "(0.1 standard errors apart)"
    )
    (missed,) = planted_versus_found({"pitch_damping": -800.0}, effects)
    assert (
        missed
        == "hidden pitch_damping -800; not found (the refit added actuator_delay)"
    )


def test_channels_left_above_their_noise_are_named():
    metrics = {
        "channels": {
            "az": {"misfit_ratio": 3.3, "ljung_box_p": 1e-12},
            "q": {"misfit_ratio": 1.02, "ljung_box_p": 0.4},
            # large but white: noise the estimate missed, not a missing term
            "ax": {"misfit_ratio": 2.5, "ljung_box_p": 0.3},
        }
    }
    (row,) = unexplained_channels(metrics, ("actuator_delay",))
    assert row["channel"] == "az"
    assert row["message"].startswith(
        "az stays 3.3x its noise after the fit with actuator_delay"
    )
