"""The three commands of the workflow as functions: each fits a vehicle's model
(its registry entry), writes its figures and markdown report to `out` (if given)
and returns a JSON-ready dict."""

import pathlib
import sys

from .._diagnose._workflow import (
    derivative_table,
    diagnose,
    fit_log,
    fit_metrics,
    FlightFit,
    localise,
    MAX_ITER,
    ranking_report,
)
from .._log._format import FlightLog
from ._markdown import (
    derivative_markdown,
    metrics_table,
    ranking_table,
    write_index,
    write_report,
)
from ._units import channel_units, effect_unit, with_unit


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _name(log) -> str:
    if isinstance(log, FlightLog):
        return log.path.name if log.path is not None else "log"
    return pathlib.Path(log).name


def _localise_markdown(loc: dict) -> str:
    lines = [
        "Residual RMS over the channel's noise sigma (1: the model explains all "
        "but the noise). Worst places:",
        "",
    ]
    for w in loc["worst"]:
        lines.append(f"- {worst_place(w)}")
    for row in loc["thrust"]:
        cells = ", ".join(
            f"{c} {v:.1f}"
            for c, v in zip(loc["channels"], row["misfit_ratio"], strict=True)
        )
        lines.append(f"- thrust {row['regime']}: {cells}")
    return "\n".join(lines)


# the variables `localise` bins the misfit by: (words, unit)
_REGIME_WORDS = {
    "time": ("time", "s"),
    "alpha_deg": ("alpha", "deg"),
    "V": ("airspeed", "m/s"),
    "h_km": ("altitude", "km"),
}


def worst_place(w: dict) -> str:
    """One of `localise`'s worst places in words with units, e.g. `q: 4.2 x noise
    for time in [10, 15] s`."""
    words, unit = _REGIME_WORDS.get(w["variable"], (w["variable"], ""))
    return (
        f"{w['channel']}: {w['misfit_ratio']:.1f} x noise for {words} in "
        f"[{w['low']:.3g}, {w['high']:.3g}]{' ' + unit if unit else ''}"
    )


def _fitting(log, which: str = ""):
    """What to print once a log has been read and its fit begins."""

    def say(model) -> None:
        _say(f"fitting the {which}model to {_name(log)} (compiles on first use)...")

    return say


def run_compare(
    entry,
    log,
    out: pathlib.Path | None,
    base: FlightFit | None = None,
    max_iter: int | None = MAX_ITER,
) -> tuple[dict, FlightFit]:
    """Fit `entry`'s model (unless `base` is given) to `log` (a path or a
    [`FlightLog`][]) and report how well it matches the measurements."""
    if base is None:
        base = fit_log(
            entry,
            log,
            max_iter=max_iter,
            say=_fitting(log, ""),
        )
    _say("measuring the fit per channel and by flight regime...")
    metrics = fit_metrics(base)
    loc = localise(base)
    derivs = derivative_table(base)
    result = {**metrics, "localise": loc, "derivatives": derivs}
    # the unit each channel is shown in (the log's own where its column map gave
    # one) and the factor from the SI values of the report
    units = channel_units(base.outputs, base.spec.columns)
    result["display_units"] = {n: list(u) for n, u in units.items()}
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        from ._discrepancy_plots import plot_fits, plot_regimes

        plot_fits(
            [("baseline", base)],
            out / "compare.png",
            f"{_name(log)}: measured vs model",
        )
        plot_regimes(base, out / "regimes.png")
        write_report(
            out / "compare.md",
            f"compare: {_name(log)}",
            [
                (
                    "Fit per channel",
                    f"Output-error cost det(R) = {base.cost:.4g}; "
                    f"converged: {metrics['converged']} after {metrics['iterations']} "
                    "iterations. The rms and bias are in each channel's unit; "
                    "the other columns are ratios.\n\n"
                    + metrics_table(metrics, names=base.outputs, units=units),
                ),
                (
                    "Where it fails",
                    _localise_markdown(loc) + "\n\n![regimes](regimes.png)",
                ),
                (
                    "Fitted derivatives (1/rad, secant form CL = CLa alpha + CLde de; Cramér-Rao standard errors)",
                    derivative_markdown(derivs or []),
                ),
                ("Measured vs model", "![fit](compare.png)"),
            ],
        )
        write_index(out)
        _say(f"wrote {out / 'compare.md'} with compare.png, regimes.png and index.md")
    return result, base


