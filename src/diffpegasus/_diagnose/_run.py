"""The three commands of the workflow as functions: each fits, writes its figures and
markdown report to `out` (if given) and returns a JSON-ready dict."""

import pathlib
import sys

from .._log._format import FlightLog
from .._report._markdown import (
    derivative_markdown,
    metrics_table,
    ranking_table,
    write_report,
)
from ._fit import ModelFit
from ._workflow import (
    check_addable,
    derivative_table,
    diagnose,
    fit,
    fit_metrics,
    localise,
    Settings,
)


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _name(log: FlightLog) -> str:
    return log.path.name if log.path is not None else "log"


def _localise_markdown(loc: dict) -> str:
    lines = [
        "Residual RMS over the channel's noise sigma (1: the model explains all "
        "but the noise). Worst places:",
        "",
    ]
    for w in loc["worst"]:
        lines.append(
            f"- {w['channel']}: {w['misfit_ratio']:.1f} x noise for "
            f"{w['variable']} in [{w['low']:.3g}, {w['high']:.3g}]"
        )
    for row in loc["thrust"]:
        cells = ", ".join(
            f"{c} {v:.1f}"
            for c, v in zip(loc["channels"], row["misfit_ratio"], strict=True)
        )
        lines.append(f"- thrust {row['regime']}: {cells}")
    return "\n".join(lines)


def run_compare(
    log: FlightLog,
    settings: Settings,
    out: pathlib.Path | None,
    base: ModelFit | None = None,
) -> tuple[dict, ModelFit]:
    """Fit the baseline model (unless given) and report how well it matches the
    measurements."""
    if base is None:
        _say(f"fitting the global model to {_name(log)} (compiles on first use)...")
        base = fit(log, (), settings)
    metrics = fit_metrics(base)
    loc = localise(base)
    derivs = derivative_table(base)
    result = {**metrics, "localise": loc, "derivatives": derivs}
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        from .._report._discrepancy_plots import plot_fits, plot_regimes

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
                    "iterations.\n\n" + metrics_table(metrics),
                ),
                (
                    "Where it fails",
                    _localise_markdown(loc) + "\n\n![regimes](regimes.png)",
                ),
                (
                    "Fitted derivatives (1/rad, secant form CL = CLa alpha + CLde de; Cramér-Rao standard errors)",
                    derivative_markdown(derivs),
                ),
                ("Measured vs model", "![fit](compare.png)"),
            ],
        )
        _say(f"wrote {out / 'compare.md'} with compare.png and regimes.png")
    return result, base


def run_diagnose(
    log: FlightLog,
    settings: Settings,
    out: pathlib.Path | None,
    add: tuple[str, ...] = (),
    base: ModelFit | None = None,
) -> tuple[dict, ModelFit]:
    """Fit (with the effects `add`), then rank the library's other effects."""
    check_addable(tuple(add), settings)
    if base is None:
        _say(f"fitting the global model to {_name(log)} (compiles on first use)...")
        base = fit(log, add, settings)
    _say("score test of every candidate effect...")
    result = diagnose(base, settings)
    result["cost"] = base.cost
    result["model_effects"] = list(add)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        from .._report._discrepancy_plots import plot_ranking

        plot_ranking(result, out / "diagnose.png")
        write_report(
            out / "diagnose.md",
            f"diagnose: {_name(log)}",
            [
                ("Verdict", result["message"]),
                ("Ranking", ranking_table(result) + "\n\n![ranking](diagnose.png)"),
            ],
        )
        _say(f"wrote {out / 'diagnose.md'} and diagnose.png")
    return result, base


def run_fit(
    log: FlightLog,
    add: tuple[str, ...],
    settings: Settings,
    out: pathlib.Path | None,
    before: ModelFit | None = None,
) -> dict:
    """Fit without and with the effects `add`; before/after metrics and the effects'
    estimates."""
    check_addable(tuple(add), settings)
    if before is None:
        _say(f"fitting the baseline model to {_name(log)} (compiles on first use)...")
        before = fit(log, (), settings)
    _say(f"refitting with {', '.join(add)}...")
    after = fit(log, tuple(add), settings, start=before)
    m_before, m_after = fit_metrics(before), fit_metrics(after)
    effects = after.effect_estimates()
    result = {
        "added": list(add),
        "before": m_before,
        "after": m_after,
        "cost_ratio": m_after["cost"] / m_before["cost"],
        "effects": effects,
    }
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        from .._report._discrepancy_plots import plot_fits

        plot_fits(
            [("before", before), ("after", after)],
            out / "fit.png",
            f"{_name(log)}: before and after adding {', '.join(add)}",
        )
        eff = "\n".join(
            f"- {name}: {e['parameter']} = {e['estimate']:.5g} +/- {e['stderr']:.2g} "
            f"(Cramér-Rao {e['stderr_crb']:.2g})"
            for name, e in effects.items()
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
                ("Per channel", metrics_table(m_after, m_before)),
                ("Before and after", "![fit](fit.png)"),
            ],
        )
        _say(f"wrote {out / 'fit.md'} and fit.png")
    return result
