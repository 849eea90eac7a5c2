"""The process-noise candidate of a diagnosis: turbulence, or a missing term?

Offered data flown through turbulence, an output-error fit leaves coloured residuals
that several deterministic candidates can each partly explain; the honest answer is
that the model is driven by random gusts, which the filter-error method estimates.
So a diagnosis can also score *process noise* (`x' = f + F w` on the named states):

1. **Is there process noise?** The filter-error fit of the same model (the same held
   candidates; started from the output-error estimates and from the model's start
   values, the better kept) against the output-error fit
   by the likelihood ratio of the two maximum-likelihood fits (both with R relaxed,
   diagonal): `LR = N ln(det R_OEM / det R_FEM)` over the `N` samples, against a
   chi-square with as many degrees of freedom as intensities (the intensities sit on
   their boundary 0 under the null, which makes the chi-square conservative). The
   filter-error optimiser does not drive the intensities to exactly zero on data
   without process noise (at `F = 0` its cost is flat in `F`), so it stops a few
   percent above the output-error det(R) there: `LR` is clipped at 0. Significant
   when the Bonferroni-corrected p-value is below the level and `LR` exceeds a
   penalty (`min_statistic`, see [`ProcessNoiseRule`][]).
2. **Is a term missing even so?** Process noise absorbs any misfit, a missing term's
   too. So every deterministic candidate is score-tested again *at the filter-error
   fit* (on the innovations, with the exact Jacobian the fit already has and the
   Morelli-Klein variance for what colour remains): a candidate that is significant
   there (`survives`) is a missing term that turbulence does not explain; it ranks
   ahead of process noise, and process noise is then not declared significant (the
   missing term's misfit inflates its likelihood ratio too): add the term and
   diagnose again.

The ranking: candidates that survive process noise (by cost fall), then
`process_noise` when significant, then the rest by cost fall. When process noise is
significant and nothing survives, the verdict is "the residuals are explained by
turbulence (process noise), not by a missing term; use the filter-error estimates".
"""

import dataclasses
from collections.abc import Mapping, Sequence

import jax.numpy as jnp
import numpy as np
import scipy.stats

from .._estimate._filter_error import (
    choose_gain,
    FilterErrorFit,
    fit_filter_error,
    residual_intensities,
)
from .._estimate._fit import Fit
from .._estimate._score import score_variance


PROCESS_NOISE = "process_noise"
TURBULENCE_VERDICT = (
    "the residuals are explained by turbulence (process noise), not by a missing "
    "term; use the filter-error estimates"
)


@dataclasses.dataclass(frozen=True)
class ProcessNoiseRule:
    """`significance`: family-wise level (Bonferroni over the candidates and the
    process-noise test); `min_statistic`: the likelihood-ratio penalty process
    noise must exceed; `min_survivor`: the score statistic (at the filter-error
    fit) a deterministic candidate must exceed to count as missing even with
    process noise allowed.

    Measured (`experiments/turbulence_diagnosis.py`; 30 s HFB-320 flights at 10 Hz,
    the vehicle's 12 candidates, 12 seeds each): on clean flights the filter-error
    det(R) never fell below the output-error one (LR 0 after clipping: no false
    alarm; the penalty 50 leaves room for a structural misfit's colour); in Dryden
    gusts of 0.3 m/s LR 1700-2700 and the largest deterministic score at the
    filter-error fit 9.1; with CMq held at zero in gusts of 0.1 (0.05) m/s LR
    370-660 (120-200) and the missing damping (pitch or alpha-dot) scores 27-55
    (25-41) there. The penalty 16 sits between (a factor 1.55 below the smallest,
    1.75 above the largest).

    `min_log_ratio`: besides, the filter must lower det(R) at least `e^2` = 7.4
    times (`LR > 2 N`). On clean flights of the independent HFB-320 generator (true
    elevator steps between samples, which the model's linear interpolation cannot
    follow) the filter absorbs that structural misfit as process noise: LR 254 over
    301 samples (det(R) 2.3 times lower), far above the chi-square penalty but a
    factor 0.43 of this one; in the 0.3 m/s gusts above ln(ratio) is 5.7-9.1, on the
    real HFB-320 record 16. Turbulence weaker than the model's own structural misfit
    (e.g. 0.1 m/s on this vehicle) is not called turbulence: this test cannot tell it
    from model error.
    """

    significance: float = 0.01
    min_statistic: float = 50.0
    min_survivor: float = 16.0
    min_log_ratio: float = 2.0

    def judge(self, lr: float, samples: int, dof: int, tests: int):
        """`(p, passes, strong)`: the Bonferroni-corrected p-value of `lr` on `dof`
        degrees of freedom among `tests` tests; whether it passes the chi-square
        and its penalty (then the deterministic candidates are judged at the
        filter-error fit); whether det(R) falls enough for turbulence to be named
        (`lr > min_log_ratio * samples` as well)."""
        p = float(min(1.0, scipy.stats.chi2.sf(lr, dof) * tests))
        passes = bool(p < self.significance and lr > self.min_statistic)
        return p, passes, bool(passes and lr > self.min_log_ratio * samples)


