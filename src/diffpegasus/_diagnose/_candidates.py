"""Which held term would explain the misfit: the score test of every candidate
parameter at an output-error fit of any model, ranked by the predicted fall of det(R).
"""

from collections.abc import Mapping, Sequence

import jax.numpy as jnp
import numpy as np

from .._estimate._fit import Fit, fit
from .._estimate._model import Model, Record
from .._estimate._score import score


def score_candidates(result: Fit, candidates: Sequence[str], level: float = 0.01):
    """The ranking of held parameters `candidates` at the fit `result`.

    Each row: `parameter`, `cost_reduction` (predicted fraction of det(R) removed by
    the one Gauss-Newton step freeing it), `statistic` (chi-square, 1 degree of
    freedom, variance with the residuals' colour), `p_value`, `estimate` and
    `stderr` (after that step), `significant` (Bonferroni-corrected p below
    `level`) and `hard_to_tell_from` (candidates whose sensitivities correlate
    above 0.9 once the free unknowns are projected out). Best first.
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
    k = len(candidates)
    rows = []
    for i, c in enumerate(candidates):
        p = float(st["p_value"][i])
        close = [
            candidates[j]
            for j in range(k)
            if j != i and abs(float(st["correlation"][i, j])) > 0.9
        ]
        rows.append(
            {
                "parameter": c,
                "cost_reduction": float(1.0 - st["cost_ratio"][i]),
                "statistic": float(st["statistic"][i]),
                "p_value": p,
                "estimate": float(st["estimate"][i]),
                "stderr": float(st["stderr"][i]),
                "significant": bool(p * k < level),
                "hard_to_tell_from": close,
            }
        )
    rows.sort(key=lambda r: -r["cost_reduction"])
    return rows


def diagnose_model(
    model: Model,
    records: Record | Sequence[Record],
    candidates: Sequence[str],
    *,
    level: float = 0.01,
    process_noise: Sequence[str] | Mapping[str, float] | None = None,
    **fit_options,
) -> tuple[Fit, list[dict]]:
    """Fit `model` with the `candidates` (parameter names) held at their start
    values, then rank them by score test (see [`score_candidates`][]). With
    `process_noise` (states, or a dict of start intensities), process noise is a
    candidate too, scored by the filter-error fit's likelihood ratio, and the
    deterministic candidates are tested again at that fit (see
    [`process_noise_candidate`][]; its row's `verdict` is the message when its
    likelihood ratio passes). Keyword arguments go to [`fit`][]."""
    fixed = tuple(dict.fromkeys(tuple(model.fixed) + tuple(candidates)))
    result = fit(model.replace(fixed=fixed), records, **fit_options)
    ranking = score_candidates(result, candidates, level)
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
