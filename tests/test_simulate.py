"""The Pegasus flight: envelope, solver accuracy, batching."""

import jax
import numpy as np
import pytest

import diffpegasus as dp

from .helpers import nominal_flight, numpy_channels, short_config


@pytest.fixture(scope="module")
def flight():
    return nominal_flight()


def test_sampled_at_1khz_with_every_channel(flight):
    from diffpegasus._log._format import REQUIRED_CHANNELS, TRUTH_CHANNELS

    assert np.allclose(np.diff(flight["t"]), 1e-3)
    assert flight["t"][-1] == pytest.approx(80.3)
    for name in REQUIRED_CHANNELS + TRUTH_CHANNELS:
        assert name in flight, name
        assert np.all(np.isfinite(flight[name])), name


def test_burnout_envelope(flight):
    # SPEC section 2: burnout Mach 7.5-9.5 and altitude 50-70 km.
    assert 7.5 <= flight["mach"][-1] <= 9.5
    assert 50e3 <= flight["h"][-1] <= 70e3


def test_pull_up_and_climb(flight):
    t, gamma = flight["t"], np.rad2deg(flight["gamma"])
    assert gamma[t < 6].min() < -5, "falls after the drop"
    assert 25 <= gamma.max() <= 45, "pull-up to roughly 30-40 deg"
    climbing = t > 25
    assert np.all(np.diff(flight["h"][climbing]) > 0)


def test_alpha_inside_database_and_peak_dynamic_pressure(flight):
    lo, hi = dp.load_database().alpha_range
    assert lo <= flight["alpha"].min() and flight["alpha"].max() <= hi
    i = np.argmax(flight["qbar"])
    assert 50e3 <= flight["qbar"][i] <= 90e3
    assert 2.0 <= flight["mach"][i] <= 3.5


def test_truth_matches_database_at_samples(flight):
    db = dp.load_database()
    for i in [0, 10_000, 40_000, 80_000]:
        d = db.derivatives(flight["alpha"][i], flight["mach"][i])
        for name in dp.DERIVATIVE_NAMES:
            assert flight[f"true_{name}"][i] == pytest.approx(float(getattr(d, name)))


def test_total_coefficients_are_the_linear_model(flight):
    cl = flight["true_CLa"] * flight["alpha"] + flight["true_CLde"] * flight["de"]
    np.testing.assert_allclose(flight["true_CL"], cl, rtol=1e-12, atol=1e-14)


def test_moment_balance_from_logged_channels(flight):
    # Iyy qdot + Iyy_dot q = qbar S c CM + (xcp - xcg) m az  (no planted effects).
    lhs = flight["Iyy"] * flight["qdot"] + flight["Iyy_dot"] * flight["q"]
    fz = flight["mass"] * flight["az"]
    rhs = (
        flight["qbar"] * 13.5 * 2.48 * flight["true_CM"]
        + (flight["xcp"] - flight["xcg"]) * fz
    )
    np.testing.assert_allclose(lhs, rhs, rtol=1e-9, atol=1e-6 * np.abs(lhs).max())


def test_solver_step_converged():
    fine = numpy_channels(dp.simulate(short_config(dt=1.25e-3), noise=False))
    coarse = numpy_channels(dp.simulate(short_config(), noise=False))
    assert np.max(np.abs(fine["alpha"] - coarse["alpha"])) < 1e-5
    assert np.max(np.abs(fine["q"] - coarse["q"])) < 1e-5


def test_batch_equals_one_by_one():
    config = short_config(t_final=8.0)
    perturbations = dp.sample_perturbations(jax.random.key(7), 3)
    keys = jax.random.split(jax.random.key(8), 3)
    batch = dp.simulate_batch(config, keys, perturbations)
    for i in range(3):
        p = jax.tree_util.tree_map(lambda x, i=i: x[i], perturbations)
        single = dp.simulate(p.apply(config), keys[i])
        for name in ["alpha", "q", "az", "h", "true_CMa"]:
            np.testing.assert_allclose(
                np.asarray(batch.channels[name][i]),
                np.asarray(single.channels[name]),
                rtol=1e-10,
                atol=1e-12,
            )
    # the perturbations really differ between flights
    assert np.ptp(np.asarray(batch.channels["mass"][:, 0])) > 10


def test_noise_is_seeded_and_has_the_documented_size():
    config = short_config(sensors=dp.SensorModel())
    a = numpy_channels(dp.simulate(config, jax.random.key(1)))
    b = numpy_channels(dp.simulate(config, jax.random.key(1)))
    clean = numpy_channels(dp.simulate(config, noise=False))
    np.testing.assert_array_equal(a["az"], b["az"])
    for name, sigma in dp.SensorModel().sigma.items():
        assert np.std(a[name] - clean[name]) == pytest.approx(sigma, rel=0.1), name
    assert np.array_equal(a["mass"], clean["mass"])
