"""The process-noise candidate of a diagnosis: turbulence, or a missing term?

Offered data flown through turbulence, an output-error fit leaves coloured residuals
that several deterministic candidates can each partly explain; the honest answer is
that the model is driven by random gusts, which the filter-error method estimates.
So a diagnosis can also score *process noise* (`x' = f + F w` on the named states).
Process noise can only take findings away, never add one: a deterministic term is
named only if the calibrated output-error rule ([`DecisionRule`][]) named it.

1. **Is there process noise?** The filter-error fit of the same model (the same held
   candidates; started from the output-error estimates and from the model's start
   values, the better kept) against the output-error fit by the likelihood ratio
   of the two maximum-likelihood fits (both with R relaxed, diagonal):
   `LR = N ln(det R_OEM / det R_FEM)` over the `N` samples, against a chi-square
   with as many degrees of freedom as intensities (Bonferroni over the candidates
   and this test; the intensities sit on their boundary 0 under the null, which
   makes the chi-square conservative; the filter-error optimiser stops a little
   above the output-error det(R) on data without process noise, so `LR` is clipped
   at 0). The likelihood ratio alone cannot tell gusts from a structural misfit of
   the model, which a filter absorbs too (on calm flights of a launch vehicle
   flown by another simulator, 3-7 per sample, more than in gusts). So process
   noise is named only if, besides, the **filter explains the record**: its
   innovations are what its model says, white and unpredictable from anything
   known before each sample (its own past, the filter's predicted outputs, the
   inputs), by [`innovation_check`][] on every output against its chi-square.
   A misfit is a function of the flight: the filter's corrections follow it, and
   its innovations stay predictable from the flight's own signals.
2. **Is a term missing even so?** Process noise absorbs any misfit, a missing term's
   too. So every output-error finding is score-tested again *at the filter-error
   fit* (on the innovations, with the exact Jacobian the fit already has and the
   Morelli-Klein variance for what colour remains), against a threshold from that
   fit's own innovations ([`survivor_threshold`][]: the sieve bootstrap of the
   output-error rule): one above it `survives`, is a missing term that turbulence
   does not explain, ranks ahead of process noise, and process noise is then not
   declared significant (the missing term's misfit inflates its likelihood ratio
   too): add the term and diagnose again. One below it is taken away, and said to
   be hard to tell from the gusts on this record.

The ranking: the findings that survive process noise, then `process_noise` when
present, then the rest by cost fall; without process noise, the output-error
ranking with `process_noise` last. When process noise is present and nothing
survives, the verdict is "the residuals are explained by turbulence (process
noise), not by a missing term; use the filter-error estimates".
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
from .._estimate._gust import Gust, LOG_LENGTH, LOG_TAU
from .._estimate._score import score_variance
from ._calibration import Calibration
from ._rule import DecisionRule


PROCESS_NOISE = "process_noise"
TURBULENCE_VERDICT = (
    "the residuals are explained by turbulence (process noise), not by a missing "
    "term; use the filter-error estimates"
)


@dataclasses.dataclass(frozen=True)
class ProcessNoiseRule:
    """`significance`: the family-wise false-alarm level of the process-noise test
    (Bonferroni over the candidates and the process-noise test for the likelihood
    ratio; over the outputs for the innovations' check) and of the survivors'
    threshold; `lags`: lagged innovations in the innovations' check (default
    `ceil(10 log10 N)`, at most `N / 4`); `replicates` and `seed` of the survivors'
    sieve bootstrap (at least `5 / significance` replicates).

    No constant here is tuned on a simulator: the likelihood ratio is judged by its
    chi-square, the innovations' check by its chi-square, the survivors by a
    threshold from the filter-error fit's own innovations."""

    significance: float = 0.01
    lags: int | None = None
    replicates: int = 2000
    seed: int = 0


