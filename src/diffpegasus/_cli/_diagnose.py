"""`compare` and `diagnose`: where a fit fails and which missing term explains it."""

import pathlib
from typing import Annotated

import typer

from .._log._format import LogError
from ._common import (
    _banner,
    _check_addable,
    _check_out,
    _fail,
    _global_fit_failed,
    _json_out,
    _os_error,
    _read,
    _settings,
    AddOption,
    AlphaOrderOption,
    app,
    ColumnsOption,
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
    ResampleOption,
    VehicleOption,
)
from ._fit import _fit_model


@app.command()
def compare(
    log: Annotated[pathlib.Path, typer.Argument(help="Flight log CSV")],
    vehicle: VehicleOption = "pegasus",
    model: ModelOption = None,
    columns: ColumnsOption = None,
    fix: FixOption = None,
    knots: KnotsOption = 6,
    alpha_order: AlphaOrderOption = 3,
    rate: RateOption = 50.0,
    node_interval: NodeOption = 1.0,
    out: Annotated[
        pathlib.Path | None, typer.Option(help="Folder for the report")
    ] = None,
    as_json: JsonOption = False,
    resample: ResampleOption = False,
    method: MethodOption = "oem",
    process_noise: ProcessNoiseOption = None,
    max_iter: MaxIterOption = 400,
):
    """Fit the model by output error (or, --vehicle/--model with --method fem, by
    filter error: process noise such as turbulence) and show where it fails:
    per-channel metrics (of the residuals, or of the filter's innovations),
    whiteness, misfit by flight regime, fitted derivatives with standard errors."""
    if model is not None or vehicle != "pegasus":
        _fit_model(
            model or vehicle,
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
        )
        return
    if method != "oem" or process_noise:
        _fail(
            "--method fem goes with --vehicle NAME or --model FILE: the Pegasus "
            "workflow's multiple-shooting spline baseline has no filter-error fit"
        )
    from .._diagnose import run_compare
    from .._diagnose._convergence import why_not_converged

    settings = _settings(knots, alpha_order, rate, node_interval, max_iter)
    _check_out(out, "folder")
    flight = _read(log, resample)
    try:
        result, base = run_compare(flight, settings, out)
    except ValueError as e:
        _fail(str(e))
    except OSError as e:
        _fail(_os_error(e))
    failed = why_not_converged(base, settings.max_iter)
    _global_fit_failed(result, "the output-error fit of the model")
    if failed:
        result["message"] = failed
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
    typer.echo(f"output-error cost det(R) = {result['cost']:.4g}")
    typer.echo(
        f"{'channel':>8s} {'rms':>10s} {'TIC':>7s} {'R^2':>8s} {'rms/noise':>9s} {'white p':>8s}"
    )
    for name, m in result["channels"].items():
        typer.echo(
            f"{name:>8s} {m['rms']:10.3g} {m['tic']:7.3f} {m['r2']:8.4f} "
            f"{m['misfit_ratio']:9.2f} {m['ljung_box_p']:8.2g}"
        )
    for w in result["localise"]["worst"][:3]:
        typer.echo(
            f"worst: {w['channel']} {w['misfit_ratio']:.1f} x noise for {w['variable']} "
            f"in [{w['low']:.3g}, {w['high']:.3g}]"
        )


