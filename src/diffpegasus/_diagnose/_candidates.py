"""Which held term would explain the misfit: the score test of every candidate
parameter at an output-error fit of any model, ranked by the predicted fall of det(R).
"""

from collections.abc import Mapping, Sequence

import equinox as eqx
import numpy as np

from .._cache import kept_call
from .._estimate._fit import Fit, fit
from .._estimate._score import score, score_linearised
from .._model import Model, Record
from ._calibration import padded_count
from ._rule import DecisionRule, verdict


def score_candidates(
    result: Fit,
    candidates: Sequence[str],
    level: float = 0.01,
    *,
    rule: DecisionRule | None = None,
):
    """The ranking of held parameters `candidates` at the fit `result`, decided by
    the same rule as the Pegasus workflow's diagnosis ([`DecisionRule`][]): a
    threshold from the fit's own residuals (sieve bootstrap) holding the
    family-wise false-alarm level `level`.

    Each row: `parameter`, `effect` (the library effect's name, the part before the dot,
    or the parameter of a bare model), `cost_reduction` (predicted fraction of det(R)
    removed by the one Gauss-Newton step freeing it: the share of the misfit, reported,
    not decided on), `statistic` (1 degree of freedom, variance with the residuals'
    colour and their covariance between outputs), `p_value` (family-wise, from the
    bootstrap), `threshold` (the statistic a candidate must exceed on this log),
    `estimate` and `stderr` (after that step), `significant` (statistic above the
    threshold; an `actuator_delay` also needs an estimate of at least half a sample
    interval, a lead never is), `resolution_limit` (a delay below half a sample
    interval: where the input's steps fall between samples, not physics), `lead`
    and `hard_to_tell_from` (candidates whose sensitivities correlate above 0.9
    once the free unknowns are projected out). Significant rows first, then by cost
    reduction.
    """
    model = result.model
    names = list(model.parameters)
    for c in candidates:
        if c not in names:
            raise ValueError(f"candidate {c!r} is not a parameter of the model")
        if result.free[names.index(c)]:
            raise ValueError(
                f"candidate {c!r} is estimated already; hold it to test it"
            )
    idx = np.array([names.index(c) for c in candidates])
    k = len(idx)
    # padded (the first candidate repeated) so that diagnoses with a few candidates
    # more or fewer share one compiled program; each candidate's numbers are its
    # own column's, the padding is cut off
    padded = np.concatenate([idx, np.full(padded_count(k) - k, idx[0])])
    # through the cache's kept programs, as the fit's solve: a later process skips
    # its tracing, and one started at the same time waits for this one's compilation
    # from the fit's own linearisation at its estimates where it has one (the
    # engine's solve): a program without the model, instead of one that holds the
    # model's Jacobian again (15.7 s of XLA for the launch vehicle's)
    static = {"nx": len(model.states), "p": len(names)}
    dynamic = {
        "layout": result.layout,
        "z": np.asarray(result.z),
        "free": np.asarray(result.free),
        "candidates": padded,
    }
    if result.linearisation is not None:
        dynamic["linearisation"] = result.linearisation
        st = kept_call(score_linearised, static, dynamic)
    else:
        dynamic["r"] = np.asarray(result.R)
        st = kept_call(score, {"model": model.structure(), **static}, dynamic)
    st = eqx.tree_at(
        lambda t: (
            t.statistic, t.p_value, t.estimate, t.stderr, t.cost_ratio,
            t.ls_reduction, t.correlation, t.rows, t.curvature, t.slope,
        ),
        st,
        (
            st.statistic[:k], st.p_value[:k], st.estimate[:k], st.stderr[:k],
            st.cost_ratio[:k], st.ls_reduction[:k], st.correlation[:k, :k],
            st.rows[..., :k], st.curvature[:k], st.slope[:k],
        ),
    )  # fmt: skip
    rule = rule or DecisionRule(significance=level)
    # judged by parameter (two may belong to one effect); the effect named after
    effects = [c.split(".")[0] for c in candidates]
    ranking, _ = rule.decide(
        st,
        list(candidates),
        list(candidates),
        delays=[e.endswith("_delay") for e in effects],  # actuator, aileron, rudder
        resolution=sample_resolution(result),
    )
    for row in ranking:
        row["effect"] = row["parameter"].split(".")[0]
        row["hard_to_tell_from"] = [c["effect"] for c in row["hard_to_tell_from"]]
    return ranking


def sample_resolution(result: Fit) -> float:
    """Half the (largest) sample interval of the fitted records, s: the timing
    resolution of an input step between samples."""
    return 0.5 * max(float(np.mean(np.diff(r.t))) for r in result.records)


def diagnosis_message(ranking: list[dict], result: Fit) -> str:
    """The verdict of [`score_candidates`][]'s ranking in words (shared with the
    Pegasus workflow): every significant candidate's statistic against the log's
    threshold and its family-wise p-value (the evidence) and its share of det(R),
    said apart; plainly when none is significant; a sub-sample delay called a
    resolution limit, a lead never significant."""
    rows = [
        dict(r, hard_to_tell_from=[n.split(".")[0] for n in r["hard_to_tell_from"]])
        for r in ranking
    ]
    return verdict(rows, sample_resolution(result))


def diagnose_model(
    model: Model,
    records: Record | Sequence[Record],
    candidates: Sequence[str],
    *,
    level: float = 0.01,
    process_noise: Sequence[str] | Mapping[str, float] | None = None,
    gust=None,
    **fit_options,
) -> tuple[Fit, list[dict]]:
    """Fit `model` with the `candidates` (parameter names) held at their start
    values, then rank them by score test and decide by the rule calibrated on the
    fit's own residuals (see
    [`score_candidates`][]; [`diagnosis_message`][] puts the verdict in words).
    With `process_noise` (states, or a dict of start intensities), process noise
    is a candidate too, scored by the filter-error fit's likelihood ratio, and the
    deterministic candidates are tested again at that fit (see
    [`process_noise_candidate`][]: process noise may only take an output-error
    finding away; its row's `verdict` is the message when process noise is
    present; with a [`Gust`][] `gust`, coloured turbulence is offered besides
    white noise and the log chooses). Keyword arguments go to [`fit`][]."""
    fixed = tuple(dict.fromkeys(tuple(model.fixed) + tuple(candidates)))
    result = fit(model.replace(fixed=fixed), records, **fit_options)
    ranking = score_candidates(result, candidates, level)
    # in turbulence the output-error fit may stop at its iteration cap: process
    # noise is still scored from where it stopped (its det(R) only overstates LR)
    if process_noise is not None and np.isfinite(result.cost):
        from ._process_noise import process_noise_candidate, ProcessNoiseRule

        _, ranking, message = process_noise_candidate(
            result,
            ranking,
            process_noise,
            rule=ProcessNoiseRule(significance=level),
            gust=gust,
        )
        for row in ranking:
            if row.get("effect") == "process_noise":
                row["verdict"] = message
    return result, ranking
