"""`vehicles`, `fit` and `demo`: fit a vehicle or model file, refit with effects added."""

import dataclasses
import pathlib
from typing import Annotated

import typer

from .._errors import LogError
from ._common import (
    _banner,
    _check_out,
    _entry,
    _fail,
    _global_fit_failed,
    _json_out,
    _os_error,
    AddOption,
    AlphaOrderOption,
    app,
    assignments,
    ColumnsOption,
    FIT,
    FIT_FAILED,
    FixOption,
    JsonOption,
    KnotsOption,
    MaxIterOption,
    MethodOption,
    ModelOption,
    NodeOption,
    OUTPUT,
    parse_assignment_text,
    positive,
    ProcessNoiseOption,
    RateOption,
    ReportOption,
    ResampleOption,
    VehicleOption,
)


FIT_PANEL = "Fit and diagnose"


def _fit_model(
    entry,
    logs,
    columns,
    fix,
    bias,
    initial_state,
    shooting_interval,
    out,
    as_json,
    add=(),
    show_channels=False,
    method="oem",
    process_noise=(),
    max_iter=None,
):
    """Fit `entry`'s model (a vehicle's registry entry) to `logs` (one manoeuvre
    each) by output or filter error; print or `--json` the report."""
    from .._estimate import MultipleShooting
    from ._fem import check_method, format_fem_table, run_model_fem
    from ._runners import format_channels, format_table, run_model_fit

    try:
        check_method(method)
    except LogError as e:
        _fail(str(e))
    if method == "fem":
        if bias or initial_state == "estimated" or shooting_interval is not None:
            _fail(
                "--method fem holds each record's initial state (the filter corrects "
                "it) on one segment without output biases: --bias, --initial-state "
                "estimated and --shooting-interval go with --method oem"
            )
        if out is not None:
            _fail(
                "--out with --method fem: the report figures are of output-error "
                "fits; use --json for the filter-error fit"
            )
    elif process_noise:
        _fail("--process-noise goes with --method fem")
    if method not in ("oem", "fem") and (
        bias or initial_state or shooting_interval is not None or out is not None
    ):
        _fail(
            f"--method {method} runs with its default settings: --bias, "
            "--initial-state, --shooting-interval and --out go with --method oem"
        )

    if initial_state not in (None, "fixed", "estimated"):
        _fail(f"--initial-state must be fixed or estimated, got {initial_state!r}")
    if shooting_interval is not None and not shooting_interval > 0:
        _fail(f"--shooting-interval must be positive, got {shooting_interval}")
    _check_out(out, "folder")
    try:
        # with --add, compose every candidate (the others held at zero, left out of
        # the report): the same program as `diagnose` of this vehicle compiled
        spec, records = entry.problem(
            logs, columns=columns, add=tuple(add), candidates=bool(add)
        )
        if method == "fem":
            report = run_model_fem(
                spec,
                logs,
                holds=fix or (),
                process_noise=process_noise,
                records=records,
                max_iter=max_iter,
            )
        elif method != "oem":
            report = _run_registered(spec, logs, columns, fix or (), method, max_iter)
        else:
            report = run_model_fit(
                spec,
                logs,
                columns=columns,
                holds=fix or (),
                initial_state=initial_state,
                biases=tuple(bias) if bias else None,
                shooting=None
                if shooting_interval is None
                else MultipleShooting(interval=shooting_interval),
                out=out,
                records=records,
                max_iter=max_iter,
            )
    except LogError as e:
        _fail(str(e))
    except OSError as e:
        _fail(_os_error(e))
    if as_json:
        _json_out(report)
    else:
        if method == "fem":
            typer.echo(format_fem_table(report))
        elif method == "oem":
            typer.echo(format_table(report))
        else:
            typer.echo(_format_registered(report))
        if show_channels and "channels" in report:
            typer.echo(format_channels(report["channels"]))
    if not report["converged"]:
        typer.echo(f"error: {', '.join(map(str, logs))}: {report['message']}", err=True)
        raise typer.Exit(code=FIT_FAILED)


