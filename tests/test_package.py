"""The package's public surface loads on first use."""

import subprocess
import sys

import diffpegasus as dp


def test_every_public_name_resolves():
    assert len(dp.__all__) > 100
    for name in dp.__all__:
        assert getattr(dp, name) is not None, name
    assert set(dp.__all__) <= set(dir(dp))
    from diffpegasus import fit, RK4, simulate_model  # noqa: F401

    assert simulate_model.__name__ == "simulate"  # the one renamed name


def test_the_command_line_imports_only_what_it_runs():
    # a command that fits an HFB-320 log must not pay for the campaign, the neural
    # model, the diagnosis workflow, diffrax or matplotlib at start-up
    heavy = (
        "diffpegasus._campaign._montecarlo",
        "diffpegasus._estimate._nn",
        "diffpegasus._diagnose._workflow",
        "diffrax",
        "matplotlib",
    )
    code = (
        "import sys, diffpegasus._cli; "
        f"print([m for m in {heavy!r} if m in sys.modules])"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == "[]", out.stdout