def run_diagnose(
    entry,
    log,
    out: pathlib.Path | None,
    add: tuple[str, ...] = (),
    base: FlightFit | None = None,
    process_noise=None,
    max_iter: int | None = MAX_ITER,
) -> tuple[dict, FlightFit]:
    """Fit (with the effects `add`; unless `base` is given), then rank the
    vehicle's other candidate effects ([`diagnose_model`][] without a `base`);
    with `process_noise` (states, or a dict of start intensities) process noise
    is a candidate too (the filter-error fit's likelihood ratio)."""
    if base is None:
        from .._diagnose._candidates import diagnose_model

        spec, records = entry.problem([log], add=tuple(add), candidates=True)
        _fitting(log)(spec.model)
        fitted, ranking = diagnose_model(
            spec.model,
            records,
            spec.candidates,
            process_noise=process_noise or None,
            shooting=spec.shooting,
            initial_state=spec.initial_state,
            biases=spec.biases,
            max_iter=max_iter,
            throw=False,
        )
        base = FlightFit(spec, fitted, tuple(add))
        _say("score test of every candidate effect...")
        result = ranking_report(base, ranking)
        verdicts = [r["verdict"] for r in ranking if r.get("verdict")]
        if verdicts:
            result["message"] = verdicts[0]
    else:
        _say("score test of every candidate effect...")
        result = diagnose(base)
    result["cost"] = base.cost
    result["converged"] = base.converged
    result["iterations"] = int(base.result.iterations)
    result["model_effects"] = list(add)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        from ._discrepancy_plots import plot_ranking

        plot_ranking(result, out / "diagnose.png")
        write_report(
            out / "diagnose.md",
            f"diagnose: {_name(log)}",
            [
                ("Verdict", result["message"]),
                ("Ranking", ranking_table(result) + "\n\n![ranking](diagnose.png)"),
            ],
        )
        write_index(out)
        _say(f"wrote {out / 'diagnose.md'}, diagnose.png and index.md")
    return result, base


def run_fit(
    entry,
    log,
    add: tuple[str, ...],
    out: pathlib.Path | None,
    before: FlightFit | None = None,
    max_iter: int | None = MAX_ITER,
) -> tuple[dict, FlightFit]:
    """Fit without and with the effects `add`; before/after metrics and the effects'
    estimates, and the refit."""
    if before is None:
        before = fit_log(
            entry,
            log,
            max_iter=max_iter,
            say=_fitting(log, "baseline "),
        )
    _say(f"refitting with {', '.join(add)}...")
    after = fit_log(entry, log, tuple(add), start=before, max_iter=max_iter)
    m_before, m_after = fit_metrics(before), fit_metrics(after)
    effects = after.effect_estimates()
    result = {
        "added": list(add),
        "before": m_before,
        "after": m_after,
        "cost_ratio": m_after["cost"] / m_before["cost"],
        "effects": effects,
        "unexplained": unexplained_channels(m_after, add),
        "display_units": {
            n: list(u)
            for n, u in channel_units(after.outputs, after.spec.columns).items()
        },
    }
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        from ._discrepancy_plots import plot_fits

        plot_fits(
            [("before", before), ("after", after)],
            out / "fit.png",
            f"{_name(log)}: before and after adding {', '.join(add)}",
        )
        eff = "\n".join(
            f"- {name}: {e['parameter']} = "
            f"{with_unit(e['estimate'], effect_unit(name), '.5g')} +/- "
            f"{with_unit(e['stderr'], effect_unit(name), '.2g')} "
            f"(Cramér-Rao {with_unit(e['stderr_crb'], effect_unit(name), '.2g')})"
            for name, e in effects.items()
        )
        left = "\n".join(f"- {u['message']}" for u in result["unexplained"]) or (
            "Every channel's residual is within twice its noise after the refit."
        )
        write_report(
            out / "fit.md",
            f"fit: {_name(log)} + {', '.join(add)}",
            [
                (
                    "Cost",
                    f"det(R) before {m_before['cost']:.4g}, after {m_after['cost']:.4g} "
                    f"(ratio {result['cost_ratio']:.3g})",
                ),
                ("Added effects", eff),
                (
                    "Per channel",
                    metrics_table(
                        m_after,
                        m_before,
                        names=after.outputs,
                        units=channel_units(after.outputs, after.spec.columns),
                    ),
                ),
                ("What the refit leaves unexplained", left),
                ("Before and after", "![fit](fit.png)"),
            ],
        )
        write_index(out)
        _say(f"wrote {out / 'fit.md'}, fit.png and index.md")
    return result, after


def unexplained_channels(metrics: dict, added=()) -> list[dict]:
    """The channels whose residual stays well above their noise after a fit: rms
    over the log's own noise estimate above 2 (the noise then explains under a
    quarter of the residual's variance) and the residual not white (Ljung-Box p
    below 0.01), each with words on what it may mean."""
    out = []
    for name, m in metrics["channels"].items():
        ratio, p = m.get("misfit_ratio"), m.get("ljung_box_p")
        if ratio is None or p is None or not (ratio > 2.0 and p < 0.01):
            continue
        added_text = f" with {', '.join(added)}" if added else ""
        out.append(
            {
                "channel": name,
                "misfit_ratio": ratio,
                "ljung_box_p": p,
                "message": (
                    f"{name} stays {ratio:.1f}x its noise after the fit{added_text} "
                    f"(residual not white, Ljung-Box p {p:.2g}): something the model "
                    f"still lacks acts on {name} (another effect: run `diagnose` again "
                    f"with --add for what was added; or a sensor error on {name}: "
                    "bias, scale factor, misalignment or position), or the log's "
                    "noise on it is not white (structural vibration, quantisation), "
                    "which makes the noise estimate low"
                ),
            }
        )
    return out