def _run_registered(spec, logs, columns, holds, method, max_iter) -> dict:
    """Any registered estimator with its default settings: the report of the
    fields every result has ([`AbstractFit`][])."""
    import sys

    import numpy as np

    from .._estimate._entry import estimate
    from .._estimate._methods import ESTIMATORS
    from ._runners import load_records, num, parse_holds

    spec = parse_holds(list(holds), spec)
    records = load_records(spec, logs, columns)
    try:
        result = estimate(
            spec.model,
            records,
            ESTIMATORS[method](),
            max_iter=max_iter,
            throw=False,
            progress=sys.stderr.isatty(),
        )
    except ValueError as e:
        raise LogError(str(e)) from None
    ok = result.converged
    names = spec.model.parameters
    hidden = set(spec.candidates)
    shown = [i for i, n in enumerate(names) if n not in hidden]
    return {
        "method": method,
        "converged": ok,
        "message": result.message,
        "cost": num(result.cost),
        "iterations": int(result.iterations),
        "estimates": {names[i]: num(result.params[i]) if ok else None for i in shown},
        "stderr": {
            names[i]: num(result.stderr_corrected[i]) if ok and result.free[i] else None
            for i in shown
        },
        "stderr_crb": {
            names[i]: num(result.stderr[i]) if ok and result.free[i] else None
            for i in shown
        },
        "fixed": [names[i] for i in shown if not result.free[i]],
        "high_correlations": [
            {"a": a, "b": b, "correlation": c}
            for a, b, c in (result.high_correlations() if ok else [])
            if a not in hidden and b not in hidden and np.isfinite(c)
        ],
    }


def _format_registered(report: dict) -> str:
    lines = [f"{'parameter':>12s} {'estimate':>14s} {'std. error':>12s}"]
    for name, est in report["estimates"].items():
        sd = report["stderr"][name]
        if est is None:
            lines.append(f"{name:>12s} {'-':>14s}")
        elif sd is None:
            lines.append(f"{name:>12s} {est:14.6g} {'(held)':>12s}")
        else:
            lines.append(f"{name:>12s} {est:14.6g} {sd:12.4g}")
    lines.append(
        f"{report['method']}: cost {report['cost']:.6e}   iterations: "
        f"{report['iterations']}"
    )
    for c in report["high_correlations"]:
        lines.append(f"correlation {c['a']} / {c['b']}: {c['correlation']:+.3f}")
    return "\n".join(lines)


@app.command(rich_help_panel="Reference")
def vehicles(as_json: JsonOption = False):
    """List the built-in vehicles (use with --vehicle)."""
    from .._registry import vehicle_descriptions

    descriptions = vehicle_descriptions()
    if as_json:
        _json_out(descriptions)
        return
    for name, text in descriptions.items():
        typer.echo(f"{name:15s} {text}")