def likelihood_ratio(oem: Fit, fem: FilterErrorFit) -> tuple[float, float]:
    """`(LR, fall)`: `N ln(det R_OEM / det R_FEM)` clipped at 0 (`N` samples over
    all records) and the fraction of det(R) the filter-error fit removes (may be
    negative: see the module)."""
    n = sum(len(r.t) for r in oem.records)
    ratio = float(fem.cost) / float(oem.cost)
    lr = max(0.0, -n * float(np.log(ratio))) if np.isfinite(ratio) else 0.0
    return lr, 1.0 - ratio


def score_at_filter_error(fem: FilterErrorFit, candidates: Sequence[str]) -> list[dict]:
    """Score test of held parameters `candidates` at the filter-error fit `fem`, on
    its innovations: per candidate its `statistic` (chi-square, 1 dof; variance
    with the innovations' remaining colour and covariance between outputs, as the
    output-error score's, [`score_variance`][]), raw `p_value`, the one
    Gauss-Newton step's `estimate` and `stderr`, with every free parameter and
    process-noise intensity re-adjusted (projected out). Same order as
    `candidates`."""
    names = list(fem.model.parameters)
    free = np.concatenate([fem.free, np.ones(len(fem.F), bool)])
    jw = np.asarray(fem.jacobian)
    ew = np.asarray(fem.whitened)
    n_z = jw.shape[-1]
    rows = jw.reshape(-1, jw.shape[-2], n_z)  # (samples, outputs, unknowns)
    e = ew.reshape(-1, ew.shape[-1])
    flat = rows.reshape(-1, n_z)
    h = flat.T @ flat
    g = flat.T @ e.reshape(-1)
    ff = np.flatnonzero(free)
    out = []
    z = np.concatenate([fem.params, fem.F])
    for c in candidates:
        if c not in names:
            raise ValueError(f"candidate {c!r} is not a parameter of the model")
        i = names.index(c)
        if free[i]:
            raise ValueError(
                f"candidate {c!r} is estimated already; hold it to test it"
            )
        d = np.zeros(n_z)
        d[i] = 1.0
        d[ff] -= np.linalg.lstsq(h[np.ix_(ff, ff)], h[ff, i], rcond=None)[0]
        s = float(d @ h @ d)
        slope = float(d @ g)
        if not s > 0:
            out.append(
                {
                    "parameter": c,
                    "statistic": 0.0,
                    "p_value": 1.0,
                    "estimate": float(z[i]),
                    "stderr": float("inf"),
                }
            )
            continue
        step = -slope / s
        col = rows @ d
        var = max(
            float(score_variance(jnp.asarray(col), jnp.asarray(e + step * col))), s
        )
        stat = slope**2 / var
        out.append(
            {
                "parameter": c,
                "statistic": stat,
                "p_value": float(scipy.stats.chi2.sf(stat, 1)),
                "estimate": float(z[i] + step),
                "stderr": float(np.sqrt(var) / s),
            }
        )
    return out


