"""Compare, localise, diagnose, add and refit: the discrepancy workflow on a log."""

import dataclasses

import jax
import numpy as np

from .._estimate._global_oem import score_test
from .._log._format import FlightLog
from .._vehicle._effects import EFFECTS, make_effect
from ._convergence import fit_budget, progress
from ._fit import block_weights, fit_model, ModelFit
from ._metrics import binned_misfit, channel_metrics, residual_noise_sigma
from ._model import ModelSpec, OUTPUTS
from ._rule import DecisionRule, DELAY_EFFECT, rule_summary, verdict


# Absorbed by a baseline with alpha^2 terms (alpha_order >= 2); and a bias on the
# altitude channel is the same as a shift of the (estimated) initial altitude.
_ALPHA_SQUARED = ("lift_alpha_squared", "drag_alpha_squared", "moment_alpha_squared")
_NOT_IDENTIFIABLE = ("sensor_bias:h",)


def default_candidates(alpha_order: int = 3) -> tuple[str, ...]:
    """The library effects a diagnosis tests: every effect, `sensor_bias` on every
    output channel; minus those the baseline already contains (the alpha^2 effects
    when `alpha_order >= 2`) and `sensor_bias:h` (indistinguishable from the initial
    altitude, which is estimated)."""
    names = [n for n in EFFECTS if n != "sensor_bias"]
    names += [f"sensor_bias:{c}" for c in OUTPUTS]
    drop = set(_NOT_IDENTIFIABLE) | (set(_ALPHA_SQUARED) if alpha_order >= 2 else set())
    return tuple(n for n in names if n not in drop)


@dataclasses.dataclass
class Settings:
    """How the model is built and fitted (see `diffpegasus compare --help`), and
    the decision rule of [`diagnose`][]: `significance`, the family-wise
    false-alarm level of a diagnosis, whose threshold comes from the fit's own
    residuals ([`DecisionRule`][]). `max_iter` is a budget, not a target: the fit
    stops when det(R) settles, and continues (in rounds of `round_iter`
    iterations, reported on the terminal) while it still falls, up to
    `max_iter`."""

    knots: int = 6
    knot_placement: str = "quantile"
    alpha_order: int = 3
    alpha_elevator: bool = True
    rate: float = 50.0
    node_interval: float = 1.0
    max_iter: int = 400
    round_iter: int = 50
    significance: float = 0.01

    def spec(self, log: FlightLog, extra: tuple[str, ...] = ()) -> ModelSpec:
        effects = tuple(dict.fromkeys(default_candidates(self.alpha_order) + extra))
        return ModelSpec(
            s_ref=log.s_ref,
            c_ref=log.c_ref,
            knots=self.knots,
            knot_placement=self.knot_placement,
            alpha_order=self.alpha_order,
            alpha_elevator=self.alpha_elevator,
            effects=effects,
        )


def fit(
    log: FlightLog,
    add: tuple[str, ...] = (),
    settings: Settings | None = None,
    start: ModelFit | None = None,
) -> ModelFit:
    """Fit the global model with the effects `add` estimated (canonical names)."""
    settings = settings or Settings()
    check_addable(add, settings)
    spec = settings.spec(log, tuple(add))
    done = 0
    while True:
        # rounds of one compiled length, continued from where the last stopped
        size = min(settings.round_iter, settings.max_iter - done)
        result = fit_model(
            log,
            spec,
            tuple(add),
            rate=settings.rate,
            node_interval=settings.node_interval,
            start=start,
            max_iter=size,
        )
        done += int(result.result.iterations)
        if bool(result.result.converged) or not np.isfinite(result.cost):
            return fit_budget(result, done, settings)
        if done >= settings.max_iter:
            return fit_budget(result, done, settings)
        progress(
            f"  {done} iterations: det(R) = {result.cost:.4g}, largest continuity "
            f"defect {float(result.result.defect):.2g} of the state scale; continuing"
        )
        start = result


def check_addable(add: tuple[str, ...], settings: Settings) -> None:
    """A clear error for an effect that cannot be added to the model."""
    for name in add:
        make_effect(name)
        if name in _NOT_IDENTIFIABLE:
            raise ValueError(
                f"{name} cannot be estimated: it is the same unknown as the initial "
                "altitude, which the fit estimates"
            )
        if name in _ALPHA_SQUARED and settings.alpha_order >= 2:
            raise ValueError(
                f"{name} is already in the baseline (its alpha^2 terms); to test it "
                "as an effect use --alpha-order 1"
            )


