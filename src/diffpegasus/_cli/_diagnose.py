"""`compare` and `diagnose`: where a fit fails and which missing term explains it,
for any vehicle (its registry entry builds the model and the records)."""

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
    _log_arg,
    _os_error,
    AddOption,
    AlphaOrderOption,
    app,
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
    ProcessNoiseOption,
    RateOption,
    ReportOption,
    ResampleOption,
    VehicleOption,
)
from ._fit import _fit_model, FIT_PANEL


@app.command(rich_help_panel=FIT_PANEL)
def compare(
    log: Annotated[pathlib.Path, typer.Argument(help="Flight log file")],
    vehicle: VehicleOption = "pegasus",
    model: ModelOption = None,
    columns: ColumnsOption = None,
    fix: FixOption = None,
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
    """Fit the model to one log and show where it fails.

    Output error by default: per-channel metrics, whiteness of the residuals,
    misfit by flight regime, fitted derivatives with standard errors. With
    `--method fem` (filter error: process noise such as turbulence), per-channel
    metrics of the filter's innovations.
    """
    entry = _entry(
        vehicle,
        model,
        knots=knots,
        alpha_order=alpha_order,
        rate=rate,
        node_interval=node_interval,
    )
    if method != "oem" or process_noise or columns is not None or fix:
        _fit_model(
            entry,
            [log],
            columns,
            fix,
            None,
            None,
            None,
            out,
            as_json,
            show_channels=True,
            method=method,
            process_noise=tuple(process_noise or ()),
            max_iter=max_iter,
        )
        return
    from .._report import _runs

    _check_out(out, "folder")
    try:
        result, _ = _runs.run_compare(
            entry, _log_arg(log, resample), out, max_iter=max_iter
        )
    except LogError as e:
        _fail(str(e))
    except OSError as e:
        _fail(_os_error(e))
    failed = _global_fit_failed(result, "the output-error fit of the model")
    if failed:
        result["derivatives"] = None
        if out is not None:
            _banner(out / "compare.md", failed)
    if as_json:
        _json_out(result)
    else:
        _print_compare(result)
    if failed:
        typer.echo(f"error: {log}: {failed}", err=True)
        raise typer.Exit(code=FIT_FAILED)


def _print_compare(result):
    typer.echo(
        f"output-error cost det(R) = {result['cost']:.4g} ({result['iterations']} "
        "iterations)"
    )
    typer.echo(
        f"{'channel':>8s} {'unit':>8s} {'rms':>10s} {'TIC':>7s} {'R^2':>8s} "
        f"{'rms/noise':>9s} {'white p':>8s}"
    )
    units = result.get("display_units", {})
    for name, m in result["channels"].items():
        unit, k = units.get(name, ("SI", 1.0))
        typer.echo(
            f"{name:>8s} {unit:>8s} {k * m['rms']:10.3g} {m['tic']:7.3f} "
            f"{m['r2']:8.4f} {m['misfit_ratio']:9.2f} {m['ljung_box_p']:8.2g}"
        )
    from .._report._runs import worst_place

    for w in result["localise"]["worst"][:3]:
        typer.echo(f"worst: {worst_place(w)}")


def _print_ranking(report):
    from .._diagnose._rule import ranking_lines

    typer.echo(report["message"])
    if isinstance(report.get("rule"), dict):
        typer.echo(f"decision rule: {report['rule']['text']}")
    baseline = report.get("baseline")
    if isinstance(baseline, dict):
        typer.echo(f"baseline: {baseline['knots']} Mach functions; {baseline['rule']}")
    effects = [r for r in report["ranking"] if r["effect"] != "process_noise"]
    for r in report["ranking"]:
        if r["effect"] == "process_noise":
            mark = "*" if r["significant"] else " "
            typer.echo(
                f"{mark} {'process_noise':24s} statistic {r['statistic']:8.1f}  "
                f"p = {r['p_value']:.2g}  cost fall "
                f"{100 * r['cost_reduction']:5.1f}%  (likelihood ratio, "
                f"{r['dof']} dof) F = "
                + ", ".join(f"{k} {v:.3g}" for k, v in r["intensities"].items())
            )
    typer.echo("\n".join(ranking_lines(effects, top=len(effects))))


def _write_diagnosis(report: dict, out: pathlib.Path, name: str) -> None:
    from .._report._discrepancy_plots import plot_ranking
    from .._report._markdown import ranking_table, write_index, write_report

    out.mkdir(parents=True, exist_ok=True)
    plot_ranking(report, out / "diagnose.png")
    write_report(
        out / "diagnose.md",
        f"diagnose: {name}",
        [
            ("Verdict", report["message"]),
            ("Ranking", ranking_table(report) + "\n\n![ranking](diagnose.png)"),
        ],
    )
    write_index(out)
    typer.echo(f"wrote {out / 'diagnose.md'}, diagnose.png and index.md", err=True)


@app.command(rich_help_panel=FIT_PANEL)
def diagnose(
    log: Annotated[pathlib.Path, typer.Argument(help="Flight log file")],
    vehicle: VehicleOption = "pegasus",
    model: ModelOption = None,
    columns: ColumnsOption = None,
    fix: FixOption = None,
    add: AddOption = None,
    knots: KnotsOption = None,
    alpha_order: AlphaOrderOption = None,
    rate: RateOption = None,
    node_interval: NodeOption = None,
    out: ReportOption = None,
    as_json: JsonOption = False,
    resample: ResampleOption = False,
    process_noise: Annotated[
        list[str] | None,
        typer.Option(
            help="Score process noise (turbulence) on this state too (repeatable; "
            "default the vehicle's or model file's process_noise, hfb320: V, "
            "alpha, theta, q; `none` skips it)",
            rich_help_panel=FIT,
        ),
    ] = None,
    max_iter: MaxIterOption = None,
):
    """Rank the effects the model may be missing, or say that none is.

    Each candidate effect of the vehicle (or model file) is scored by how much of
    the misfit it would explain (score test with exact Jacobians). With process
    noise declared, process noise (turbulence) is a candidate too: the
    filter-error fit's likelihood ratio, and every effect tested again at that fit
    (a term missing even under process noise ranks first).
    """
    from ._fem import diagnosis_states, process_noise_diagnosis
    from ._runners import run_model_diagnose

    entry = _entry(
        vehicle,
        model,
        knots=knots,
        alpha_order=alpha_order,
        rate=rate,
        node_interval=node_interval,
    )
    _check_out(out, "folder")
    try:
        spec, records = entry.problem(
            [_log_arg(log, resample)],
            columns=columns,
            add=tuple(add or ()),
            candidates=True,
        )
        report = run_model_diagnose(
            spec,
            [log],
            holds=fix or (),
            process_noise=diagnosis_states(tuple(process_noise or ()), spec),
            records=records,
            max_iter=max_iter,
            score_process_noise=process_noise_diagnosis,
        )
        report["model_effects"] = list(add or ())
        if out is not None and report["ranking"]:
            _write_diagnosis(report, out, log.name)
    except LogError as e:
        _fail(str(e))
    except OSError as e:
        _fail(_os_error(e))
    if as_json:
        _json_out(report)
    else:
        _print_ranking(report)
    # an output-error fit stopped by turbulence is no failure when the filter-error
    # fit explains the record
    explained = report.get("filter_error", {}).get("converged", False)
    if not report["fit"]["converged"] and not explained:
        typer.echo(f"error: {log}: {report['message']}", err=True)
        raise typer.Exit(code=FIT_FAILED)
