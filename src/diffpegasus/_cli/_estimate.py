"""`estimate lse|oem|nn`: per-window derivatives from a flight log."""

import pathlib
from typing import Annotated

import typer

from .._errors import LogError
from ._common import (
    _check_out,
    _check_units,
    _fail,
    _json_out,
    _os_error,
    at_least_one,
    DATA,
    estimate_app,
    EstimateVehicleOption,
    finite,
    FIT,
    FIT_FAILED,
    JsonOption,
    MaxIterOption,
    MODEL,
    OutOption,
    OUTPUT,
    positive,
    ResampleOption,
    UnitsOption,
    vehicle_geometry,
    with_vehicle,
)


def _estimates_verdict(est, d: dict) -> tuple[str, str]:
    """What the estimator achieved, in words, and how it went (`"ok"`, `"warning"`
    or `"error"` when nothing was estimated). Nulls every estimate of a window whose
    fit did not converge."""
    import numpy as np

    valid = np.asarray(est.valid, bool).reshape(-1)
    n = valid.size
    flags = d.get("flags", {})
    converged = flags.get("converged")
    if converged is not None:
        bad = [i for i, ok in enumerate(converged) if not ok]
        for table in (d["estimates"], d.get("stderr") or {}):
            for column in table.values():
                for i in bad:
                    column[i] = None
        if len(bad) == n:
            its = flags.get("iterations")
            after = f" after {max(its)} iterations" if its else ""
            return (
                f"the {est.method} fit did not converge{after}, so it estimated "
                "nothing: every derivative is null (the log may not excite the "
                "vehicle, or the model cannot follow it)",
                "error",
            )
        if bad:
            return (
                f"{len(bad)} of {n} windows did not converge; their derivatives are "
                "null",
                "warning",
            )
    if not valid.any():
        return (
            f"no window has an estimate of its own ({n} windows; the {est.method} "
            "regressors are rank-deficient or every window is below the dynamic-"
            "pressure threshold): every derivative is null",
            "error",
        )
    return f"{int(valid.sum())} of {n} windows estimated", "ok"


def _emit_estimates(est, out: pathlib.Path | None, as_json: bool, units: str) -> None:
    d = est.to_dict(units)
    message, level = _estimates_verdict(est, d)
    failed = level == "error"
    if failed:
        for table in (d["estimates"], d.get("stderr") or {}):
            for column in table.values():
                column[:] = [None] * len(column)
    d["message"] = message
    if out is not None:
        from .._report._plotting import plot_estimates  # matplotlib only when plotting

        try:
            out.mkdir(parents=True, exist_ok=True)
            est.write_csv(out / f"{est.method}_estimates.csv", units)
            plot_estimates(est, out / f"{est.method}_estimates.png", units)
            from .._report._markdown import write_index

            write_index(out)
        except OSError as e:
            _fail(_os_error(e))
        typer.echo(
            f"wrote {out / f'{est.method}_estimates.csv'}, .png and index.md", err=True
        )
    if as_json:
        _json_out(d)
    else:
        _print_estimates(est, d, units, failed)
    if level != "ok":
        typer.echo(f"{level}: {message}", err=True)
    if failed:
        raise typer.Exit(code=FIT_FAILED)


def _print_estimates(est, d: dict, units: str, failed: bool) -> None:
    typer.echo(f"{len(d['window_start'])} windows; estimates in {d['units']}:")
    names = list(d["estimates"])
    typer.echo("  window      " + "".join(f"{n:>12s}" for n in names))
    for i, t0 in enumerate(d["window_start"]):
        vals = [d["estimates"][n][i] for n in names]
        typer.echo(
            f"  {t0:7.2f} s   "
            + "".join(f"{'-':>12s}" if v is None else f"{v:12.5g}" for v in vals)
        )
    if est.truth is not None and not failed:
        mse = est.mse(units)
        typer.echo("MSE vs window-mean truth (valid windows), (" + d["units"] + ")^2:")
        typer.echo("  " + "  ".join(f"{k} {v:.3g}" for k, v in mse.items()))