def channel_noise(fit: ModelFit) -> np.ndarray:
    """White-noise sigma of every output at the model's samples, SI units: the
    sidecar's `noise_sigmas` (per log sample) scaled to a block mean, where given
    and positive; else [`residual_noise_sigma`][] of the fit's residual (its
    spectrum above the model's bandwidth), which does not count real signal."""
    given = fit.log.metadata.get("noise_sigmas") or {}
    w = block_weights(fit.step) if fit.step > 1 else np.ones(1)
    scale = np.sqrt(np.sum(w**2)) / np.sum(w)
    r = fit.residuals
    out = []
    for i, name in enumerate(OUTPUTS):
        sigma = given.get(name) if isinstance(given, dict) else None
        if isinstance(sigma, int | float) and sigma > 0:
            out.append(float(sigma) * scale)
        else:
            out.append(residual_noise_sigma(r[:, i]))
    return np.array(out)


def fit_metrics(fit: ModelFit) -> dict:
    """`{"cost": det R, "converged": .., "channels": {name: metrics}}`."""
    de = np.asarray(fit.problem.inputs[:, 0])
    noise = channel_noise(fit)
    channels = {
        name: channel_metrics(fit.measured[:, i], fit.model[:, i], de, noise[i])
        for i, name in enumerate(OUTPUTS)
    }
    return {
        "cost": fit.cost,
        "converged": bool(fit.result.converged),
        "iterations": int(fit.result.iterations),
        "channels": channels,
    }


def derivative_table(fit: ModelFit, points: int = 5) -> list[dict]:
    """The fitted derivatives (1/rad) with Cramér-Rao standard errors at `points`
    Mach numbers spread over the record, each at the record's mean alpha there, in
    the database's (secant) form `CL = CLa(alpha, M) alpha + CLde de`, so
    `CLa = a_1 + a_2 alpha + ...` and `CLde = b + c alpha`, comparable with a log's `true_*` columns:
    `{"mach", "alpha", "CLa": [est, sd], ...}`."""
    spec = fit.spec
    mach = fit.log["mach"][fit.index]
    alpha = fit.log["alpha"][fit.index]
    order = np.argsort(mach)
    chunks = np.array_split(order, points)
    theta = np.asarray(fit.result.params[: spec.n_aero])
    sd = np.asarray(fit.result.stderr[: spec.n_aero])
    cov = np.asarray(fit.result.correlation[: spec.n_aero, : spec.n_aero]) * np.outer(
        sd, sd
    )
    basis_all = np.asarray(fit.problem.inputs[:, -spec.knots :])
    per = len(spec.terms) * spec.knots
    rows = []
    for chunk in chunks:
        b = basis_all[chunk].mean(axis=0)
        a = float(alpha[chunk].mean())
        row = {"mach": float(mach[chunk].mean()), "alpha": a}
        for j, coef in enumerate(("CL", "CD", "CM")):
            # sum_p a_p alpha^(p-1) (the secant slope), and the elevator term
            g_alpha = np.zeros(spec.n_aero)
            g_de = np.zeros(spec.n_aero)
            for p in range(1, spec.alpha_order + 1):
                sl = slice(j * per + (p - 1) * spec.knots, j * per + p * spec.knots)
                g_alpha[sl] = a ** (p - 1) * b
            start = j * per + spec.alpha_order * spec.knots
            g_de[start : start + spec.knots] = b
            if spec.alpha_elevator:  # CLde(alpha) = b + c alpha
                g_de[start + spec.knots : start + 2 * spec.knots] = a * b
            for name, gvec in ((f"{coef}a", g_alpha), (f"{coef}de", g_de)):
                row[name] = [
                    float(gvec @ theta),
                    float(np.sqrt(max(gvec @ cov @ gvec, 0.0))),
                ]
        rows.append(row)
    return rows


