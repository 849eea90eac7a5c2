"""The decision rule calibrated on the log: the block bootstrap of the efficient
score against closed forms (chi-square maxima, Politis and White's block length of
an AR(1) series), its family-wise false-alarm level on coloured residuals, and the
rule's verdicts on a synthetic score test (delays: resolution, leads)."""

import functools
import types

import jax
import numpy as np
import pytest
import scipy.stats

from diffpegasus._diagnose._calibration import block_length, calibrate, statistics
from diffpegasus._diagnose._rule import DecisionRule


def _ar1(rng, n, channels, phi):
    e = np.zeros((n, channels))
    w = rng.normal(size=(n, channels))
    e[0] = w[0] / np.sqrt(1 - phi**2)
    for i in range(1, n):
        e[i] = phi * e[i - 1] + w[i]
    return e


def _test(rows, e):
    curvature = np.einsum("nok,nok->k", rows, rows)
    slope = np.einsum("nok,no->k", rows, e)
    return curvature, slope


def test_bootstrap_null_of_white_gaussian_scores_is_the_chi_square_maximum():
    # linear Gaussian case: k independent sensitivity directions, white residuals;
    # the score statistics are independent chi-square(1), so the level-a threshold
    # of their maximum is F^-1((1 - a)^(1/k)). Measured over 5 draws at n = 1000:
    # 5.8-6.4 against 6.20; the bootstrap's own 95% point from 1000 replicates
    # scatters by about 5%
    rng = np.random.default_rng(0)
    n, outputs, k = 600, 2, 4
    rows = rng.normal(size=(n, outputs, k))
    exact = scipy.stats.chi2.ppf(0.95 ** (1 / k), 1)
    found = []
    for i in range(3):
        e = rng.normal(size=(n, outputs))
        cal = calibrate(
            rows, e, *_test(rows, e), level=0.05, replicates=1000, key=jax.random.key(i)
        )
        found.append(cal.threshold)
        assert cal.order <= 3  # white: (almost) no autoregression
    assert np.mean(found) == pytest.approx(exact, rel=0.12), found


def test_block_length_of_an_ar1_series_matches_politis_white():
    # AR(1) with phi: G / g(0) = 2 phi / (1 - phi^2), so the circular-block length
    # is (1.5 (G / g)^2)^(1/3) n^(1/3); the estimate from one record scatters (the
    # flat-top window's sum over lags): measured 0.8-1.2 of the formula
    rng = np.random.default_rng(1)
    n, phi = 4000, 0.8
    ratio = 2 * phi / (1 - phi**2)
    exact = (1.5 * ratio**2) ** (1 / 3) * n ** (1 / 3)
    found = block_length(_ar1(rng, n, 1, phi))
    assert found == pytest.approx(exact, rel=0.35)
    # the largest over channels: a white channel beside it does not shorten it
    both = np.column_stack([_ar1(rng, n, 1, phi), rng.normal(size=n)])
    assert block_length(both) >= 0.6 * exact


def test_family_wise_level_holds_on_coloured_residuals():
    # 60 records of AR(0.8) residuals in two channels with no effect: the share
    # flagged at level 0.1 stays near 0.1 (binomial sd 0.039); a chi-square(1)
    # threshold with Bonferroni flags far more here (the statistic's variance,
    # estimated from one coloured record, scatters)
    rng = np.random.default_rng(2)
    n, outputs, k, records = 400, 2, 3, 60
    t = np.arange(n) / n
    # smooth sensitivities, like a manoeuvre's
    rows = np.stack(
        [np.sin(2 * np.pi * (j + 1) * t + o) for j in range(k) for o in range(outputs)],
        axis=1,
    ).reshape(n, k, outputs)
    rows = np.transpose(rows, (0, 2, 1))
    flagged, chi_square = 0, 0
    bonferroni = scipy.stats.chi2.ppf(1 - 0.1 / k, 1)
    for i in range(records):
        e = _ar1(rng, n, outputs, 0.8)
        curvature, slope = _test(rows, e)
        rule = DecisionRule(significance=0.1, replicates=200, seed=i)
        cal = rule.calibrate(rows, e, curvature, slope)
        stat = statistics(rows, e, curvature, slope)
        flagged += bool(np.max(stat) > cal.threshold)
        chi_square += bool(np.max(stat) > bonferroni)
    assert 0.02 <= flagged / records <= 0.2, (flagged, chi_square)
    assert chi_square > flagged


def _score_test(rows, e, start):
    # a ScoreTest of held parameters at `start` from its parts, as `score` gives it
    curvature, slope = _test(rows, e)
    norms = np.sqrt(curvature)
    return types.SimpleNamespace(
        rows=rows,
        residuals=e,
        valid=np.ones(rows.shape[0], bool),
        curvature=curvature,
        slope=slope,
        statistic=statistics(rows, e, curvature, slope),
        estimate=start - slope / curvature,
        stderr=1.0 / norms,
        cost_ratio=np.ones(rows.shape[2]) - slope**2 / curvature / np.sum(e**2),
        correlation=np.einsum("nok,noj->kj", rows, rows) / np.outer(norms, norms),
    )