def _diagnose_model(which, log, columns, fix, add, as_json, process_noise=()):
    from .._vehicle import vehicle_spec
    from ._fem import diagnosis_states
    from ._runners import run_model_diagnose

    try:
        spec = vehicle_spec(str(which), add=add, candidates=True)
        report = run_model_diagnose(
            spec,
            [log],
            columns=columns,
            holds=fix or (),
            process_noise=diagnosis_states(process_noise, spec),
        )
    except LogError as e:
        _fail(str(e))
    if as_json:
        _json_out(report)
    else:
        from .._diagnose._rule import ranking_lines

        deterministic = []
        for r in report["ranking"]:
            if r["effect"] != "process_noise":
                deterministic.append(r)
                continue
            mark = "*" if r["significant"] else " "
            typer.echo(
                f"{mark} {'process_noise':24s} statistic {r['statistic']:8.1f}  "
                f"p = {r['p_value']:.2g}  cost fall "
                f"{100 * r['cost_reduction']:5.1f}%  (likelihood ratio, "
                f"{r['dof']} dof) F = "
                + ", ".join(f"{k} {v:.3g}" for k, v in r["intensities"].items())
            )
        typer.echo("\n".join(ranking_lines(deterministic, top=len(deterministic))))
        if "rule" in report:
            typer.echo(f"decision rule: {report['rule']['text']}")
        typer.echo(report["message"])
    # an output-error fit stopped by turbulence is no failure when the filter-error
    # fit explains the record
    explained = report.get("filter_error", {}).get("converged", False)
    if not report["fit"]["converged"] and not explained:
        typer.echo(f"error: {log}: {report['message']}", err=True)
        raise typer.Exit(code=FIT_FAILED)


@app.command()
def diagnose(
    log: Annotated[pathlib.Path, typer.Argument(help="Flight log CSV")],
    vehicle: VehicleOption = "pegasus",
    model: ModelOption = None,
    columns: ColumnsOption = None,
    fix: FixOption = None,
    add: AddOption = None,
    knots: KnotsOption = 6,
    alpha_order: AlphaOrderOption = 3,
    rate: RateOption = 50.0,
    node_interval: NodeOption = 1.0,
    out: Annotated[
        pathlib.Path | None, typer.Option(help="Folder for the report")
    ] = None,
    as_json: JsonOption = False,
    resample: ResampleOption = False,
    process_noise: Annotated[
        list[str] | None,
        typer.Option(
            help="--vehicle/--model: score process noise (turbulence) on this state "
            "too (repeatable; default the vehicle's or model file's process_noise, "
            "hfb320: V, alpha, theta, q; `none` skips it). Not for the Pegasus "
            "workflow (its 72-parameter spline baseline is fitted by multiple "
            "shooting, which the filter-error method does not take)"
        ),
    ] = None,
    max_iter: MaxIterOption = 400,
):
    """Rank the library's effects by how much of the misfit each would explain
    (score test with exact Jacobians); say when none is significant. With
    --vehicle/--model and process noise declared, process noise (turbulence) is a
    candidate too: the filter-error fit's likelihood ratio, and every effect tested
    again at that fit (a term missing even under process noise ranks first)."""
    if model is not None or vehicle != "pegasus":
        _diagnose_model(
            model or vehicle,
            log,
            columns,
            fix,
            tuple(add or ()),
            as_json,
            tuple(process_noise or ()),
        )
        return
    if process_noise:
        _fail(
            "--process-noise goes with --vehicle NAME or --model FILE: the Pegasus "
            "workflow's multiple-shooting spline baseline has no filter-error fit"
        )
    from .._diagnose import run_diagnose
    from .._diagnose._convergence import why_not_converged
    from .._diagnose._rule import ranking_lines

    add = tuple(add or ())
    settings = _settings(knots, alpha_order, rate, node_interval, max_iter)
    _check_addable(add, settings)
    _check_out(out, "folder")
    flight = _read(log, resample)
    try:
        result, base = run_diagnose(flight, settings, out, add)
    except ValueError as e:
        _fail(str(e))
    except OSError as e:
        _fail(_os_error(e))
    failed = why_not_converged(base, settings.max_iter)
    if failed:
        # the statistics at an unconverged fit are the fit's leftovers: shown, not
        # decided on
        for r in result["ranking"]:
            r["significant"] = False
        result.update(message=failed, significant=[], provisional=True)
        if out is not None:
            _banner(out / "diagnose.md", failed)
        if as_json:
            _json_out(result)
        else:
            typer.echo("\n".join(ranking_lines(result["ranking"])))
        typer.echo(f"error: {log}: {failed}", err=True)
        raise typer.Exit(code=FIT_FAILED)
    if as_json:
        _json_out(result)
        return
    typer.echo(result["message"])
    typer.echo(f"decision rule: {result['rule']['text']}")
    typer.echo("\n".join(ranking_lines(result["ranking"])))