def best_filter_error(result: Fit, process_noise, **fem_options) -> FilterErrorFit:
    """The filter-error fit of `result`'s model and records from two starts, the
    output-error estimates and the model's start values, whichever reaches the
    lower det(R) (a converged one first). One start is not enough in turbulence:
    the output-error estimates can be far off (on 2 of 12 simulated HFB-320 flights
    in 0.3 m/s gusts CMq -630 and -290 for -27) and the filter-error fit from there
    stops in a local optimum with 10x the det(R)."""
    options = {"throw": False, **fem_options}
    # the output-error fit's residuals scale the start intensities (no refit from
    # each start); its initial states start the filter when it estimated them
    residuals = [
        rec.measured - y for rec, y in zip(result.records, result.outputs, strict=True)
    ]
    x0 = (
        np.asarray(result.initial_states)
        if np.any(np.asarray(result.initial_stderr) > 0)
        and all(rec.x0 is None for rec in result.records)
        else None
    )
    if isinstance(process_noise, Mapping):
        residuals = None
    elif options.get("gain", 0) is None:
        # one choice for both starts (see `choose_gain`), at the output-error fit
        noise_states = tuple(result.model.states.index(s) for s in process_noise)
        x_start = (
            x0
            if x0 is not None
            else np.array(
                [
                    rec.x0
                    if rec.x0 is not None
                    else rec.measured_states(result.model, [0])[0]
                    for rec in result.records
                ]
            )
        )
        f0 = residual_intensities(
            result.model, result.records, residuals, result.params, noise_states
        )
        options["gain"] = choose_gain(
            result.model,
            result.records,
            noise_states,
            x_start,
            result.params,
            f0,
            residuals,
        )
    fits = [
        fit_filter_error(
            result.model,
            result.records,
            process_noise=process_noise,
            start=start,
            residuals=residuals,
            x0=x0,
            **options,
        )
        for start in (result.params, result.model.start)
    ]
    return min(
        fits,
        key=lambda f: (not f.converged, f.cost if np.isfinite(f.cost) else np.inf),
    )


