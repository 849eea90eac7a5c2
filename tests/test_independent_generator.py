"""The independent HFB-320 generator's planted effects (it is the reference the
diagnosis is checked against, so its own physics is checked here)."""

import numpy as np
import pytest

from . import independent_generator as gen


def test_gust_path_in_still_air_is_the_books_model():
    """The gusty flight is integrated in body axes (inertial u, w); in still air
    it must be the book's (V, alpha) equations. Measured agreement 5e-10 of each
    channel's range (DOP853 at rtol 1e-11); 1e-8 leaves room for the platform."""
    still, _ = gen.generate_hfb320(3, 20.0, noise=False)
    calm, meta = gen.generate_hfb320(3, 20.0, noise=False, gust_sigma=1e-12)
    assert meta["turbulence"]["sigma"] == 1e-12
    for name in ("V", "alpha", "theta", "q", "qdot", "ax", "az"):
        scale = np.ptp(still[name])
        assert np.max(np.abs(calm[name] - still[name])) < 1e-8 * scale, name


def test_gusts_move_the_air_data_and_not_the_logged_surface():
    """1 m/s gusts over 10 s: alpha scatters by less than sigma / V = 0.0096 rad
    (measured 0.0030 rad: the 5 s gust time constant is slow against the short
    period, which follows the slow part of the wind); the logged elevator is the
    commanded one."""
    still, _ = gen.generate_hfb320(3, 20.0, 10.0, noise=False)
    gusty, _ = gen.generate_hfb320(3, 20.0, 10.0, noise=False, gust_sigma=1.0)
    np.testing.assert_array_equal(gusty["de"], still["de"])
    assert 1e-3 < np.std(gusty["alpha"] - still["alpha"]) < 1e-2


def test_planted_bias_and_delay():
    """A sensor bias is the channel plus its value; an actuator delay leaves the
    logged surface and everything before the first step as they were, and moves
    the response after it."""
    clean, _ = gen.generate_hfb320(5, 10.0, noise=False)
    biased, meta = gen.generate_hfb320(
        5, 10.0, noise=False, effects={"sensor_bias:q": 0.002}
    )
    assert meta["hidden_effects"] == {"sensor_bias:q": 0.002}
    np.testing.assert_allclose(biased["q"] - clean["q"], 0.002, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(biased["az"], clean["az"])
    late, _ = gen.generate_hfb320(5, 10.0, noise=False, effects={"actuator_delay": 0.1})
    np.testing.assert_array_equal(late["de"], clean["de"])
    first = np.flatnonzero(np.diff(clean["de"]))[0] + 1
    np.testing.assert_allclose(late["q"][:first], clean["q"][:first], rtol=1e-9)
    assert np.max(np.abs(late["q"] - clean["q"])) > 0.1 * np.ptp(clean["q"])


def test_unknown_effect_is_refused():
    with pytest.raises(ValueError, match="unknown effects"):
        gen.generate_hfb320(0, 10.0, effects={"moment_offset": 0.01})
