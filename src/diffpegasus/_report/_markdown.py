"""Markdown reports a person opens: tables and the figures beside them."""

import pathlib

from .._files import write_text


def _f(x, fmt=".3g"):
    return "-" if x is None else format(x, fmt)


def _scaled(x, factor):
    return None if x is None else x * factor


def metrics_table(
    metrics: dict,
    before: dict | None = None,
    names: tuple[str, ...] | None = None,
    units: dict[str, tuple[str, float]] | None = None,
) -> str:
    """One row per channel (`names`, default every channel of `metrics`); with
    `before`, the RMS before and after side by side. `units`: `{channel: (unit,
    factor from SI)}` ([`channel_units`][]) the rms and bias are shown in (default
    SI); TIC, R^2, rms/noise and p are ratios, without unit."""
    from ._units import channel_units

    names = names or tuple(metrics["channels"])
    units = units or channel_units(names)
    head = "| channel | unit | rms | nrms | bias [95% interval] | TIC | R^2 | rms/noise | Ljung-Box p | max xcorr(input) |"
    if before is not None:
        head = "| channel | unit | rms before | rms after | TIC before | TIC after | rms/noise before | rms/noise after |"
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for name in names:
        m = metrics["channels"][name]
        unit, k = units.get(name, ("SI", 1.0))
        if before is not None:
            b = before["channels"][name]
            lines.append(
                f"| {name} | {unit} | {_f(_scaled(b['rms'], k))} | "
                f"{_f(_scaled(m['rms'], k))} | {_f(b['tic'])} | "
                f"{_f(m['tic'])} | {_f(b['misfit_ratio'])} | {_f(m['misfit_ratio'])} |"
            )
            continue
        lo, hi = m["bias_ci95"]
        lines.append(
            f"| {name} | {unit} | {_f(_scaled(m['rms'], k))} | {_f(m['nrms'])} | "
            f"{_f(_scaled(m['bias'], k))} [{_f(_scaled(lo, k))}, "
            f"{_f(_scaled(hi, k))}] | {_f(m['tic'])} | {_f(m['r2'], '.4f')} | "
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
        "| rank | effect | share of misfit (predicted det(R) fall) | score statistic | p-value | estimate | std. error | unit | significant | hard to tell from |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    from ._units import effect_unit

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
            f"{r.get('stderr', float('nan')):.2g} | "
            f"{effect_unit(r['effect']) or '-'} | {_verdict(r)} | {close} |"
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


def planted_versus_found(
    hidden: dict[str, float], effects: dict[str, dict]
) -> list[str]:
    """One line per planted effect: its value beside the one the refit found, with
    the standard error and how many standard errors apart they are, e.g. `hidden
    actuator_delay 0.02 s, found 0.02003 s ± 0.00031 s (0.1 standard errors
    apart)`; or that the refit did not add it.

    **Arguments:** `hidden`, `{effect: planted value}` (SI units); `effects`, the
    refit's added effects as [`run_fit`][] reports them (`estimate`, `stderr`).
    """
    from ._units import effect_unit, with_unit

    lines = []
    for name, value in hidden.items():
        unit = effect_unit(name)
        planted = f"hidden {name} {with_unit(value, unit, '.3g')}"
        e = effects.get(name)
        if e is None or e.get("estimate") is None:
            added = ", ".join(effects) or "nothing"
            lines.append(f"{planted}; not found (the refit added {added})")
            continue
        est, sd = e["estimate"], e["stderr"]
        apart = abs(est - value) / sd if sd and sd > 0 else float("nan")
        lines.append(
            f"{planted}, found {with_unit(est, unit, '.4g')} ± "
            f"{with_unit(sd, unit, '.2g')} ({apart:.1f} standard errors apart)"
        )
    return lines


# what each file a command writes holds, for the index page of its folder
_CONTENTS = {
    "index.md": None,
    "flight.csv": "the simulated flight log (its sidecar flight.json: how it was made)",
    "flight.json": "the flight log's sidecar: sample rate, geometry, planted effects",
    "trajectory.png": "the flight: altitude, Mach, angle of attack, elevator, dynamic pressure, thrust, mass, CG and cp",
    "compare.md": "how well the model fits: per-channel metrics, where it fails, fitted derivatives",
    "compare.png": "measured against model for every channel, the whole record and a zoom on where the model fails most",
    "regimes.png": "residual over noise by flight regime (alpha, airspeed, altitude; thrust on and off)",
    "diagnose.md": "which candidate effect explains the misfit: the ranking and the verdict",
    "diagnose.png": "the ranking: predicted fall of the cost per candidate effect",
    "fit.md": "the refit with the added effects: cost and metrics before and after, the effects' values",
    "fit.png": "measured against the model before and after the refit, with a zoom on where it failed most",
    "summary.md": "the planted effect beside the one found, and what stays unexplained",
    "design.json": "the designed input and the predicted standard errors of every input",
    "design_inputs.png": "the excitations and the alpha response under the same limits",
    "design_stderr.png": "predicted standard errors per derivative and input",
}
_SUFFIX = {
    ".md": "report",
    ".png": "figure",
    ".csv": "table",
    ".json": "data (JSON)",
    ".eqx": "trained network",
}


def write_index(folder: pathlib.Path, title: str | None = None) -> pathlib.Path:
    """Write `folder/index.md`: every file in the folder (not in subfolders) with
    what it holds, reports first, then figures, then data; returns its path."""
    folder = pathlib.Path(folder)
    files = sorted(
        (f for f in folder.iterdir() if f.is_file() and not f.name.startswith(".")),
        key=lambda f: (
            [".md", ".png", ".csv", ".json"].index(f.suffix)
            if f.suffix in (".md", ".png", ".csv", ".json")
            else 4,
            f.name,
        ),
    )
    lines = [f"# {title or folder.name}", "", "| file | what it holds |", "|---|---|"]
    for f in files:
        if f.name == "index.md":
            continue
        what = _CONTENTS.get(f.name)
        if what is None:
            what = _describe(f.name)
        link = f"[{f.name}]({f.name})"
        lines.append(f"| {link} | {what} |")
    path = folder / "index.md"
    write_text(path, "\n".join(lines) + "\n")
    return path


def _describe(name: str) -> str:
    stem, suffix = pathlib.Path(name).stem, pathlib.Path(name).suffix
    if stem.endswith("_estimates"):
        method = stem.removesuffix("_estimates").upper()
        return f"{method} derivative estimates per window ({'values' if suffix == '.csv' else 'figure'})"
    if stem.startswith("fit_"):
        return f"measured against model, record {stem.removeprefix('fit_')}"
    return _SUFFIX.get(suffix, "file")
