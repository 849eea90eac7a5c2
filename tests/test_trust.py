"""Trust on data we did not make (issue 15): the discrepancy workflow on logs of an
independent generator (`independent_generator.py`: numpy and scipy only, its own
atmosphere, aerodynamic table, motor, integrator, true-step elevator pulses, lower
noise, several sample rates).

The flights are 30 s from drop with the Pegasus reference geometry, so the model
has the shape of `test_discrepancy.py`'s and the compiled fit is shared.
"""

import ast
import functools
import pathlib
import sys

import numpy as np
import pytest

import diffpegasus as dp
from diffpegasus._diagnose._metrics import residual_noise_sigma
from diffpegasus._registry._pegasus import block_means, block_weights
from diffpegasus.discrepancy import diagnose, fit_log, fit_metrics, vehicle_entry

from . import independent_generator as gen


sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "experiments"))
from _shared import segment_projection  # noqa: E402


ENTRY = vehicle_entry("pegasus")


def fit(log, add=(), start=None):
    return fit_log(ENTRY, log, add, start=start)


HERE = pathlib.Path(__file__).parent


@functools.cache
def log(seed: int, rate: float, effect: tuple = ()) -> dp.FlightLog:
    """A generator log written to disk and read back through the log reader."""
    import tempfile

    folder = pathlib.Path(tempfile.mkdtemp(prefix="trust_"))
    name = "clean" if not effect else effect[0].replace(":", "_")
    path = gen.make_log(
        folder / f"{name}_{seed}_{int(rate)}.csv",
        seed,
        rate,
        30.0,
        dict([effect]) if effect else None,
    )
    return dp.read_log(path)


@functools.cache
def baseline(seed: int, rate: float, effect: tuple = ()):
    base = fit(log(seed, rate, effect))
    return base, diagnose(base)


def test_generator_shares_no_code_with_the_package():
    tree = ast.parse((HERE / "independent_generator.py").read_text())
    modules = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            modules |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            modules.add((node.module or "").split(".")[0])
    assert modules <= {"json", "pathlib", "numpy", "scipy"}, modules


def test_generator_log_format_and_sample_rates():
    # the logs the clean-flight validation tests below diagnose (made once, shared)
    for seed, rate in ((17, 1000.0), (3, 50.0)):
        lg = log(seed, rate)
        assert lg.sample_rate == pytest.approx(rate)
        assert lg.metadata["noise_sigmas"]["q"] == 2e-4
        assert lg.s_ref == 13.5 and lg.c_ref == 2.48
    # the same flight at both rates: the 50 Hz samples are the 1 kHz truth
    clean_fast = gen.generate(7, 1000.0, noise=False)[0]
    clean_slow = gen.generate(7, 50.0, noise=False)[0]
    np.testing.assert_allclose(
        clean_fast["alpha"][::20], clean_slow["alpha"], atol=1e-9
    )
    # elevator pulses are true steps: a jump within one 1 kHz sample
    assert np.max(np.abs(np.diff(clean_fast["de"]))) > np.deg2rad(1.4)


@pytest.mark.parametrize("step", [1, 2, 4, 5, 20])
def test_block_means_keep_a_step_on_time(step):
    # a unit step at a time between samples, sampled at 1/step of the model rate and
    # reduced by block means: the linear interpolant of the means has the step's
    # timing (its integral) to within half a log sample, zero on average over
    # where the step falls; picking every n-th sample moves it by up to a model
    # sample
    rng = np.random.default_rng(0)
    errors_mean, errors_pick = [], []
    n = 400 * step
    t = np.arange(n)
    for _ in range(200):
        s = rng.uniform(100 * step, 300 * step)
        x = (t >= s).astype(float)
        means, index = block_means(x, step)
        # time of the step implied by a piecewise-linear signal: t_end - integral
        centre = index[-1] - np.trapezoid(means, index)
        picked = index[-1] - np.trapezoid(x[index], index)
        errors_mean.append(centre - s)
        errors_pick.append(picked - s)
    errors_mean, errors_pick = np.array(errors_mean), np.array(errors_pick)
    # each log sample stands for its own interval: a step between samples is known
    # to half a sample
    assert np.max(np.abs(errors_mean)) <= 0.5 + 1e-9
    assert abs(np.mean(errors_mean)) < 0.1
    if step > 2:
        assert np.max(np.abs(errors_pick)) > 0.3 * step
    assert block_weights(step).sum() == pytest.approx(step)


