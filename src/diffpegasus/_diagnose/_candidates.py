"""Which held term would explain the misfit: the score test of every candidate
parameter at an output-error fit of any model, ranked by the predicted fall of det(R).
"""

from collections.abc import Mapping, Sequence

import jax.numpy as jnp
import numpy as np

from .._estimate._fit import Fit, fit
from .._estimate._score import score
from .._model import Model, Record
from ._rule import DecisionRule, verdict


def score_candidates(
    result: Fit,
    candidates: Sequence[str],
    level: float = 0.01,
    min_statistic: float = DecisionRule.min_statistic,
):
    """The ranking of held parameters `candidates` at the fit `result`, decided by
    the same rule as the Pegasus workflow's diagnosis ([`DecisionRule`][]).

    Each row: `parameter`, `effect` (the library effect's name, the part before the dot,
    or the parameter of a bare model), `cost_reduction` (predicted fraction of det(R)
    removed by the one Gauss-Newton step freeing it: the share of the misfit, reported,
    not decided on), `statistic` (chi-square, 1 degree of freedom, variance with the
    residuals' colour and their covariance between outputs), `p_value`
    (Bonferroni-corrected over the candidates), `estimate` and `stderr` (after that
    step), `significant` (p below `level` and statistic above the penalty
    `min_statistic`; an `actuator_delay` instead needs an estimate of at least half a
    sample interval), `resolution_limit` (a delay below half a sample interval: where
    the input's steps fall between samples, not physics) and `hard_to_tell_from`
    (candidates whose sensitivities correlate above 0.9 once the free unknowns are
    projected out). Best (largest cost reduction) first.
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
    st = score(
        model.structure(),
        result.layout,
        jnp.asarray(result.z),
        jnp.asarray(result.R),
        jnp.asarray(result.free),
        jnp.asarray(idx),
        nx=len(model.states),
        p=len(names),
    )
    st = {k: np.asarray(getattr(st, k)) for k in st.__dataclass_fields__}
    rule = DecisionRule(level, min_statistic)
    k = len(candidates)
    rows = []
    for i, c in enumerate(candidates):
        effect = c.split(".")[0]
        decided = rule.judge(
            statistic=float(st["statistic"][i]),
            p_value=float(st["p_value"][i]),
            estimate=float(st["estimate"][i]),
            tested=k,
            is_delay=effect.endswith("_delay"),  # actuator, aileron, rudder
            resolution=sample_resolution(result),
        )
        close = [
            candidates[j]
            for j in range(k)
            if j != i and abs(float(st["correlation"][i, j])) > 0.9
        ]
        rows.append(
            {
                "parameter": c,
                "effect": effect,
                "cost_reduction": float(1.0 - st["cost_ratio"][i]),
                "statistic": float(st["statistic"][i]),
                "p_value": decided["p_value"],
                "estimate": float(st["estimate"][i]),
                "stderr": float(st["stderr"][i]),
                "significant": decided["significant"],
                "resolution_limit": decided["resolution_limit"],
                "hard_to_tell_from": close,
            }
        )
    rows.sort(key=lambda r: -r["cost_reduction"])
    return rows


def sample_resolution(result: Fit) -> float:
    """Half the (largest) sample interval of the fitted records, s: the timing
    resolution of an input step between samples."""
    return 0.5 * max(float(np.mean(np.diff(r.t))) for r in result.records)


def diagnosis_message(
    ranking: list[dict],
    result: Fit,
    level: float = 0.01,
    min_statistic: float = DecisionRule.min_statistic,
) -> str:
    """The verdict of [`score_candidates`][]'s ranking in words (shared with the
    Pegasus workflow): the significant candidate's statistic and p-value (the
    evidence) and its share of det(R), said apart; plainly when none is
    significant; a sub-sample delay called a resolution limit."""
    rows = [
        dict(r, hard_to_tell_from=[n.split(".")[0] for n in r["hard_to_tell_from"]])
        for r in ranking
    ]
    return verdict(rows, DecisionRule(level, min_statistic), sample_resolution(result))


def diagnose_model(
    model: Model,
    records: Record | Sequence[Record],
    candidates: Sequence[str],
    *,
    level: float = 0.01,
    min_statistic: float = DecisionRule.min_statistic,
    process_noise: Sequence[str] | Mapping[str, float] | None = None,
    **fit_options,
) -> tuple[Fit, list[dict]]:
    """Fit `model` with the `candidates` (parameter names) held at their start
    values, then rank them by score test and decide by the measured rule (see
    [`score_candidates`][]; [`diagnosis_message`][] puts the verdict in words).
    With `process_noise` (states, or a dict of start intensities), process noise
    is a candidate too, scored by the filter-error fit's likelihood ratio, and the
    deterministic candidates are tested again at that fit (see
    [`process_noise_candidate`][]; its row's `verdict` is the message when its
    likelihood ratio passes). Keyword arguments go to [`fit`][]."""
    fixed = tuple(dict.fromkeys(tuple(model.fixed) + tuple(candidates)))
    result = fit(model.replace(fixed=fixed), records, **fit_options)
    ranking = score_candidates(result, candidates, level, min_statistic)
    # in turbulence the output-error fit may stop at its iteration cap: process
    # noise is still scored from where it stopped (its det(R) only overstates LR)
    if process_noise is not None and np.isfinite(result.cost):
        from ._process_noise import process_noise_candidate, ProcessNoiseRule

        _, ranking, message = process_noise_candidate(
            result, ranking, process_noise, rule=ProcessNoiseRule(significance=level)
        )
        for row in ranking:
            if row.get("effect") == "process_noise":
                row["verdict"] = message
    return result, ranking