@app.command(rich_help_panel=FIT_PANEL)
def fit(
    logs: Annotated[
        list[pathlib.Path],
        typer.Argument(help="Flight log(s): one manoeuvre per file", metavar="LOG..."),
    ],
    vehicle: VehicleOption = "pegasus",
    model: ModelOption = None,
    columns: ColumnsOption = None,
    fix: FixOption = None,
    bias: Annotated[
        list[str] | None,
        typer.Option(
            help="Estimate a per-record bias on this output (repeatable)",
            rich_help_panel=FIT,
        ),
    ] = None,
    initial_state: Annotated[
        str | None,
        typer.Option(help="fixed or estimated (per record)", rich_help_panel=FIT),
    ] = None,
    shooting_interval: Annotated[
        float | None,
        typer.Option(
            help="Multiple shooting with a node every this many s",
            callback=positive,
            rich_help_panel=FIT,
        ),
    ] = None,
    add: AddOption = None,
    knots: KnotsOption = None,
    alpha_order: AlphaOrderOption = None,
    rate: RateOption = None,
    node_interval: NodeOption = None,
    out: ReportOption = None,
    as_json: JsonOption = False,
    resample: ResampleOption = False,
    method: MethodOption = "oem",
    process_noise: ProcessNoiseOption = None,
    max_iter: MaxIterOption = None,
):
    """Fit a vehicle's or model file's parameters to flight logs.

    Output error by default: estimates, standard errors, correlations, cost.
    `--method fem` (filter error) is for logs flown through turbulence: it adds the
    process-noise intensities and whether the filter's gain constraint binds.

    With `--add` on one log: refit with the named effects added, before/after
    metrics per channel and the effects' fitted values with standard errors.
    """
    entry = _entry(
        vehicle,
        model,
        knots=knots,
        alpha_order=alpha_order,
        rate=rate,
        node_interval=node_interval,
    )
    add = tuple(add or ())
    generic = (
        not add
        or len(logs) != 1
        or method != "oem"
        or columns is not None
        or fix
        or bias
        or initial_state
        or shooting_interval
    )
    if generic:
        _fit_model(
            entry,
            logs,
            columns,
            fix,
            bias,
            initial_state,
            shooting_interval,
            out,
            as_json,
            add,
            method=method,
            process_noise=tuple(process_noise or ()),
            max_iter=max_iter,
        )
        return
    log = logs[0]
    from .._report import _runs
    from ._common import _log_arg
    from ._runners import fit_report

    _check_out(out, "folder")
    try:
        result, after = _runs.run_fit(
            entry, _log_arg(log, resample), add, out, max_iter=max_iter
        )
    except LogError as e:
        _fail(str(e))
    except OSError as e:
        _fail(_os_error(e))
    # the refit as any fit reports it (estimates, standard errors, cost) beside
    # the before/after comparison
    result = {**fit_report(after.result, after.spec), **result}
    result["cost"] = result["after"]["cost"]
    failed = _global_fit_failed(
        result["after"], "the output-error fit with the added effects"
    )
    result["message"] = result["after"]["message"]
    if failed:
        result["effects"] = {name: None for name in result["effects"]}
        if out is not None:
            _banner(out / "fit.md", failed)
        if as_json:
            _json_out(result)
        typer.echo(f"error: {log}: {failed}", err=True)
        raise typer.Exit(code=FIT_FAILED)
    if as_json:
        _json_out(result)
        return
    _print_before_after(result)


def _print_before_after(result):
    b, a = result["before"], result["after"]
    typer.echo(
        f"output-error cost det(R): before {b['cost']:.4g}, after {a['cost']:.4g} "
        f"({1 / result['cost_ratio']:.3g}x lower)"
    )
    typer.echo(
        f"{'channel':>8s} {'unit':>8s} {'rms before':>11s} {'rms after':>11s} "
        f"{'TIC before':>11s} {'TIC after':>10s} {'rms/noise before':>17s} "
        f"{'rms/noise after':>16s}"
    )
    units = result.get("display_units", {})
    for name in b["channels"]:
        mb, ma = b["channels"][name], a["channels"][name]
        unit, k = units.get(name, ("SI", 1.0))
        typer.echo(
            f"{name:>8s} {unit:>8s} {k * mb['rms']:11.4g} {k * ma['rms']:11.4g} "
            f"{mb['tic']:11.4f} {ma['tic']:10.4f} {mb['misfit_ratio']:17.2f} "
            f"{ma['misfit_ratio']:16.2f}"
        )
    from .._report._units import effect_unit, with_unit

    for name, e in result["effects"].items():
        unit = effect_unit(name)
        typer.echo(
            f"{name}: {e['parameter']} = {with_unit(e['estimate'], unit, '.5g')} +/- "
            f"{with_unit(e['stderr'], unit, '.2g')}"
        )
    for u in result.get("unexplained", ()):
        typer.echo(f"note: {u['message']}")