def innovation_check(
    innovations: np.ndarray, regressors: np.ndarray, lags: int
) -> tuple[np.ndarray, int]:
    """Whether a filter's innovations are what its model says they are: a white
    sequence that nothing known before the sample predicts. Per output, the
    Lagrange-multiplier statistic `N R^2` of the regression of the innovation on
    its own `lags` previous values and on `regressors` (each known before the
    sample: the filter's predicted outputs, the inputs), chi-square with
    `lags + regressors` degrees of freedom when the model holds (Breusch-Godfrey's
    test with the regressors added).

    **Arguments:** `innovations` `(samples, outputs)`; `regressors` `(samples,
    columns)`; `lags`.

    **Returns:** `(statistics (outputs,), dof)`."""
    e = np.asarray(innovations, float)
    z = np.asarray(regressors, float)
    n, m = e.shape
    z = z[:, np.std(z, axis=0) > 0]
    z = (z - z.mean(axis=0)) / z.std(axis=0)
    stats = np.zeros(m)
    dof = lags + z.shape[1]
    for i in range(m):
        y = e[:, i] - e[:, i].mean()
        if not np.any(y):
            continue
        own = np.column_stack(
            [np.concatenate([np.zeros(j), y[:-j]]) for j in range(1, lags + 1)]
        )
        x = np.column_stack([np.ones(n), own, z])
        q, _ = np.linalg.qr(x)
        fitted = q @ (q.T @ y)
        stats[i] = n * float(fitted @ fitted) / float(y @ y)
    return stats, dof