@estimate_app.command("lse")
def estimate_lse_command(
    log: Annotated[
        pathlib.Path,
        typer.Argument(help="Pegasus flight log CSV (as `simulate` writes)"),
    ],
    vehicle: EstimateVehicleOption = "pegasus",
    window: Annotated[
        float,
        typer.Option(help="Window length, s", callback=positive, rich_help_panel=FIT),
    ] = 0.5,
    intercept: Annotated[
        bool,
        typer.Option(
            help="Also estimate CL0, CD0, CM0 per window", rich_help_panel=FIT
        ),
    ] = False,
    tol: Annotated[
        float,
        typer.Option(
            help="Rank tolerance for A and A^T A",
            callback=positive,
            rich_help_panel=FIT,
        ),
    ] = 1e-2,
    units: UnitsOption = "deg",
    out: OutOption = None,
    as_json: JsonOption = False,
    resample: ResampleOption = False,
):
    """Per-window least squares on a Pegasus log (thesis chapter 3).

    Equation error: each window's coefficients regressed on alpha and the
    elevator, the reference geometry from `--vehicle`.
    """
    from .._estimate import estimate_lse
    from .._log._format import read_log

    _check_units(units)
    _check_out(out, "folder")
    try:
        flight = with_vehicle(read_log(log, resample=resample), vehicle)
        est = estimate_lse(flight, window=window, intercept=intercept, tol=tol)
    except (LogError, ValueError) as e:
        _fail(str(e))
    _emit_estimates(est, out, as_json, units)


@estimate_app.command("oem")
def estimate_oem_command(
    log: Annotated[
        pathlib.Path,
        typer.Argument(help="Pegasus flight log CSV (as `simulate` writes)"),
    ],
    vehicle: EstimateVehicleOption = "pegasus",
    shooting: Annotated[
        str, typer.Option(help="single or multiple", rich_help_panel=FIT)
    ] = "multiple",
    window: Annotated[
        float,
        typer.Option(
            help="Parameter window, s", callback=positive, rich_help_panel=FIT
        ),
    ] = 0.5,
    node_interval: Annotated[
        float,
        typer.Option(
            help="Shooting nodes every S s", callback=positive, rich_help_panel=FIT
        ),
    ] = 2.0,
    decimate: Annotated[
        int,
        typer.Option(
            help="Fit at 1/n of the log rate (means of n samples)",
            callback=at_least_one,
            rich_help_panel=DATA,
        ),
    ] = 5,
    start: Annotated[
        str,
        typer.Option(
            help="Starting values: lse, database or truth10", rich_help_panel=FIT
        ),
    ] = "lse",
    axes: Annotated[
        str,
        typer.Option(help="Estimate body or wind derivatives", rich_help_panel=MODEL),
    ] = "body",
    parameters: Annotated[
        str,
        typer.Option(
            help="linear: continuous and linear in time between window "
            "boundaries; window: per window the derivatives and how the alpha "
            "derivatives change inside it (with time and alpha); hybrid: "
            "those terms for the force derivatives in alpha only (CXa, CZa per "
            "window), the others linear; constant per window (the thesis's "
            "model); multiple shooting only",
            rich_help_panel=MODEL,
        ),
    ] = "hybrid",
    min_qbar: Annotated[
        float,
        typer.Option(
            help="Windows below this mean dynamic pressure (Pa) are not fitted",
            callback=finite,
            rich_help_panel=DATA,
        ),
    ] = 2000.0,
    max_iter: MaxIterOption = None,
    units: UnitsOption = "deg",
    out: OutOption = None,
    as_json: JsonOption = False,
    resample: ResampleOption = False,
):
    """Per-window output-error fit of a Pegasus log (thesis chapter 5).

    Maximum likelihood by single or multiple shooting. Output error only:
    per-window derivatives on multiple-shooting segments have no filter-error
    counterpart here (the filter runs through a whole record from a held initial
    state); for logs flown through turbulence use `fit --method fem --vehicle NAME`
    or `--model FILE`.
    """
    from .._estimate import estimate_oem
    from .._estimate._pegasus_oem import PARAMETERS
    from .._log._format import read_log
    from .._vehicle._parts import Geometry

    _check_units(units)
    _check_out(out, "folder")
    if shooting not in ("single", "multiple"):
        _fail(f"--shooting must be single or multiple, got {shooting!r}")
    if parameters not in PARAMETERS:
        _fail(
            f"--parameters must be one of {', '.join(PARAMETERS)}, got {parameters!r}"
        )
    if axes not in ("body", "wind"):
        _fail(f"--axes must be body or wind, got {axes!r}")
    try:
        flight = with_vehicle(read_log(log, resample=resample), vehicle)
        typer.echo("fitting (compiles on first use)...", err=True)
        est = estimate_oem(
            flight,
            geometry=Geometry(*vehicle_geometry(vehicle)),
            window=window,
            node_interval=node_interval,
            shooting=shooting,
            decimate=decimate,
            start=start,
            axes=axes,
            parameters=parameters,
            min_qbar=min_qbar,
            max_iter=max_iter,
        )
    except (LogError, ValueError) as e:
        _fail(str(e))
    _emit_estimates(est, out, as_json, units)