@app.command(rich_help_panel=FIT_PANEL)
def demo(
    out: Annotated[
        pathlib.Path,
        typer.Option(help="Folder for the results", rich_help_panel=OUTPUT),
    ] = pathlib.Path("demo"),
    hidden: Annotated[
        str,
        typer.Option(
            help="The effect hidden in the simulated flight, NAME=VALUE",
            callback=assignments,
        ),
    ] = "actuator_delay=0.02",
    seed: Annotated[int, typer.Option(help="Seed of the simulated flight")] = 1,
    duration: Annotated[
        float | None,
        typer.Option(help="Flight length, s (default: to burnout)", callback=positive),
    ] = None,
    sample_rate: Annotated[
        float,
        typer.Option(help="Log rate of the simulated flight, Hz", callback=positive),
    ] = 100.0,
):
    """Plant an effect in a simulated Pegasus flight and find it again.

    The discrepancy workflow end to end: simulate a flight with a hidden effect,
    show the model failing, diagnose, add the top effect, refit, report the planted
    value beside the one found. Takes a few minutes (most of it compiling).
    """
    from .._log._format import write_log
    from .._report._markdown import planted_versus_found
    from .._report._plotting import plot_trajectory
    from .._report._runs import run_compare, run_diagnose, run_fit

    entry = _entry("pegasus")
    out.mkdir(parents=True, exist_ok=True)
    typer.echo(
        f"1. simulating a Pegasus flight (drop to burnout) with a hidden effect ({hidden})..."
    )
    try:
        log = entry.simulate(
            seed=seed, hidden=[hidden], duration=duration, sample_rate=sample_rate
        )
    except LogError as e:
        _fail(str(e))
    path = write_log(out / "flight.csv", log)
    log = dataclasses.replace(log, path=path)  # reports name the file
    plot_trajectory(log, out / "trajectory.png")
    typer.echo("2. compare: fitting the model without it (compiles on first use)...")
    metrics, base = run_compare(entry, log, out)
    for name, m in metrics["channels"].items():
        if m["misfit_ratio"] > 1.5:
            typer.echo(
                f"   {name}: residual rms {m['misfit_ratio']:.1f} x noise, not white (p {m['ljung_box_p']:.1g})"
            )
    typer.echo("3. diagnose: which library effect explains the misfit?")
    diag, _ = run_diagnose(entry, log, out, (), base)
    typer.echo(f"   {diag['message']}")
    for r in diag["ranking"][:3]:
        typer.echo(
            f"   {r['effect']:>24s} predicted cost fall {100 * r['cost_reduction']:5.1f}%  p {r['p_value']:.2g}"
        )
    if not diag["significant"]:
        typer.echo("nothing to add; done")
        return
    top = diag["significant"][0]
    typer.echo(f"4. fit --add {top}: refitting...")
    result, _ = run_fit(entry, log, (top,), out, base)
    _print_before_after(result)
    name, value = parse_assignment_text("--hidden", hidden, need_value=True)
    found = planted_versus_found({name: value}, result["effects"])
    for line in found:
        typer.echo(line)
    _write_summary(out, found, result)
    typer.echo(
        f"wrote {path}, trajectory.png and the reports compare.md, diagnose.md, "
        f"fit.md, summary.md (with their PNGs; index.md lists them) in {out}"
    )


def _write_summary(out: pathlib.Path, found: list[str], result: dict) -> None:
    """The demo's outcome in one page: planted against found, what stays
    unexplained, and the folder's index."""
    from .._report._markdown import write_index, write_report

    left = "\n".join(f"- {u['message']}" for u in result.get("unexplained", ()))
    write_report(
        out / "summary.md",
        "demo: the planted effect and the one found",
        [
            ("Planted and found", "\n".join(f"- {line}" for line in found)),
            (
                "What the refit leaves unexplained",
                left or "Every channel's residual is within twice its noise.",
            ),
            (
                "Reports",
                "[compare.md](compare.md) (the model without the effect), "
                "[diagnose.md](diagnose.md) (which effect explains the misfit), "
                "[fit.md](fit.md) (the refit with it).",
            ),
        ],
    )
    write_index(out, "demo: a planted effect found again")