def process_noise_candidate(
    result: Fit,
    ranking: list[dict],
    process_noise: Sequence[str] | Mapping[str, float],
    *,
    rule: ProcessNoiseRule = ProcessNoiseRule(),
    **fem_options,
) -> tuple[FilterErrorFit, list[dict], str | None]:
    """Score process noise at the output-error fit `result` whose held candidates
    `ranking` ranks (rows of [`score_candidates`][]), see the module.

    **Arguments:** `process_noise`: the states with process noise (names, or a dict
    of start intensities, state units / sqrt(s)); `rule`: the thresholds; further
    keywords go to [`fit_filter_error`][] (`full_R`, `rtol`, `max_iter`).

    **Returns:** `(fem, ranking, message)`: the filter-error fit of `result`'s model
    (candidates held; the better of two starts, [`best_filter_error`][]), the new
    ranking (every deterministic row gains
    `statistic_under_process_noise`, `p_value_under_process_noise` (Bonferroni) and
    `survives_process_noise`; one `process_noise` row with `statistic` (LR),
    `dof`, `p_value` (Bonferroni), `cost_reduction` (measured, not predicted),
    `intensities` and `intensities_stderr` by state, `filter_error_estimates` and
    `filter_error_stderr`, `constraint_active`; its `estimate`/`stderr`/
    `parameter` are those of the intensity best determined, `F[state]`), and the
    verdict when the likelihood ratio passes (`None` otherwise: the deterministic
    verdict stands). When it passes, a deterministic row's `significant` becomes
    whether it survives process noise (the output-error test's flag, misled by the
    noise, is kept as `significant_output_error`), and `process_noise` is
    significant only when no term survives."""
    if result.bias_outputs:
        raise ValueError(
            "the filter-error method has no output biases: score process noise at "
            "an output-error fit without them"
        )
    fem = best_filter_error(result, process_noise, **fem_options)
    cands = [r["parameter"] for r in ranking]
    k = len(cands) + 1
    lr, fall = likelihood_ratio(result, fem) if fem.converged else (0.0, 0.0)
    dof = len(fem.F)
    p, present, strong = rule.judge(lr, sum(len(r.t) for r in result.records), dof, k)
    under = (
        {r["parameter"]: r for r in score_at_filter_error(fem, cands)}
        if fem.converged
        else {}
    )
    rows = []
    for r in ranking:
        u = under.get(r["parameter"])
        row = dict(r)
        row.setdefault("effect", r["parameter"].split(".")[0])
        if u is None:
            row.update(
                statistic_under_process_noise=None,
                p_value_under_process_noise=None,
                survives_process_noise=False,
            )
        else:
            pu = float(min(1.0, u["p_value"] * k))
            row.update(
                statistic_under_process_noise=u["statistic"],
                p_value_under_process_noise=pu,
                # a sub-sample delay is the log's resolution, not physics, at
                # either fit (the shared rule, _diagnose/_rule.py)
                survives_process_noise=bool(
                    pu < rule.significance
                    and u["statistic"] > rule.min_survivor
                    and not r.get("resolution_limit", False)
                ),
            )
        if present:
            row["significant_output_error"] = r["significant"]
            row["significant"] = row["survives_process_noise"]
        rows.append(row)
    first = sorted(
        (r for r in rows if r["survives_process_noise"]),
        key=lambda r: -r["cost_reduction"],
    )
    # a missing term makes the filter-error fit look better too: process noise is
    # significant only when no term survives it (else re-test after adding it)
    significant = strong and not first
    z_scores = np.abs(fem.F) / np.where(fem.F_stderr > 0, fem.F_stderr, np.inf)
    best = int(np.argmax(z_scores)) if len(fem.F) else 0
    pn = {
        "parameter": f"F[{fem.process_noise[best]}]",
        "effect": PROCESS_NOISE,
        "cost_reduction": float(fall),
        "statistic": float(lr),
        "dof": dof,
        "p_value": p,
        "estimate": float(fem.F[best]),
        "stderr": float(fem.F_stderr[best]),
        "significant": significant,
        "likelihood_ratio_passes": present,
        "turbulence_sized": strong,
        "resolution_limit": False,
        # terms significant at the filter-error fit but below the penalty (what
        # gusts can imitate, e.g. an offset where the held initial state is off)
        "hard_to_tell_from": [
            r["effect"]
            for r in rows
            if r["p_value_under_process_noise"] is not None
            and r["p_value_under_process_noise"] < rule.significance
            and not r["survives_process_noise"]
        ],
        "intensities": dict(zip(fem.process_noise, fem.F.tolist(), strict=True)),
        "intensities_stderr": dict(
            zip(fem.process_noise, fem.F_stderr.tolist(), strict=True)
        ),
        "filter_error_estimates": fem.estimates(),
        "filter_error_stderr": dict(
            zip(fem.model.parameters, fem.stderr.tolist(), strict=True)
        ),
        "filter_error_converged": fem.converged,
        "constraint_active": fem.constraint_active,
    }
    if present:
        rest = sorted(
            (r for r in rows if not r["survives_process_noise"]),
            key=lambda r: -r["cost_reduction"],
        )
        new = [*first, pn, *rest]
    else:
        new = sorted(
            [*rows, pn], key=lambda r: (not r["significant"], -r["cost_reduction"])
        )
    message = None
    if present:
        if first:
            top = first[0]
            message = (
                f"{top['effect']} is missing even with process noise allowed (score "
                f"statistic {top['statistic_under_process_noise']:.0f} at the "
                f"filter-error fit, p {top['p_value_under_process_noise']:.2g}): "
                f"{top['parameter']} = {top['estimate']:.4g} +/- {top['stderr']:.2g} "
                f"by output error. Process noise (likelihood ratio {lr:.0f} on "
                f"{dof} dof) absorbs a missing term's misfit too: diagnose again "
                "with the term added to tell whether turbulence remains"
            )
        elif not strong:
            message = (
                f"no candidate is significant: process noise lowers det(R) "
                f"{100 * fall:.0f}% (likelihood ratio {lr:.0f} on {dof} dof), less "
                f"than the {np.exp(rule.min_log_ratio):.1f}-fold fall that tells "
                "turbulence from the model's own structural misfit, and no term "
                "survives at the filter-error fit"
            )
        else:
            message = (
                f"{TURBULENCE_VERDICT} (likelihood ratio {lr:.0f} on {dof} dof, "
                f"p {p:.2g}; det(R) {100 * fall:.0f}% lower; no candidate term "
                "survives at the filter-error fit)"
            )
            if pn["hard_to_tell_from"]:
                message += (
                    "; the gusts cannot be told apart from "
                    + ", ".join(pn["hard_to_tell_from"])
                    + " on this record (significant at the filter-error fit, "
                    f"below the penalty {rule.min_survivor:g})"
                )
    return fem, new, message