def _default_training_logs():
    """Three simulated training flights with different inputs and seeds."""
    import jax

    from .._simulate._solve import (
        elevator_command,
        flight_to_log,
        PegasusConfig,
        simulate,
    )

    return [
        flight_to_log(
            simulate(
                PegasusConfig(elevator=elevator_command(name)), jax.random.key(seed)
            )
        )
        for name, seed in (("pulse", 11), ("3211", 12), ("multisine", 13))
    ]


@estimate_app.command("nn")
def estimate_nn_command(
    log: Annotated[
        pathlib.Path,
        typer.Argument(help="Pegasus flight log CSV (as `simulate` writes)"),
    ],
    vehicle: EstimateVehicleOption = "pegasus",
    network: Annotated[
        pathlib.Path | None,
        typer.Option(
            help="Trained network (.eqx); trained on three simulated flights if omitted",
            rich_help_panel=MODEL,
        ),
    ] = None,
    save_network: Annotated[
        pathlib.Path | None,
        typer.Option(
            help="Where to save a newly trained network (.eqx)", rich_help_panel=OUTPUT
        ),
    ] = None,
    old_model: Annotated[
        pathlib.Path | None, typer.Option("--model", hidden=True)
    ] = None,
    old_save_model: Annotated[
        pathlib.Path | None, typer.Option("--save-model", hidden=True)
    ] = None,
    derivatives: Annotated[
        str, typer.Option(help="lse or central", rich_help_panel=FIT)
    ] = "lse",
    window: Annotated[
        float,
        typer.Option(help="Window length, s", callback=positive, rich_help_panel=FIT),
    ] = 0.5,
    units: UnitsOption = "deg",
    out: OutOption = None,
    as_json: JsonOption = False,
    resample: ResampleOption = False,
):
    """Neural model plus least squares on a Pegasus log (thesis chapter 4).

    A network learns the coefficients from the flight condition; each window's
    derivatives are then fitted to it. `--model`/`--save-model` are the former
    names of `--network`/`--save-network` (kept for one release).
    """
    import jax

    from .._estimate import (
        estimate_nn,
        load_network,
        save_network as save_network_file,
        train_network,
    )
    from .._log._format import read_log

    if old_model is not None:
        if network is not None:
            _fail("--model is the former name of --network: give one")
        typer.echo("note: --model is now --network", err=True)
        network = old_model
    if old_save_model is not None:
        if save_network is not None:
            _fail("--save-model is the former name of --save-network: give one")
        typer.echo("note: --save-model is now --save-network", err=True)
        save_network = old_save_model
    _check_units(units)
    _check_out(out, "folder")
    try:
        flight = with_vehicle(read_log(log, resample=resample), vehicle)
        if network is None:
            typer.echo(
                "no --network given: training a network on three simulated flights "
                "(pulse, 3-2-1-1, multisine); this takes a few minutes",
                err=True,
            )
            net, _ = train_network(_default_training_logs(), jax.random.key(0))
            if save_network is not None:
                save_network_file(save_network, net)
                typer.echo(f"saved the network to {save_network}", err=True)
        else:
            net = load_network(network)
        est = estimate_nn(flight, net, window=window, derivatives=derivatives)
    except (LogError, ValueError, OSError) as e:
        _fail(str(e))
    _emit_estimates(est, out, as_json, units)
