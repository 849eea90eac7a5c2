"""Markdown reports a person opens: tables and the figures beside them."""

import pathlib

from .._files import write_text


def _f(x, fmt=".3g"):
    return "-" if x is None else format(x, fmt)


def metrics_table(
    metrics: dict, before: dict | None = None, names: tuple[str, ...] | None = None
) -> str:
    """One row per channel (`names`, default every channel of `metrics`); with
    `before`, the RMS before and after side by side."""
    head = "| channel | rms | nrms | bias [95% interval] | TIC | R^2 | rms/noise | Ljung-Box p | max xcorr(de) |"
    if before is not None:
        head = "| channel | rms before | rms after | TIC before | TIC after | rms/noise before | rms/noise after |"
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for name in names or tuple(metrics["channels"]):
        m = metrics["channels"][name]
        if before is not None:
            b = before["channels"][name]
            lines.append(
                f"| {name} | {_f(b['rms'])} | {_f(m['rms'])} | {_f(b['tic'])} | "
                f"{_f(m['tic'])} | {_f(b['misfit_ratio'])} | {_f(m['misfit_ratio'])} |"
            )
            continue
        lo, hi = m["bias_ci95"]
        lines.append(
            f"| {name} | {_f(m['rms'])} | {_f(m['nrms'])} | {_f(m['bias'])} "
            f"[{_f(lo)}, {_f(hi)}] | {_f(m['tic'])} | {_f(m['r2'], '.4f')} | "
            f"{_f(m['misfit_ratio'])} | {_f(m['ljung_box_p'], '.2g')} | "
            f"{_f(m.get('xcorr_input_max'), '.2f')} |"
        )
    return "\n".join(lines)


def _verdict(r: dict) -> str:
    if r.get("resolution_limit"):
        return "no (resolution limit)"
    if r["significant"]:
        return "yes"
    if r.get("given"):
        # above the first threshold but judged again once the significant effects
        # were fitted: say so, or a row above the threshold reads as a contradiction
        return (
            f"no ({r['statistic_given']:.1f} "
            f"{'<' if r['statistic_given'] <= r['threshold_given'] else '>'} "
            f"{r['threshold_given']:.3g} given "
            f"{', '.join(r['given'])})"
        )
    return "no"


def ranking_table(diagnosis: dict, top: int = 10) -> str:
    lines = [
        "| rank | effect | share of misfit (predicted det(R) fall) | score statistic | p-value | estimate | std. error | significant | hard to tell from |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for i, r in enumerate(diagnosis["ranking"][:top], 1):
        close = ", ".join(
            c
            if isinstance(c, str)
            else c["effect"]
            if c.get("correlation") is None
            else f"{c['effect']} ({c['correlation']:+.2f})"
            for c in r["hard_to_tell_from"]
        )
        lines.append(
            f"| {i} | {r['effect']} | {100 * r['cost_reduction']:.1f}% | "
            f"{r['statistic']:.1f} | {r['p_value']:.2g} | "
            f"{r.get('parameter', '')} = {r.get('estimate', float('nan')):.4g} | "
            f"{r.get('stderr', float('nan')):.2g} | {_verdict(r)} | {close} |"
        )
    return "\n".join(lines)


def derivative_markdown(rows: list[dict]) -> str:
    names = ("CLa", "CLde", "CDa", "CDde", "CMa", "CMde")
    lines = [
        "| Mach | alpha, deg | " + " | ".join(names) + " |",
        "|---|---|" + "---|" * len(names),
    ]
    import math

    for r in rows:
        cells = [f"{r[n][0]:.4g} +/- {r[n][1]:.2g}" for n in names]
        lines.append(
            f"| {r['mach']:.2f} | {math.degrees(r['alpha']):.1f} | "
            + " | ".join(cells)
            + " |"
        )
    return "\n".join(lines)


def write_report(
    path: pathlib.Path, title: str, sections: list[tuple[str, str]]
) -> None:
    """A markdown file: a title and `(heading, body)` sections."""
    text = [f"# {title}", ""]
    for heading, body in sections:
        text += [f"## {heading}", "", body, ""]
    write_text(path, "\n".join(text))