def test_residual_noise_sigma_ignores_signal():
    from diffpegasus._diagnose._metrics import noise_sigma

    rng = np.random.default_rng(1)
    n = 1500
    noise = 0.01 * rng.normal(size=n)
    # a pulse train's edges in the measurement (qdot-like) and a slow structural
    # misfit the model leaves
    pulses = 0.1 * ((np.arange(n) // 25) % 2)
    slow = 0.05 * np.sin(np.linspace(0, 6, n))
    measured = pulses + slow + noise
    model = pulses
    sigma = residual_noise_sigma(measured - model)
    assert abs(sigma - 0.01) < 0.001, sigma  # the estimate's own scatter ~4%
    # second differences of the measurement count the edges as noise
    assert noise_sigma(measured) > 1.5 * 0.01


# Clean flights flag nothing the model and the generator agree on. Two differences
# between them were found this way (measured, see STRUCTURAL and gravity_shift
# below): the generator's gravity was 0.008 m/s^2 stronger than the package's
# Newton's law with the equatorial radius (an az bias), which is why the package
# now uses standard gravity, as its own atmosphere does; and the generator's Mach
# table changes faster after ignition than the baseline's six Mach functions
# follow (a thrust-misalignment-like moment of +0.003 to +0.007 m).
# Where the noise is low (1 kHz logs averaged to the model's 50 Hz) the rule
# calibrated on the log may report them, with their sizes; nothing else may be flagged.
# Seed 17 at 1 kHz: the largest of 20 clean flights (thrust-misalignment statistic
# 102). All three are validation tests (`-m validation`): a clean launch-vehicle
# flight of this generator flagging nothing is checked by default in
# tests/test_fem_pegasus.py (its calm flight); the false-alarm rate over many clean
# flights is measured by experiments/decision_rule.py.
@pytest.mark.parametrize(
    "seed,rate",
    [
        pytest.param(3, 1000.0, marks=pytest.mark.validation),
        pytest.param(3, 50.0, marks=pytest.mark.validation),
        pytest.param(17, 1000.0, marks=pytest.mark.validation),
    ],
)
def test_clean_generator_flights_flag_only_the_known_model_differences(seed, rate):
    base, result = baseline(seed, rate)
    assert base.converged
    assert set(result["significant"]) <= {"sensor_bias:az", "thrust_misalignment"}, (
        result["ranking"][:3]
    )
    for r in result["ranking"]:
        if r["significant"] and r["effect"] == "sensor_bias:az":
            # the gravity difference, and what remains with the package's gravity
            # patched into the generator (-0.0018 +/- 0.0017, seed 3 at 200 Hz)
            expected = -gravity_shift(log(seed, rate))
            assert abs(r["estimate"] - expected) < 3 * r["stderr"] + 0.002, r
        if r["significant"] and r["effect"] == "thrust_misalignment":
            assert 0.0 < r["estimate"] < STRUCTURAL["thrust_misalignment"], r
    if not result["significant"]:
        assert "no candidate effect is significant" in result["message"]
    # a delay found here can only be a sub-sample artefact
    delay = next(r for r in result["ranking"] if r["effect"] == "actuator_delay")
    assert not delay["significant"]


# Why a planted moment offset of 0.006 is missed on this generator (the validation
# page "independent generators"): the baseline's own misfit is as large. On a
# noise-free clean flight it scores a thrust misalignment of 0.0097 +/- 0.0016 m
# (statistic 38.3: above the 21.0 of a planted CM0 of 0.006 at 50 Hz, seed 1),
# while the moment offset stays small (0.0025 +/- 0.0016). No noise: the fit and
# its score are deterministic, so the bounds are near the measured values. A
# validation test, as are the clean flights above that bound the misfit with noise.
@pytest.mark.validation
def test_noise_free_clean_flight_carries_a_misalignment_sized_misfit(tmp_path):
    path = gen.make_log(tmp_path / "clean_13_50.csv", 13, 50.0, 30.0, noise=False)
    base = fit(dp.read_log(path))
    assert base.converged
    rows = {r["effect"]: r for r in diagnose(base)["ranking"]}
    misalignment, offset = rows["thrust_misalignment"], rows["moment_offset"]
    assert 0.008 < misalignment["estimate"] < 0.0115, misalignment
    assert misalignment["statistic"] > 30.0, misalignment
    assert abs(offset["estimate"]) < 0.004, offset


# Planted effects, each at a rate where the issue found a problem; sizes a few
# times what a clean flight's structural misfit mimics.
# All validation tests (`-m validation`), each a repeat of what a default test
# covers: a planted effect named first and recovered (the vertical wind of
# test_discrepancy.py; the delay and the az bias there too, added one after the
# other, and the az bias on the independent HFB-320 below); where a step falls
# between samples by test_block_means_keep_a_step_on_time. Pitch damping at 1 kHz
# is a known failure, and the moment offset at 200 Hz is at the rule's detection
# limit, so it asserts nothing.
PLANTED = [
    pytest.param("actuator_delay", 0.04, 1000.0, 0, marks=pytest.mark.validation),
    pytest.param("actuator_delay", 0.04, 50.0, 2, marks=pytest.mark.validation),
    pytest.param("sensor_bias:az", 0.3, 200.0, 3, marks=pytest.mark.validation),
    pytest.param("pitch_damping", -3.0, 1000.0, 0, marks=pytest.mark.validation),
    pytest.param("thrust_misalignment", 0.03, 1000.0, 0, marks=pytest.mark.validation),
    # at the rule's detection limit on this generator: a planted CM0 of 0.01 gives
    # a score statistic of 29-40 (measured, seeds 3 and 2), about the threshold
    # this generator's logs give at 200 Hz (29-42); a CM0 of 0.006 was found on
    # seed 0 (52 against 31) and missed on seed 1 (27 against 46)
    pytest.param(
        "moment_offset",
        0.01,
        200.0,
        3,
        marks=[
            pytest.mark.validation,
            pytest.mark.xfail(strict=False, reason="at the rule's detection limit"),
        ],
    ),
]
# The generator's gravity is standard gravity with the inverse square of the
# distance from a 6371 km Earth; the package's the same with the standard
# atmosphere's 6356.766 km (8e-5 m/s^2 apart at 12 km). Before the package used
# standard gravity (it had Newton's law with the equatorial radius, 0.008 m/s^2
# weaker) the difference was a force g cos(theta) in the w equation that an az
# bias absorbs. Measured then (seed 3, 200 Hz): clean az-bias score estimate
# -0.0099 +/- 0.0017 with the generator's gravity, -0.0018 +/- 0.0017 with the
# package's patched into it. So the expected refit is the planted bias minus the
# mean gravity difference along body z, computed from the two gravity laws at the
# log's altitude and attitude.
STRUCTURAL = {
    # clean flights show a thrust-misalignment-like misfit of +0.003 to +0.0066 m:
    # the generator's table changes with Mach faster (a transonic peak, PCHIP) than
    # the baseline's 6 Mach functions follow, right after ignition (with the
    # generator's table frozen at Mach 2 the clean estimate is -0.0002 +/- 0.0002
    # instead of +0.0060 +/- 0.0007, seed 3, 200 Hz); measured refits of 0.03:
    # 0.0360 +/- 0.0004 (1 kHz), 0.0324 +/- 0.0005 (200 Hz)
    "thrust_misalignment": 0.008,
}


def gravity_shift(lg: dp.FlightLog) -> float:
    """Mean of (generator's - package's gravity) x cos(theta) over the log, m/s^2:
    what an az-bias estimate carries on the generator's logs."""
    h, theta = lg["h"], lg["theta"]
    diff = gen.gravity(h) - np.asarray(dp.gravity(h))
    return float(np.mean(diff * np.cos(theta)))


# what the data cannot tell the planted effect from (projected correlation > 0.9)
TIED = {"pitch_damping": {"alpha_dot_damping"}}


@pytest.mark.parametrize("name,value,rate,seed", PLANTED)
def test_planted_effect_is_first_significant_and_recovered(name, value, rate, seed):
    base, result = baseline(seed, rate, (name, value))
    top = result["ranking"][0]
    assert top["effect"] == name or top["effect"] in TIED.get(name, ()), result[
        "ranking"
    ][:3]
    assert name in result["significant"]
    after = fit(log(seed, rate, (name, value)), (name,), start=base)
    assert after.cost < 0.75 * base.cost
    est = after.effect_estimates()[name]
    # where each step falls between samples moves it by up to half a log sample:
    # about h / sqrt(12 x 60 steps) on average, 0.75 ms at 50 Hz (measured refit
    # at 50 Hz: 0.03940 +/- 0.00016), which the standard error does not contain
    sampling = 0.05 / rate if name == "actuator_delay" else 0.0
    tolerance = 3 * est["stderr"] + STRUCTURAL.get(name, 0.0) + sampling
    expected = value
    if name == "sensor_bias:az":
        expected = value - gravity_shift(log(seed, rate, (name, value)))
    assert abs(est["estimate"] - expected) < tolerance, (est, expected)
    # the noise sigma comes from the log itself (the residual's spectrum above the
    # model's bandwidth), not from its sidecar: never below the generator's noise
    # reduced by the block mean to the model rate. Not within 30% of it at 1 kHz:
    # there the block mean leaves so little noise that the baseline's structural
    # misfit reaches the residual's upper band too
    step = max(1, round(rate / ENTRY.rate))
    w = block_weights(step)
    scale = np.sqrt(np.sum(w**2)) / np.sum(w)
    channels = fit_metrics(after)["channels"]
    assert channels["q"]["noise"] > 0.7 * gen.NOISE["q"] * scale


# --- the decision rule, shared by the workflow and the engine (issue 15 item 2) ----
def test_score_variance_counts_covariance_between_outputs():
    from diffpegasus._estimate._score import score_variance

    rng = np.random.default_rng(2)
    n = 40
    rows = rng.normal(size=(n, 3))
    resid = rng.normal(size=(n, 3))
    # the definition, lag by lag: (1/n) sum_lag (sum_o sum_t e[t, o] j[t + lag, o])^2,
    # never below the outputs' own terms (1/n) sum_lag sum_o (sum_t ...)^2
    joint, own = 0.0, 0.0
    for lag in range(-(n - 1), n):
        lo, hi = max(0, -lag), min(n, n - lag)
        per_output = np.sum(resid[lo:hi] * rows[lo + lag : hi + lag], axis=0)
        joint += np.sum(per_output) ** 2
        own += np.sum(per_output**2)
    assert float(score_variance(rows, resid)) == pytest.approx(
        max(joint, own) / n, rel=1e-10
    )
    # evidence that cancels between outputs is not credited below their own terms
    flipped = resid * np.array([1.0, -1.0, 1.0])
    assert float(score_variance(rows[:, [0, 0, 0]], flipped[:, [0, 0, 0]])) >= float(
        score_variance(rows[:, :1], resid[:, :1])
    )
    # one misfit seen the same way in two outputs: their evidence is one piece, so
    # the variance is that of the sum (4x one output's), not the sum of each
    # output's own (2x)
    one = float(score_variance(rows[:, :1], resid[:, :1]))
    both = float(score_variance(rows[:, [0, 0]], resid[:, [0, 0]]))
    assert both == pytest.approx(4.0 * one, rel=1e-12)


def _rows(statistic, estimate, threshold=40.0):
    # a ranking as DecisionRule.decide makes it, for the verdict's words
    return dict(
        effect="sensor_bias:az",
        parameter="bias",
        statistic=statistic,
        p_value=1e-3,
        cost_reduction=0.05,
        estimate=estimate,
        stderr=0.01,
        significant=True,
        resolution_limit=False,
        lead=False,
        hard_to_tell_from=[],
        threshold=threshold,
        false_alarm_level=0.01,
        null_replicates=2000,
        null_order=12,
    )


def test_verdict_says_which_number_is_which():
    from diffpegasus._diagnose._rule import ranking_lines, rule_summary, verdict

    row = dict(_rows(820.0, 0.29), hard_to_tell_from=["sensor_bias:ax"])
    delay = dict(
        _rows(50.0, 0.004),
        effect="actuator_delay",
        parameter="tau",
        significant=False,
        resolution_limit=True,
    )
    lead = dict(delay, estimate=-0.05, resolution_limit=False, lead=True)
    text = verdict([row, delay, lead], 0.01)
    # significance (statistic against the log's threshold, p) and share of the
    # misfit (det R) said apart; a small share does not hide a significant effect
    assert "sensor_bias:az is significant (score statistic 820 > threshold 40" in text
    assert "explains 5% of det(R)" in text
    assert "cannot tell it apart from sensor_bias:ax" in text
    assert "resolution limit of the log" in text and "not physics" in text
    assert "would be a lead" in text and "never significant" in text
    # the terminal says which effects cannot be told apart, not only the JSON
    lines = ranking_lines([row, delay])
    assert lines[1].startswith("*") and "cannot be told from sensor_bias:ax" in lines[1]
    # a row above the first threshold, judged again once the significant effect
    # was fitted, says so on the terminal and in the report (else "no" beside a
    # statistic above the threshold reads as a contradiction)
    from diffpegasus._report._markdown import ranking_table

    after = dict(
        row,
        effect="moment_offset",
        significant=False,
        hard_to_tell_from=[],
        given=["sensor_bias:az"],
        statistic_given=5.2,
        threshold_given=16.3,
    )
    assert "given sensor_bias:az: 5.2 < 16.3" in ranking_lines([row, after])[2]
    assert "no (5.2 < 16.3 given sensor_bias:az)" in ranking_table(
        {"ranking": [row, after]}
    )
    none = verdict([dict(row, significant=False, statistic=30.0)], 0.01)
    assert none.startswith("no candidate effect is significant")
    assert "below the threshold 40" in none
    # a sub-sample delay above the threshold is never the "strongest" that failed
    # to pass; one that passed alone but not given another says where it failed
    none = verdict(
        [
            dict(delay, significant=False, statistic=388.0, p_value=0.0005),
            dict(after, statistic=52.0, statistic_given=12.2, threshold_given=12.5),
        ],
        0.01,
    )
    assert "the strongest, moment_offset, has statistic 52" in none
    assert "above the threshold 40 from this log's residuals alone" in none
    assert "given sensor_bias:az 12.2, below the threshold 12.5 there" in none
    rule = rule_summary([row])
    assert rule["threshold"] == 40.0 and rule["false_alarm_level"] == 0.01
    assert "false-alarm level of 0.01" in rule["text"]


# --- the engine's diagnosis (`diagnose --vehicle hfb320`) on the independent
# generator's HFB-320: true steps between samples, its own integrator and noise ----
def _hfb_log(tmp_path, seed, rate=10.0, effects=None):
    channels, meta = gen.generate_hfb320(seed, rate, effects=effects)
    return gen.write(tmp_path / f"hfb_{seed}_{int(rate)}.csv", channels, meta)


# seed 6 at 10 Hz: its elevator steps fall worst between samples (delay-artefact
# statistic 388); the model's ramp for each step leaves a systematic misfit partly
# shaped like pitch damping, which the rule flagged (22 against a threshold of 9.4)
# while its bootstrap replicates were not refitted as the log was; with them
# refitted it is not flagged
# (seed 6 at 50 Hz repeats the check at another rate: a validation test)
@pytest.mark.parametrize(
    "seed,rate",
    [(3, 10.0), (6, 10.0), pytest.param(6, 50.0, marks=pytest.mark.validation)],
)
def test_engine_diagnosis_of_clean_independent_flights_flags_nothing(
    tmp_path, seed, rate
):
    from diffpegasus._cli._runners import run_model_diagnose
    from diffpegasus._registry import vehicle_spec

    report = run_model_diagnose(
        vehicle_spec("hfb320", candidates=True), [_hfb_log(tmp_path, seed, rate)]
    )
    assert report["fit"]["converged"]
    assert report["significant"] == [], report["ranking"][:3]
    assert report["message"].startswith("no candidate effect is significant")
    # where the steps fall between samples looks like a delay (seeds 3 and 6 at
    # 10 Hz: statistics 309 and 388, the largest of 30 clean flights; p ~ 0 under
    # the old rule, which flagged 27 of 30 flights): called a resolution limit
    delay = next(r for r in report["ranking"] if r["effect"] == "actuator_delay")
    assert abs(delay["estimate"]) < 0.5 / rate
    if rate == 10.0:
        assert delay["p_value"] < 0.01 and delay["resolution_limit"]
        assert "resolution limit of the log" in report["message"]


def test_engine_diagnosis_finds_a_planted_az_bias_on_independent_flights(tmp_path):
    from diffpegasus._cli._runners import run_model_diagnose
    from diffpegasus._registry import vehicle_spec

    path = _hfb_log(tmp_path, 4, 10.0, {"sensor_bias:az": 0.1})
    report = run_model_diagnose(vehicle_spec("hfb320", candidates=True), [path])
    top = report["ranking"][0]
    assert top["effect"] == "sensor_bias:az", report["ranking"][:3]
    assert report["significant"] == ["sensor_bias:az"]
    assert "sensor_bias:az is significant" in report["message"]
    assert abs(top["estimate"] - 0.1) < 3 * top["stderr"]
    # the business jet's model has no resolution chosen from the data: none reported
    assert "baseline" not in report


# --- standard errors that cover (issue 15 item 4): the secant bias of the OEM -----
@pytest.mark.slow
def test_window_terms_remove_the_secant_bias_of_the_lift_derivatives():
    """Noise-free 20 s flight (ignition and the pull-up, alpha swept by degrees per
    window): with derivatives continuous and linear in time the window estimates of
    CLa carry a structural bias (the data fix the secant and its slope in alpha,
    which differ); with the window terms (`parameters="window"`) it is gone.
    Measured on the full noise-free reference flight: CLa rms error 0.066/rad
    (linear) against 0.0079 (window)."""
    import jax

    from .helpers import short_config

    log = dp.flight_to_log(
        dp.simulate(short_config(sample_rate=200.0), jax.random.key(1))
    )
    err = {}
    for kind in ("linear", "window"):
        est = dp.estimate_oem(log, parameters=kind, decimate=1)
        use = np.asarray(est.valid) & (np.asarray(est.window_start) >= 6.0)
        e = np.asarray(est.values - est.truth)[use]
        err[kind] = np.sqrt(np.mean(e**2, axis=0))
    names = list(dp.DERIVATIVE_NAMES)
    cla, clde = names.index("CLa"), names.index("CLde")
    assert err["linear"][cla] > 0.03, err  # the bias the campaign's 65% came from
    assert err["window"][cla] < 0.3 * err["linear"][cla], err
    assert err["window"][clde] < 0.5 * err["linear"][clde], err


# --- the bootstrap refits each replicate as the fit refitted the log -------------
def _segment_problem(rng):
    # 2 outputs, 300 samples; the free unknowns a constant and a slope on each of
    # 10 segments per output (shooting nodes' shape); 4 smooth candidates, projected
    n, o = 300, 2
    t, basis, refit = segment_projection(n, o)
    raw = np.stack(
        [
            np.stack([np.sin(2.6 * np.pi * j * t), np.cos(1.4 * np.pi * j * t)], -1)
            for j in range(1, 5)
        ],
        -1,
    )
    rows = np.stack([refit(raw[..., j]) for j in range(4)], -1)
    return basis, refit, rows


def _whitened(rows, e):
    # a refit estimates R again: whitened residuals have unit mean square
    c = np.sqrt(np.mean(e**2, axis=0))
    return rows / c[None, :, None], e / c


def test_bootstrap_replicates_are_refitted_like_the_log():
    """A fit takes its free unknowns' share out of the residuals it leaves, and R
    from them; the statistic is studentised by that residual. A replicate that is
    resampled but not refitted is studentised by a fuller residual: its null is
    lighter than the refitted one's. Closed form here (a linear problem, white
    noise, resampled sample by sample): the statistic of fresh noise, refitted
    and whitened again, over 1500 draws, against the bootstrap's maxima from one
    log. Measured (seed 0): mean of the maxima 2.60 for refitted noise, 2.55 for
    the bootstrap with the refit, 2.30 without (95% points 6.79, 6.44, 5.95)."""
    from diffpegasus._diagnose._calibration import (
        _refitted,
        _spectra,
        calibrate,
        statistics,
    )

    rng = np.random.default_rng(0)
    basis, refit, rows0 = _segment_problem(rng)

    def stat(e):
        r, e = _whitened(rows0, refit(e))
        g = np.einsum("nok,no->k", r, e)
        return statistics(r, e, np.einsum("nok,nok->k", r, r), g).max()

    fresh = np.array([stat(rng.normal(size=(300, 2))) for _ in range(1500)])
    rows, e = _whitened(rows0, refit(rng.normal(size=(300, 2))))
    curvature = np.einsum("nok,nok->k", rows, rows)
    slope = np.einsum("nok,no->k", rows, e)
    kwargs = dict(level=0.05, replicates=1500, order=0)
    with_refit = calibrate(rows, e, curvature, slope, basis=basis, **kwargs)
    without = calibrate(rows, e, curvature, slope, **kwargs)
    truth = np.quantile(fresh, 0.95)
    # the mean of 1500 maxima scatters by about 2%, their 95% point by about 5%
    assert abs(np.mean(with_refit.maxima) - fresh.mean()) < 0.06 * fresh.mean()
    assert abs(with_refit.threshold - truth) < 0.12 * truth, (with_refit, truth)
    assert np.mean(without.maxima) < 0.92 * fresh.mean()
    # the refit leaves nothing along the free unknowns' directions
    sp = _spectra(rows, curvature, np.zeros(4), basis)
    left = np.asarray(_refitted(sp, rng.normal(size=(300, 2))))
    assert np.max(np.abs(np.einsum("nou,no->u", basis, left))) < 1e-10


# --- the baseline's resolution chosen from the log ------------------------------
def _sweep(n=1500, seed=0):
    """A record-like sweep: Mach 0.8 -> 3 (slow start, like a drop then a burn),
    alpha and elevator moving about, 1 s segments of 50 samples."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 50.0
    mach = 0.8 + 2.2 * (t / t[-1]) ** 1.5
    alpha = 0.05 + 0.03 * np.sin(0.9 * t) + 0.01 * np.sign(np.sin(2.3 * t))
    de = 0.02 * np.sign(np.sin(1.7 * t + 0.3)) + 0.005 * np.cos(0.4 * t)
    return t, mach, alpha, de, rng


def test_knot_choice_keeps_four_functions_for_a_cubic_in_mach():
    from diffpegasus._vehicle._mach_spline import choose_knots

    t, mach, alpha, de, rng = _sweep()
    # every count >= 4 represents a cubic in Mach exactly: more functions only
    # add variance, so the fewest is kept
    cl = (3.0 + 0.5 * mach - 0.2 * mach**3) * alpha + 0.4 * de
    cd = 0.3 * alpha**2 + (0.1 * mach) * alpha + 0.05 * de
    cm = (-1.0 + 0.3 * mach**2) * alpha - 1.2 * de
    coeffs = tuple(c + 1e-3 * rng.standard_normal(len(t)) for c in (cl, cd, cm))
    choice = choose_knots(mach, alpha, de, coeffs, np.floor(t).astype(int))
    assert choice.knots == 4, choice
    assert choice.candidates == tuple(range(4, 13))


def test_knot_choice_finds_the_resolution_a_spline_truth_needs():
    from diffpegasus._vehicle._mach_spline import (
        choose_knots,
        mach_breakpoints,
        MachSplineAerodynamics,
    )

    t, mach, alpha, de, rng = _sweep(seed=1)
    # the truth: a spline with 8 functions on the same (quantile) breakpoints,
    # coefficients far above the noise. 8 represents it exactly; fewer cannot
    # (misfit much larger than the noise), other counts only approximate it
    part = MachSplineAerodynamics(knots=8)
    a = part.regressors(mach, alpha, de, mach_breakpoints(mach, 6))
    theta = rng.normal(0.0, 1.0, (3, a.shape[1]))
    coeffs = tuple(a @ th + 1e-3 * rng.standard_normal(len(t)) for th in theta)
    choice = choose_knots(mach, alpha, de, coeffs, np.floor(t).astype(int))
    assert choice.knots == 8, choice
    # the record bounds the counts: a 10 s record (10 segments) tries at most
    # 3 + 10 / 2 = 8 functions
    short = slice(0, 500)
    bounded = choose_knots(
        mach[short],
        alpha[short],
        de[short],
        tuple(c[short] for c in coeffs),
        np.floor(t[short]).astype(int),
    )
    assert max(bounded.candidates) == 8


def test_knot_choice_reads_the_moment_through_the_pitch_rate():
    from scipy.integrate import cumulative_trapezoid

    from diffpegasus._vehicle._mach_spline import (
        choose_knots,
        mach_breakpoints,
        MachSplineAerodynamics,
        PitchRate,
    )

    t, mach, alpha, de, rng = _sweep(seed=2)
    # a moment that needs 8 Mach functions, the part beyond a cubic in Mach small:
    # below the pitch-acceleration channel's noise (5e-3 rad/s^2, the independent
    # generator's), above the pitch rate's (2e-4 rad/s) once integrated over 1 s
    part = MachSplineAerodynamics(knots=8)
    a = part.regressors(mach, alpha, de, mach_breakpoints(mach, 6))
    cm = (-1.0 + 0.3 * mach**2) * alpha - 1.2 * de
    cm = cm + 0.03 * a @ rng.normal(0.0, 1.0, a.shape[1])
    gain = 2.0 + 0.5 * np.sin(0.2 * t)  # qbar S c / Iyy, 1/s^2
    known = 0.05 * np.cos(0.7 * t)  # the rest of qdot, rad/s^2
    qdot = gain * cm + known
    q = 0.01 + cumulative_trapezoid(qdot, t, initial=0.0)
    q = q + 2e-4 * rng.standard_normal(len(t))
    cm_from_qdot = (qdot + 5e-3 * rng.standard_normal(len(t)) - known) / gain
    segment = np.floor(t).astype(int)
    pitch = PitchRate(t=t, q=q, gain=gain, known=known)
    through_q = choose_knots(mach, alpha, de, (cm_from_qdot,), segment, pitch=pitch)
    through_qdot = choose_knots(mach, alpha, de, (cm_from_qdot,), segment)
    # measured on seeds 2, 3, 4: 8, 8, 8 through q; 6, 7, 5 through qdot
    assert through_q.knots == 8, through_q
    assert through_qdot.knots < 8, through_qdot
    assert "pitch rate" in through_q.summary()["rule"]
    # the residual at the truth's resolution is white: every sample counts
    assert through_q.effective_samples[0] > 0.9 * len(t)


def test_segment_integrals_and_effective_samples_match_references():
    from scipy.integrate import cumulative_trapezoid

    from diffpegasus._vehicle._mach_spline import effective_samples, segment_integrals

    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0.0, 3.0, 200))
    x = np.column_stack([np.sin(2.0 * t), t**2])
    segment = np.floor(t).astype(int)
    got = segment_integrals(x, t, segment)
    for s in np.unique(segment):
        on = segment == s
        ref = cumulative_trapezoid(x[on], t[on], axis=0, initial=0.0)
        np.testing.assert_allclose(got[on], ref - ref.mean(axis=0), atol=1e-12)
    # first-order autoregression with rho = 0.6: n (1 - rho) / (1 + rho) = n / 4
    # (the lag-one estimate's sampling error at n = 20000 is about 0.006)
    e = rng.standard_normal(20_000)
    r = np.empty_like(e)
    r[0] = e[0]
    for i in range(1, len(e)):
        r[i] = 0.6 * r[i - 1] + e[i]
    assert abs(effective_samples(r) / len(r) - 0.25) < 0.01
    assert abs(effective_samples(e) / len(e) - 1.0) < 0.03


def test_pegasus_baseline_resolution_is_chosen_from_the_log_and_reported():
    from diffpegasus._registry._pegasus import PegasusEntry

    spec, _ = PegasusEntry(knots=None).problem([log(3, 50.0)], candidates=True)
    baseline = spec.notes["baseline"]
    # measured on this generator's logs, clean and planted, noise-free and noisy,
    # 50 Hz to 1 kHz: 12 on every one (experiments/lv_knot_rule.py); the record
    # supports more functions than the bound
    assert baseline["knots"] == 12, baseline
    assert "pitch rate" in baseline["rule"]
    assert baseline["candidates"] == list(range(4, 13))
    assert baseline["p_value"][-1] == 1.0 and baseline["p_value"][-2] < 0.01
    assert sum(n.startswith("CM.a1[") for n in spec.model.parameters) == 12
    # a fixed count says so
    fixed, _ = PegasusEntry(knots=6).problem([log(3, 50.0)])
    assert fixed.notes["baseline"] == {
        "rule": "Mach functions per coefficient term set by --knots (quantile "
        "breakpoints)",
        "knots": 6,
    }