def test_rule_finds_one_effect_not_its_lookalikes_and_judges_delays():
    # three candidates on white residuals: a delay whose signature is in the
    # residuals (planted as the step of -0.5 it would take), a look-alike of it
    # (correlation about 0.95) and an unrelated one
    rng = np.random.default_rng(3)
    n = 400
    base = rng.normal(size=(n, 1))
    rows = np.stack(
        [base, base + 0.3 * rng.normal(size=(n, 1)), rng.normal(size=(n, 1))], axis=2
    )
    e = rng.normal(size=(n, 1)) + 0.5 * rows[..., 0]
    names = ["late", "alike", "other"]
    rule = DecisionRule(significance=0.01, replicates=500)
    decide = functools.partial(
        rule.decide, effects=names, parameters=["tau", "b", "c"], resolution=0.01
    )
    test = _score_test(rows, e, np.zeros(3))
    assert test.estimate[0] < -0.4  # residual + 0.5 rows: a step of -0.5
    # as a delay that is a lead: never significant, said so
    ranking, cals = decide(test, delays=[True, False, False])
    by = {r["effect"]: r for r in ranking}
    assert by["late"]["statistic"] > cals[0].threshold and by["late"]["lead"]
    assert not by["late"]["significant"]
    # its signature is in the residuals all the same: the look-alike, tested given
    # it, is not found either
    assert not by["alike"]["significant"] and by["alike"]["given"] == ["late"]
    # the same signature the other way round is a delay: found first, and the
    # look-alike, tested again given it, is not found too
    test = _score_test(rows, rng.normal(size=(n, 1)) - 0.5 * rows[..., 0], np.zeros(3))
    ranking, cals = decide(test, delays=[True, False, False])
    assert [r["effect"] for r in ranking if r["significant"]] == ["late"]
    assert ranking[0]["effect"] == "late"
    by = {r["effect"]: r for r in ranking}
    assert by["alike"]["statistic"] > cals[0].threshold  # alone it would pass
    assert by["alike"]["given"] == ["late"]
    assert by["alike"]["statistic_given"] < by["alike"]["threshold_given"]
    assert by["late"]["hard_to_tell_from"][0]["effect"] == "alike"
    assert 3.0 < cals[0].threshold < 30.0  # white noise: about chi-square's 1% max
    # family-wise p-values: the share of replicate maxima at or above, never 0
    assert by["late"]["p_value"] == pytest.approx(1 / 501)
    # below half a log sample, a delay is a resolution limit, not a finding
    ranking, _ = decide(test, delays=[True, False, False], resolution=1.0)
    by = {r["effect"]: r for r in ranking}
    assert by["late"]["resolution_limit"] and not by["late"]["significant"]


def test_a_candidate_the_log_holds_no_information_on_is_not_scored():
    """A candidate with no sensitivity in this log (a rail's friction when the rail
    is vertical: its curvature 0, its statistic 0/0) leaves the family instead of
    making the threshold undefined: the decisions and the threshold are those of
    the other three alone (the bootstrap pads three candidates to four with a zero
    one, so the two nulls are the same draws), and the verdict says it was not
    scored. Before, every statistic was judged against a NaN threshold and nothing
    could be found."""
    from diffpegasus._diagnose._rule import verdict

    rng = np.random.default_rng(5)
    n = 400
    rows = rng.normal(size=(n, 1, 3))
    e = rng.normal(size=(n, 1)) - 0.4 * rows[..., 1]
    rule = DecisionRule(significance=0.01, replicates=500)
    three, cal3 = rule.decide(
        _score_test(rows, e, np.zeros(3)),
        ["a", "b", "c"],
        ["a", "b", "c"],
        delays=[False] * 3,
        resolution=0.01,
    )
    with np.errstate(invalid="ignore", divide="ignore"):
        four = _score_test(
            np.concatenate([rows, np.zeros((n, 1, 1))], 2), e, np.zeros(4)
        )
    assert np.isnan(four.statistic[3]) or four.statistic[3] == 0.0
    ranking, cal4 = rule.decide(
        four, ["a", "b", "c", "rail"], ["a", "b", "c", "r"],
        delays=[False] * 4, resolution=0.01,
    )  # fmt: skip
    assert np.isfinite(cal4[0].threshold)
    assert cal4[0].threshold == cal3[0].threshold
    assert [r["effect"] for r in ranking if r["significant"]] == ["b"]
    assert [r["effect"] for r in three if r["significant"]] == ["b"]
    by = {r["effect"]: r for r in ranking}
    assert by["rail"]["uninformed"] and not by["rail"]["significant"]
    assert not any(r["uninformed"] for r in three)
    assert ranking[-1]["effect"] == "rail"
    assert "rail was not scored" in verdict(ranking, 0.01)