def turbulence_evidence(
    result: Fit, fem: FilterErrorFit, rule: ProcessNoiseRule, innovations=None
):
    """Whether the filter-error model explains the record: process noise is named
    only if its filter leaves innovations that pass [`innovation_check`][] on every
    output (Bonferroni at `rule.significance`). A structural misfit of the model
    is a function of the state and the inputs: a filter absorbs part of it as
    process noise, but its corrections then follow the flight and its
    innovations stay predictable from the flight's own signals; gusts are not.
    `innovations`: per record, the innovations to judge instead of the fit's
    (those less the input's unknown sub-sample motion, [`input_timing`][]).

    **Returns:** `{"passes", "statistic" (largest over outputs), "output",
    "threshold", "dof", "lags", "text"}`."""
    n = sum(len(r.t) for r in fem.records)
    lags = rule.lags or int(min(np.ceil(10.0 * np.log10(n)), n // 4))
    # records are independent: their statistics and degrees of freedom add
    stat = np.zeros(len(fem.model.outputs))
    dof = 0
    nus = fem.innovations if innovations is None else innovations
    for rec, nu, y in zip(fem.records, nus, fem.outputs, strict=True):
        s, d = innovation_check(
            np.asarray(nu), np.column_stack([np.asarray(y), rec.inputs]), lags
        )
        stat, dof = stat + s, dof + d
    outputs = fem.model.outputs
    threshold = float(scipy.stats.chi2.isf(rule.significance / len(outputs), dof))
    worst = int(np.argmax(stat))
    passes = bool(stat[worst] <= threshold)
    return {
        "passes": passes,
        "statistic": float(stat[worst]),
        "output": outputs[worst],
        "threshold": threshold,
        "dof": int(dof),
        "lags": int(lags),
        "text": (
            f"the filter's innovations {'pass' if passes else 'fail'} the whiteness "
            f"and orthogonality check (largest N R^2 {stat[worst]:.3g}, on "
            f"{outputs[worst]}, against {threshold:.3g}, the chi-square point on "
            f"{dof} dof at {rule.significance:g} over {len(outputs)} outputs)"
        ),
    }


def likelihood_ratio(oem: Fit, fem: FilterErrorFit) -> tuple[float, float]:
    """`(LR, fall)`: `N ln(det R_OEM / det R_FEM)` clipped at 0 (`N` samples over
    all records) and the fraction of det(R) the filter-error fit removes (may be
    negative: see the module)."""
    n = sum(len(r.t) for r in oem.records)
    ratio = float(fem.cost) / float(oem.cost)
    lr = max(0.0, -n * float(np.log(ratio))) if np.isfinite(ratio) else 0.0
    return lr, 1.0 - ratio


def input_timing(result: Fit, fem: FilterErrorFit) -> dict:
    """The input's unknown sub-sample motion in the null and in the alternative
    ([`timing_directions`][]): the intervals chosen at the output-error fit (the
    null, where an interval's error is least corrected), the same intervals'
    directions at both fits, and the likelihood ratio with them adjusted in both,
    `N ln(det R'_OEM / det R'_FEM)` (each `R'` the diagonal mean square of the
    residuals less their weighted fit on the directions), clipped at 0.

    **Returns:** `{"intervals" (per record, (input, sample) pairs),
    "innovations" (per record the filter's innovations less their fit on the
    directions, for [`turbulence_evidence`][]),
    "likelihood_ratio", "likelihood_ratio_sampled_input" (the same computed
    without the directions)}`."""
    from ._input_timing import project_out, timing_directions

    intervals, adjusted = [], []
    n = 0
    ss = {k: np.zeros(len(result.model.outputs)) for k in ("oem", "fem", "o", "f")}
    for i, rec in enumerate(result.records):
        e_o = np.asarray(rec.measured) - np.asarray(result.outputs[i])
        nx = len(result.model.states)
        h_o, chosen = timing_directions(
            result.model,
            rec,
            result.params,
            np.zeros((1, nx, len(result.model.outputs))),
            np.zeros(1, int),
            np.asarray(result.initial_states)[i],
            e_o,
        )
        frec = fem.records[i]
        dt = float(rec.t[1] - rec.t[0])
        schedule = np.round((np.asarray(fem.gain_times[i]) - rec.t[0]) / dt)
        x0 = (
            frec.x0
            if frec.x0 is not None
            else np.asarray(result.initial_states)[i][: len(fem.model.states)]
        )
        e_f = np.asarray(fem.innovations[i])
        h_f, _ = timing_directions(
            fem.model,
            frec,
            fem.params,
            np.asarray(fem.gain[i]),
            schedule.astype(int),
            x0,
            e_f,
            intervals=chosen,
        )
        # an interval whose direction is not finite in either fit is dropped
        ok = np.all(np.isfinite(h_o), axis=(0, 1)) & np.all(
            np.isfinite(h_f), axis=(0, 1)
        )
        h_o, h_f = h_o[..., ok], h_f[..., ok]
        chosen = [c for c, keep in zip(chosen, ok, strict=True) if keep]
        ss["o"] += np.sum(e_o**2, axis=0)
        ss["f"] += np.sum(e_f**2, axis=0)
        ss["oem"] += np.sum(project_out(e_o, h_o, np.mean(e_o**2, axis=0)) ** 2, 0)
        left = project_out(e_f, h_f, np.mean(e_f**2, axis=0))
        ss["fem"] += np.sum(left**2, axis=0)
        n += len(rec.t)
        intervals.append(chosen)
        adjusted.append(left)

    def lr(a, b):
        return max(0.0, float(n * np.sum(np.log(ss[a] / ss[b]))))

    return {
        "intervals": intervals,
        "innovations": adjusted,
        "likelihood_ratio": lr("oem", "fem"),
        "likelihood_ratio_sampled_input": lr("o", "f"),
    }


def _filter_error_parts(fem: FilterErrorFit, candidates: Sequence[str]):
    """What a score test of held parameters `candidates` at the filter-error fit
    needs, valid samples only, in time order (records one after the other):
    `(rows (samples, outputs, k), residuals (samples, outputs), curvature (k,),
    slope (k,), basis (samples, outputs, free), z)` as [`calibrate`][] takes them:
    each candidate's whitened innovation sensitivity with every free parameter and
    intensity projected out, the whitened innovations, the information and score
    of each projected direction, and an orthonormal basis of the free unknowns'
    sensitivities (a linearised refit leaves `e - basis basis^T e`)."""
    names = list(fem.model.parameters)
    free = np.concatenate([fem.free, np.ones(len(fem.F), bool)])
    jw = np.asarray(fem.jacobian)
    ew = np.asarray(fem.whitened)
    n_z = jw.shape[-1]
    lengths = [len(r.t) for r in fem.records]
    rows = np.concatenate([jw[i, :n] for i, n in enumerate(lengths)])
    e = np.concatenate([ew[i, :n] for i, n in enumerate(lengths)])
    flat = rows.reshape(-1, n_z)
    h = flat.T @ flat
    ff = np.flatnonzero(free)
    directions = []
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
        directions.append(d)
    d = np.stack(directions, axis=1) if directions else np.zeros((n_z, 0))
    projected = rows @ d  # (samples, outputs, k)
    curvature = np.einsum("nok,nok->k", projected, projected)
    slope = np.einsum("nok,no->k", projected, e)
    q, r = np.linalg.qr(flat[:, ff])
    keep = np.abs(np.diag(r)) > 1e-10 * np.max(np.abs(np.diag(r)), initial=0.0)
    basis = q[:, keep].reshape(rows.shape[0], rows.shape[1], -1)
    return projected, e, curvature, slope, basis, np.concatenate([fem.params, fem.F])


def score_at_filter_error(fem: FilterErrorFit, candidates: Sequence[str]) -> list[dict]:
    """Score test of held parameters `candidates` at the filter-error fit `fem`, on
    its innovations: per candidate its `statistic` (chi-square, 1 dof; variance
    with the innovations' remaining colour and covariance between outputs, as the
    output-error score's, [`score_variance`][]), raw `p_value`, the one
    Gauss-Newton step's `estimate` and `stderr`, with every free parameter and
    process-noise intensity re-adjusted (projected out). Same order as
    `candidates`."""
    names = list(fem.model.parameters)
    rows, e, curvature, slope, _, z = _filter_error_parts(fem, candidates)
    out = []
    for j, c in enumerate(candidates):
        i = names.index(c)
        s, g = float(curvature[j]), float(slope[j])
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
        # the step that lowers sum e^2: e - step * col
        step = g / s
        col = rows[..., j]
        var = max(
            float(score_variance(jnp.asarray(col), jnp.asarray(e - step * col))), s
        )
        stat = g**2 / var
        out.append(
            {
                "parameter": c,
                "statistic": stat,
                "p_value": float(scipy.stats.chi2.sf(stat, 1)),
                "estimate": float(z[i] - step),
                "stderr": float(np.sqrt(var) / s),
            }
        )
    return out


def survivor_threshold(
    fem: FilterErrorFit, candidates: Sequence[str], rule: "ProcessNoiseRule"
) -> Calibration | None:
    """The statistic a deterministic finding must exceed at the filter-error fit to
    survive process noise, from the fit's own innovations: the sieve bootstrap of
    [`calibrate`][] (the `1 - significance` point of the largest statistic over
    `candidates`, the output-error findings, when the whitened innovations are
    drawn from the autoregression fitted to them, the free parameters and
    intensities refitted to first order), as the output-error rule judges its
    residuals. `None` without candidates."""
    if not candidates:
        return None
    rows, e, curvature, slope, basis, _ = _filter_error_parts(fem, candidates)
    ok = curvature > 0
    if not ok.any():
        return None
    rows, curvature, slope = rows[..., ok], curvature[ok], slope[ok]
    top = int(np.argmax(slope**2 / curvature))
    # the null resamples the innovations the fit would leave with the strongest
    # finding freed: its own signature does not widen its null
    resample = e - (slope[top] / curvature[top]) * rows[..., top]
    same = DecisionRule(rule.significance, rule.replicates, rule.seed)
    return same.calibrate(rows, e, curvature, slope, resample, basis)


def _starts(result: Fit, process_noise, fem_options):
    """What every filter-error fit of the candidate shares: its keywords (the
    gain chosen once, at the output-error fit, see `choose_gain`), the
    output-error residuals that scale the start intensities (no refit from each
    start) and the initial states (the output-error fit's when it estimated
    them)."""
    options = {"throw": False, **fem_options}
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
    return options, residuals, x0


def best_filter_error(result: Fit, process_noise, **fem_options) -> FilterErrorFit:
    """The filter-error fit of `result`'s model and records from two starts, the
    output-error estimates and the model's start values, whichever reaches the
    lower det(R) (a converged one first). One start is not enough in turbulence:
    the output-error estimates can be far off (on 2 of 12 simulated HFB-320 flights
    in 0.3 m/s gusts CMq -630 and -290 for -27) and the filter-error fit from there
    stops in a local optimum with 10x the det(R)."""
    shared = _starts(result, process_noise, fem_options)
    return _best_of_two(result, process_noise, shared)


def _best_of_two(result: Fit, process_noise, shared) -> FilterErrorFit:
    fits = [
        _fit_from(result, process_noise, shared, start)
        for start in (result.params, result.model.start)
    ]
    return min(fits, key=_rank)


def _fit_from(result: Fit, process_noise, shared, start, gust=None) -> FilterErrorFit:
    """One filter-error fit of `result`'s model and records from `start`, with
    what `_starts` prepared once for every fit of the candidate."""
    options, residuals, x0 = shared
    return fit_filter_error(
        result.model,
        result.records,
        process_noise=process_noise,
        start=start,
        residuals=residuals,
        x0=x0,
        gust=gust,
        **options,
    )


def _rank(f: FilterErrorFit):
    return (not f.converged, f.cost if np.isfinite(f.cost) else np.inf)


def _unknowns(f: FilterErrorFit) -> int:
    """The estimated unknowns of a filter-error fit: free parameters (the gust's
    correlation time among them) and intensities."""
    return int(np.sum(f.free)) + len(f.F)


def white_or_coloured(
    result: Fit, process_noise, gust: Gust | None, **fem_options
) -> tuple[FilterErrorFit, dict]:
    """The filter-error fit the process-noise candidate judges: white process
    noise on `process_noise` ([`best_filter_error`][]), or, with a [`Gust`][],
    that white noise plus the coloured gust states, fitted from the white fit's
    estimates, whichever the log prefers by Akaike's criterion on the two
    maximum likelihoods, `N ln det R + 2 k` (`N` samples, `k` estimated
    unknowns): the coloured model is kept when it lowers `N ln det R` by more
    than twice the unknowns it adds (the gust intensities and its correlation
    time).

    **Returns:** `(fit, choice)`, `choice` JSON-ready: `model` (`"white"` or
    `"coloured"`), the two fits' `det_R`, `unknowns` and `converged`, and the
    coloured fit's correlation time `tau` (s), or its length scale `length` (m)
    when the gust names the airspeed."""
    shared = _starts(result, process_noise, fem_options)
    white = _best_of_two(result, process_noise, shared)
    choice = {
        "model": "white",
        "white": {
            "det_R": float(white.cost),
            "unknowns": _unknowns(white),
            "converged": bool(white.converged),
        },
    }
    if gust is None:
        return white, choice
    start = white.params if white.converged else result.params
    coloured = _fit_from(result, process_noise, shared, start, gust)
    names = coloured.model.parameters
    scale = "tau" if LOG_TAU in names else "length"
    log_scale = coloured.params[names.index(LOG_TAU if scale == "tau" else LOG_LENGTH)]
    choice["coloured"] = {
        "det_R": float(coloured.cost),
        "unknowns": _unknowns(coloured),
        "converged": bool(coloured.converged),
        scale: float(np.exp(log_scale)),
    }
    n = sum(len(r.t) for r in result.records)

    def aic(f):
        return n * float(np.log(f.cost)) + 2 * _unknowns(f)

    choice["fits"] = {"white": white, "coloured": coloured}
    if coloured.converged and np.isfinite(coloured.cost) and coloured.cost > 0:
        if not white.converged or aic(coloured) < aic(white):
            choice["model"] = "coloured"
            return coloured, choice
    return white, choice


def process_noise_candidate(
    result: Fit,
    ranking: list[dict],
    process_noise: Sequence[str] | Mapping[str, float],
    *,
    rule: ProcessNoiseRule = ProcessNoiseRule(),
    gust: Gust | None = None,
    **fem_options,
) -> tuple[FilterErrorFit, list[dict], str | None]:
    """Score process noise at the output-error fit `result` whose held candidates
    `ranking` ranks (rows of [`score_candidates`][]), see the module.

    **Arguments:** `process_noise`: the states with process noise (names, or a dict
    of start intensities, state units / sqrt(s)); `rule`: the thresholds; `gust`:
    a [`Gust`][] to offer coloured turbulence besides white noise (the log
    chooses, [`white_or_coloured`][]); further
    keywords go to [`fit_filter_error`][] (`full_R`, `rtol`, `max_iter`).

    **Returns:** `(fem, ranking, message)`: the filter-error fit of `result`'s model
    (candidates held; the better of two starts, [`best_filter_error`][]), the new
    ranking (every deterministic row gains `statistic_under_process_noise`, and for
    an output-error finding when process noise is present
    `threshold_under_process_noise` and `p_value_under_process_noise` (family-wise,
    from the filter-error fit's bootstrap), `survives_process_noise` and
    `significant_output_error` (the calibrated output-error verdict); `significant`
    is that verdict, taken away when process noise is present and the term does not
    survive; one `process_noise` row with `statistic` (LR), `dof`, `p_value`
    (Bonferroni), `likelihood_ratio_passes`, `turbulence_evidence` (the
    innovations' check, [`turbulence_evidence`][], when the likelihood ratio
    passes), `process_noise_present`, `cost_reduction` (measured, not predicted),
    `intensities` and `intensities_stderr` by state, `filter_error_estimates` and
    `filter_error_stderr`, `constraint_active`, `hard_to_tell_from` (findings
    taken away); its `estimate`/`stderr`/`parameter` are those of the intensity
    best determined, `F[state]`), and the verdict when process noise is present
    (`None` otherwise: the output-error verdict stands)."""
    if result.bias_outputs:
        raise ValueError(
            "the filter-error method has no output biases: score process noise at "
            "an output-error fit without them"
        )
    fem, choice = white_or_coloured(result, process_noise, gust, **fem_options)
    cands = [r["parameter"] for r in ranking]
    k = len(cands) + 1
    lr, fall = likelihood_ratio(result, fem) if fem.converged else (0.0, 0.0)
    # the input is known at its samples only: its unknown motion inside the
    # intervals where it steps is a nuisance of the null and the alternative alike
    timing = input_timing(result, fem) if fem.converged else None
    if timing is not None and any(timing["intervals"]):
        lr = timing["likelihood_ratio"]
    # the coloured model's correlation time is an unknown the null lacks too
    dof = _unknowns(fem) - int(np.sum(result.free))
    p = float(min(1.0, scipy.stats.chi2.sf(lr, dof) * k))
    evidence = (
        turbulence_evidence(
            result, fem, rule, None if timing is None else timing["innovations"]
        )
        if fem.converged and p < rule.significance
        else None
    )
    present = evidence is not None and evidence["passes"]
    # the innovations' check of each noise model fitted, for the report
    for kind, f in choice.pop("fits", {}).items():
        if f.converged:
            e = turbulence_evidence(result, f, rule)
            choice[kind]["innovations"] = {
                "statistic": e["statistic"],
                "output": e["output"],
                "threshold": e["threshold"],
            }
    under = (
        {r["parameter"]: r for r in score_at_filter_error(fem, cands)}
        if fem.converged
        else {}
    )
    # only a term the calibrated output-error rule named can be named at the end;
    # process noise may take it away (it does not survive at the filter-error fit)
    findings = [r["parameter"] for r in ranking if r["significant"]]
    survivors = (
        survivor_threshold(fem, findings, rule) if present and fem.converged else None
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
                threshold_under_process_noise=None,
                survives_process_noise=bool(r["significant"] and not present),
            )
        else:
            threshold = None if survivors is None else survivors.threshold
            row.update(
                statistic_under_process_noise=u["statistic"],
                p_value_under_process_noise=(
                    float(survivors.p_values(u["statistic"])[0])
                    if survivors is not None and r["significant"]
                    else None
                ),
                threshold_under_process_noise=threshold,
                # a sub-sample delay is the log's resolution, not physics, at
                # either fit (the shared rule, _diagnose/_rule.py)
                survives_process_noise=bool(
                    r["significant"]
                    and not r.get("resolution_limit", False)
                    and (
                        not present
                        or (threshold is not None and u["statistic"] > threshold)
                    )
                ),
            )
        row["significant_output_error"] = r["significant"]
        row["significant"] = bool(r["significant"] and row["survives_process_noise"])
        rows.append(row)
    first = sorted(
        (r for r in rows if r["significant"]),
        key=lambda r: -r["cost_reduction"],
    )
    # a missing term makes the filter-error fit look better too: process noise is
    # significant only when no term survives it (else re-test after adding it)
    significant = present and not first
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
        "likelihood_ratio_passes": bool(p < rule.significance),
        "turbulence_evidence": evidence,
        "process_noise_present": present,
        "resolution_limit": False,
        # the output-error findings that do not survive at the filter-error fit:
        # what the gusts can imitate on this record
        "hard_to_tell_from": [
            r["effect"]
            for r in rows
            if present and r["significant_output_error"] and not r["significant"]
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
        "noise_model": choice,
        "input_timing": None
        if timing is None
        else {
            "intervals": [len(c) for c in timing["intervals"]],
            "likelihood_ratio_sampled_input": timing["likelihood_ratio_sampled_input"],
        },
    }
    if present:
        rest = sorted(
            (r for r in rows if not r["significant"]),
            key=lambda r: -r["cost_reduction"],
        )
        new = [*first, pn, *rest]
    else:
        # no process noise: the output-error ranking stands, process noise last
        new = [*rows, pn]
    message = None
    if present:
        if first:
            top = first[0]
            message = (
                f"{top['effect']} is missing even with process noise allowed (score "
                f"statistic {top['statistic_under_process_noise']:.0f} at the "
                f"filter-error fit, threshold {top['threshold_under_process_noise']:.3g} "
                f"from its innovations): {top['parameter']} = {top['estimate']:.4g} "
                f"+/- {top['stderr']:.2g} by output error. Process noise (likelihood "
                f"ratio {lr:.0f} on {dof} dof) absorbs a missing term's misfit too: "
                "diagnose again with the term added to tell whether turbulence remains"
            )
        else:
            message = (
                f"{TURBULENCE_VERDICT} (likelihood ratio {lr:.0f} on {dof} dof, "
                f"p {p:.2g}; det(R) {100 * fall:.0f}% lower; {evidence['text']}; no "
                "output-error finding survives at the filter-error fit)"
            )
            if pn["hard_to_tell_from"]:
                message += (
                    "; the gusts cannot be told apart from "
                    + ", ".join(pn["hard_to_tell_from"])
                    + " on this record (named by output error, below the "
                    "filter-error fit's threshold)"
                )
    return fem, new, message
