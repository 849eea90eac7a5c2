"""Equation-error least squares: exact recovery, rank rule, windows, batching."""

import json
import pathlib
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

import diffpegasus as dp
from diffpegasus._vehicle._short_period import ShortPeriodModel

from .helpers import numpy_channels, short_config


EXPERIMENTS = pathlib.Path(__file__).resolve().parents[1] / "experiments"
sys.path.insert(0, str(EXPERIMENTS))
from input_design import INPUTS, study  # noqa: E402


def _short_period_fit(model, name):
    """The input-design experiment's own fit: estimates and truth per degree."""
    r = study(model, INPUTS[name])
    return r["estimates"], r["truth"], r["rank_ATA"], r["ok"]


@pytest.fixture(scope="module")
def constant_mach():
    return ShortPeriodModel(mach_start=2.0, mach_end=2.0, duration=20.0)


def test_exact_recovery_on_noise_free_linear_model(constant_mach):
    est, truth, _, ok = _short_period_fit(constant_mach, "sine")
    assert ok.all()
    np.testing.assert_allclose(est, truth, rtol=1e-8)


@pytest.mark.parametrize("name", ["ramp", "step"])
def test_ramp_and_step_are_rank_deficient(constant_mach, name):
    est, _, rank_ata, ok = _short_period_fit(constant_mach, name)
    assert not ok.any()
    assert (rank_ata < 3).all()
    assert np.isnan(est).all(), "no window ever had an estimate to hold"


def test_pulse_identifiable_at_its_edges_and_held_between(constant_mach):
    est, truth, _, ok = _short_period_fit(constant_mach, "pulse")
    assert 0 < ok.sum() < len(ok)
    assert ok[0] and ok[4] and ok[8], "windows holding the 4 s pulse edges"
    np.testing.assert_allclose(est[ok], truth[ok], rtol=1e-8)
    # a window between edges holds the previous estimate exactly
    assert not ok[2] and np.array_equal(est[2], est[1])


def test_window_layout_bookkeeping():
    lay = dp.WindowLayout.make(1000, 100.0, 0.5)  # 20 full windows of 50
    assert (lay.count, lay.per_window, lay.last) == (20, 50, 50)
    lay = dp.WindowLayout.make(1030, 100.0, 0.5)  # 30 left over: a partial window
    assert (lay.count, lay.last) == (21, 30)
    start, end = lay.times(2.0)
    assert start[0] == 2.0 and end[0] == pytest.approx(2.5)
    assert start[-1] == pytest.approx(12.0) and end[-1] == pytest.approx(12.3)
    assert float(lay.mask()[-1].sum()) == 30
    lay = dp.WindowLayout.make(1020, 100.0, 0.5)  # 20 left over: dropped
    assert (lay.count, lay.used) == (20, 1000)
    x = jnp.arange(1030.0)
    lay = dp.WindowLayout.make(1030, 100.0, 0.5)
    np.testing.assert_allclose(
        np.asarray(lay.window_mean(x))[-1], np.mean(np.arange(1000, 1030))
    )
    with pytest.raises(ValueError, match="fewer than one"):
        dp.WindowLayout.make(40, 100.0, 0.5)


@pytest.fixture(scope="module")
def flight():
    return numpy_channels(dp.simulate(short_config(), noise=False))


def test_reconstruction_matches_simulator_truth(flight):
    c = dp.reconstruct_coefficients(
        {k: jnp.asarray(v) for k, v in flight.items()}, 13.5, 2.48
    )
    for name in ("CL", "CD", "CM"):
        np.testing.assert_allclose(
            np.asarray(getattr(c, name)), flight[f"true_{name}"], rtol=1e-9, atol=1e-12
        )


def test_pegasus_estimates_track_truth():
    config = short_config(t_final=30.0, sample_rate=1000.0, sensors=dp.SensorModel())
    log = dp.flight_to_log(dp.simulate(config, jax.random.key(4)))
    est = dp.estimate_lse(log)
    mse = est.mse("deg", t_min=5.0)
    for name, value in mse.items():
        assert value < 2e-4, (name, value)
    assert len(est.window_start) == 60
    assert np.isfinite(np.asarray(est.stderr)[10:]).all()


def test_batched_equals_per_log():
    config = short_config(t_final=10.0)
    keys = jax.random.split(jax.random.key(0), 3)
    perturbations = dp.sample_perturbations(jax.random.key(1), 3)
    flights = dp.simulate_batch(config, keys, perturbations)
    channels = dict(flights.channels)
    layout = dp.WindowLayout.make(channels["az"].shape[1], 100.0, 0.5)
    batch = dp.lse_batch(channels, layout)
    for i in range(3):
        single = dp.lse_arrays({k: v[i] for k, v in channels.items()}, layout)
        # the same least squares summed in another order (vmapped vs single): the
        # worst window (t 0.5-1 s, before ignition) differs by 5.5e-12 relative
        np.testing.assert_allclose(
            np.asarray(batch["values"][i]),
            np.asarray(single["values"]),
            rtol=1e-10,
            equal_nan=True,
        )


def test_cli_json_follows_spec(tmp_path):
    from diffpegasus._cli import app

    config = short_config(t_final=8.0)
    path = dp.write_log(tmp_path / "f.csv", dp.flight_to_log(dp.simulate(config)))
    result = CliRunner().invoke(
        app, ["estimate", "lse", str(path), "--json", "--out", str(tmp_path / "out")]
    )
    assert result.exit_code == 0, result.output
    d = json.loads(result.stdout.strip().splitlines()[-1])
    assert d["method"] == "lse" and d["units"] == "1/deg"
    n = len(d["window_start"])
    assert n == 16 and len(d["window_end"]) == n
    assert set(d["estimates"]) == set(dp.DERIVATIVE_NAMES) == set(d["stderr"])
    assert all(len(v) == n for v in d["estimates"].values())
    assert {"rank_deficient", "rank_A", "rank_ATA"} <= set(d["flags"])
    assert (tmp_path / "out" / "lse_estimates.csv").exists()
    assert (tmp_path / "out" / "lse_estimates.png").exists()

    # --vehicle gives the reference geometry: the same log estimated as the user's
    # jet (examples/my_jet.py) scales CL and CD by S_ref and CM by S_ref c_ref
    jet = pathlib.Path(__file__).parents[1] / "examples" / "my_jet.py"
    other = CliRunner().invoke(
        app, ["estimate", "lse", str(path), "--json", "--vehicle", str(jet)]
    )
    assert other.exit_code == 0, other.output
    assert "replace the log's 13.5 m^2, 2.48 m" in other.stderr
    e = json.loads(other.stdout.strip().splitlines()[-1])["estimates"]
    s_jet = 4.028e-3 * 7472.0
    for name, ratio in (
        ("CLa", 13.5 / s_jet),
        ("CDde", 13.5 / s_jet),
        ("CMa", 13.5 * 2.48 / (s_jet * 1.215)),
    ):
        for ours, base in zip(e[name], d["estimates"][name], strict=True):
            if base is not None:
                assert ours == pytest.approx(base * ratio, rel=1e-9)
    bare = pathlib.Path(__file__).parents[1] / "examples" / "unstable_aircraft.py"
    refused = CliRunner().invoke(
        app, ["estimate", "lse", str(path), "--vehicle", str(bare)]
    )
    assert refused.exit_code == 2
    assert "a bare `model` has no geometry" in refused.output
