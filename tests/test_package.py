"""The package's public surface loads on first use."""

import subprocess
import sys

import pytest

import diffpegasus as dp


@pytest.mark.parametrize("namespace", [dp, dp.pegasus, dp.lateral, dp.sixdof])
def test_every_public_name_resolves(namespace):
    for name in namespace.__all__:
        assert getattr(namespace, name) is not None, name
    assert set(namespace.__all__) <= set(dir(namespace))


def test_the_top_level_is_the_generic_vocabulary():
    # about 80 names, none of them one vehicle's (Pegasus has its own namespace)
    assert len(dp.__all__) <= 100
    assert not set(dp.__all__) & set(dp.pegasus.__all__)
    from diffpegasus import fit, RK4, simulate_model  # noqa: F401

    assert simulate_model.__name__ == "simulate"  # the one renamed name


def test_moved_names_resolve_for_one_release_with_a_warning():
    with pytest.warns(DeprecationWarning, match="diffpegasus.pegasus.simulate"):
        assert dp.simulate is dp.pegasus.simulate
    with pytest.warns(DeprecationWarning, match="diffpegasus.lateral"):
        assert dp.lateral_model is dp.lateral.lateral_model
    assert "simulate" not in dir(dp)


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