def localise(fit: ModelFit, bins: int = 5, segment: float = 5.0) -> dict:
    """Where the misfit is: residual RMS over the noise sigma (1 = noise only) per
    channel, by time segment, and by bins of Mach, alpha, dynamic pressure and thrust
    on/off."""
    r = fit.residuals
    noise = channel_noise(fit)
    noise = np.where(noise > 0, noise, 1.0)
    t = fit.t
    log = fit.log
    idx = fit.index
    quant = lambda x: np.unique(np.quantile(x, np.linspace(0, 1, bins + 1)))  # noqa: E731
    thrust = log["thrust"][idx]
    on = thrust > 0.01 * np.max(np.abs(thrust))
    out = {
        "channels": list(OUTPUTS),
        "noise": noise.tolist(),
        "time": binned_misfit(r, noise, t, np.arange(t[0], t[-1] + segment, segment)),
        "mach": binned_misfit(r, noise, log["mach"][idx], quant(log["mach"][idx])),
        "alpha_deg": binned_misfit(
            r,
            noise,
            np.rad2deg(log["alpha"][idx]),
            quant(np.rad2deg(log["alpha"][idx])),
        ),
        "qbar_kpa": binned_misfit(
            r, noise, log["qbar"][idx] / 1e3, quant(log["qbar"][idx] / 1e3)
        ),
        "thrust": [
            {
                "regime": name,
                "samples": int(sel.sum()),
                "misfit_ratio": (
                    np.sqrt(np.mean(r[sel] ** 2, axis=0)) / noise
                ).tolist(),
            }
            for name, sel in (("off", ~on), ("on", on))
            if sel.sum() >= 10
        ],
    }
    worst = []
    for key in ("time", "mach", "alpha_deg", "qbar_kpa"):
        for row in out[key]:
            for i, c in enumerate(OUTPUTS):
                worst.append((row["misfit_ratio"][i], c, key, row["low"], row["high"]))
    worst.sort(reverse=True)
    out["worst"] = [
        {"channel": c, "variable": k, "low": lo, "high": hi, "misfit_ratio": v}
        for v, c, k, lo, hi in worst[:5]
    ]
    return out


def diagnose(
    fit: ModelFit,
    settings: Settings | None = None,
    candidates: tuple[str, ...] | None = None,
) -> dict:
    """Rank the candidate effects by the predicted fall of the output-error cost from
    one Gauss-Newton step in each (score test with exact Jacobians), and decide
    which are significant.

    The decision is [`DecisionRule`][]'s, the same as the engine's
    [`score_candidates`][]: a candidate is **significant** when its score statistic
    (variance with the residuals' colour and their covariance between outputs)
    exceeds the `1 - settings.significance` point of the largest statistic over all
    candidates in block-bootstrap replicates of this fit's residuals, a threshold
    from the log itself holding that family-wise false-alarm level. The predicted
    share of det(R) it removes (`cost_reduction`) is reported beside it, not decided
    on. An actuator delay also needs an estimate of at least half a log sample
    interval (a smaller one is a `resolution_limit`: where steps of the input fall
    between samples shifts them by up to that much); a lead is never significant.

    **Returns:** `{"ranking": [{"effect", "parameter", "cost_reduction",
    "statistic", "p_value", "estimate", "stderr", "significant",
    "resolution_limit", "lead", "hard_to_tell_from", "threshold"}...],
    "significant": [...], "message": ..., "rule": {"text", "threshold",
    "false_alarm_level", ...}}`, significant rows first; `cost_reduction` is the
    predicted fractional fall of det(R).
    """
    settings = settings or Settings()
    spec = fit.spec
    free = np.asarray(fit.result.free)
    if candidates is None:
        candidates = tuple(e for e in spec.effects if not free[spec.effect_index(e)])
    idx = np.array([spec.effect_index(c) for c in candidates])
    st = jax.tree.map(np.asarray, score_test(fit.problem, fit.result, idx))
    resolution = 0.5 / fit.log.sample_rate
    rule = DecisionRule(settings.significance)
    ranking, _ = rule.decide(
        st,
        list(candidates),
        [make_effect(c).parameter for c in candidates],
        delays=[make_effect(c).name == DELAY_EFFECT for c in candidates],
        resolution=resolution,
    )
    return {
        "ranking": ranking,
        "significant": [r["effect"] for r in ranking if r["significant"]],
        "message": verdict(ranking, resolution),
        "rule": rule_summary(ranking),
    }
