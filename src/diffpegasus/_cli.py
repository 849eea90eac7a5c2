"""The `diffpegasus` command line."""

import dataclasses
import json
import pathlib
import sys
from typing import Annotated

import typer

from ._log import LogError


app = typer.Typer(
    help="Differentiable Pegasus flight simulation and aerodynamic identification.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


def _fail(message: str) -> None:
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(code=2)


# Exit code of a command whose input was fine but whose fit failed (nothing estimated).
FIT_FAILED = 3


def _check_out(out: pathlib.Path | None, kind: str) -> None:
    """Refuse an `--out` that cannot be written before any work is done."""
    from ._checks import out_problem

    if out is not None and (problem := out_problem(out, kind)) is not None:
        _fail(problem)


def _os_error(e: OSError) -> str:
    where = e.filename if e.filename is not None else "output"
    return f"{where}: cannot write ({e.strerror or e})"


def _check_units(units: str) -> None:
    if units not in ("deg", "rad"):
        _fail(f"--units must be deg or rad, got {units!r}")


# Options shared by the `estimate` commands.
UnitsOption = Annotated[str, typer.Option(help="deg or rad")]
OutOption = Annotated[pathlib.Path | None, typer.Option(help="Folder for CSV and PNG")]
JsonOption = Annotated[bool, typer.Option("--json", help="Print one JSON object")]
ResampleOption = Annotated[bool, typer.Option(help="Resample a non-uniform log")]
VehicleOption = Annotated[
    str,
    typer.Option(help="Built-in vehicle (see `diffpegasus vehicles`) or a FILE.py"),
]
ModelOption = Annotated[
    pathlib.Path | None,
    typer.Option(help="Model-definition file (Python; see the README)"),
]
ColumnsOption = Annotated[
    pathlib.Path | None,
    typer.Option(help="Column map (JSON or TOML): channel -> column, unit, scale"),
]
FixOption = Annotated[
    list[str] | None,
    typer.Option(help="Hold a parameter: NAME=VALUE, or NAME at its start value"),
]


def _simulate_to_log(
    seed: int,
    input_name: str,
    hidden: list[str],
    perturb: bool,
    duration: float | None,
    sample_rate: float,
    noise: bool,
):
    import jax
    import jax.numpy as jnp

    from ._effects import parse_assignment
    from ._simulate import (
        elevator_command,
        flight_to_log,
        PegasusConfig,
        Perturbation,
        simulate,
    )

    effects = tuple(parse_assignment(h) for h in hidden)
    config = PegasusConfig(
        elevator=elevator_command(input_name),
        effects=effects,
        sample_rate=sample_rate,
        **({} if duration is None else {"t_final": duration}),
    )
    noise_key, perturb_key = jax.random.split(jax.random.key(seed))
    metadata = {
        "seed": seed,
        "input": input_name,
        "noise_sigmas": dict(config.sensors.sigma) if noise else {},
        "hidden_effects": {
            h.split("=")[0].strip(): float(h.split("=")[1]) for h in hidden
        },
        "simulator": "diffpegasus",
    }
    if perturb:
        p = Perturbation.sample(perturb_key)
        config = p.apply(config)
        metadata["perturbation"] = {
            k: float(jnp.asarray(getattr(p, k)))
            for k in ("lift", "drag", "moment", "mass", "thrust", "cg_shift")
        }
    flight = simulate(config, noise_key, noise=noise)
    return flight_to_log(flight, metadata, vehicle=config.vehicle)


def _simulate_vehicle(name, out, seed, hidden, duration, sample_rate, noise):
    from ._effects import parse_assignment
    from ._log import FlightLog, write_log

    if name != "hfb320":
        _fail(f"simulate knows the vehicles pegasus and hfb320, not {name!r}")
    from ._vehicles._hfb320 import CANDIDATES, simulate_log

    planted = {}
    for text in hidden:
        try:
            effect = parse_assignment(text)
        except ValueError as e:
            _fail(str(e))
        spec = text.partition("=")[0].strip()
        if spec not in CANDIDATES:
            _fail(f"{spec} does not compose with hfb320; it takes {', '.join(CANDIDATES)}")
        planted[spec] = float(effect.value())
    rate = 10.0 if sample_rate == 1000.0 else sample_rate
    channels, meta = simulate_log(
        duration=30.0 if duration is None else duration,
        rate=rate,
        seed=seed,
        noise=noise,
        hidden=planted,
    )
    try:
        path = write_log(out, FlightLog(channels=channels, metadata=meta))
    except OSError as e:
        _fail(_os_error(e))
    typer.echo(f"wrote {path} and {path.with_suffix('.json')}")


@app.command()
def simulate(
    out: Annotated[
        pathlib.Path, typer.Option(help="Log CSV to write (plus .json sidecar, .png)")
    ] = pathlib.Path("flight.csv"),
    seed: Annotated[int, typer.Option(help="Seed for noise and perturbations")] = 0,
    input: Annotated[
        str,
        typer.Option(
            "--input",
            help="Excitation on top of the nominal pull-up: pulse, sine, ramp, step, "
            "doublet, 3211, multisine, none",
        ),
    ] = "pulse",
    hidden: Annotated[
        list[str] | None,
        typer.Option(
            help="Plant an effect, NAME=VALUE in SI units (repeatable), e.g. "
            "pitch_damping=-800 or sensor_bias:az=0.3; see `diffpegasus effects`"
        ),
    ] = None,
    perturb: Annotated[
        bool, typer.Option(help="Apply a random Monte Carlo perturbation (Table 6.1)")
    ] = False,
    duration: Annotated[
        float | None, typer.Option(help="Flight length, s (default: to burnout)")
    ] = None,
    sample_rate: Annotated[float, typer.Option(help="Log rate, Hz")] = 1000.0,
    noise: Annotated[bool, typer.Option(help="Add sensor noise")] = True,
    plot: Annotated[bool, typer.Option(help="Write the trajectory PNG")] = True,
    vehicle: Annotated[
        str, typer.Option(help="pegasus or hfb320 (see `diffpegasus vehicles`)")
    ] = "pegasus",
):
    """Simulate a flight of a built-in vehicle (Pegasus first stage by default)
    and write its flight log."""
    from ._log import write_log
    from ._plotting import plot_trajectory

    _check_out(out, "file")
    if vehicle != "pegasus":
        _simulate_vehicle(vehicle, out, seed, hidden or [], duration, sample_rate, noise)
        return
    try:
        log = _simulate_to_log(
            seed, input, hidden or [], perturb, duration, sample_rate, noise
        )
    except ValueError as e:
        _fail(str(e))
    try:
        path = write_log(out, log)
        typer.echo(f"wrote {path} and {path.with_suffix('.json')}")
        if plot:
            plot_trajectory(log, path.with_suffix(".png"))
            typer.echo(f"wrote {path.with_suffix('.png')}")
    except OSError as e:
        _fail(_os_error(e))
    typer.echo(_summary(log))


def _summary(log) -> str:
    import numpy as np

    i = int(np.argmax(log["qbar"]))
    return (
        f"{len(log)} samples at {log.sample_rate:g} Hz over {log.t[-1] - log.t[0]:.1f} s;"
        f" final: altitude {log['h'][-1] / 1e3:.1f} km, Mach {log['mach'][-1]:.2f};"
        f" peak dynamic pressure {log['qbar'][i] / 1e3:.1f} kPa at Mach "
        f"{log['mach'][i]:.2f}; alpha {np.rad2deg(log['alpha'].min()):.1f} to "
        f"{np.rad2deg(log['alpha'].max()):.1f} deg"
    )


@app.command()
def check(
    log: Annotated[pathlib.Path, typer.Argument(help="Flight log CSV")],
    resample: Annotated[
        bool, typer.Option(help="Resample a non-uniformly sampled log")
    ] = False,
):
    """Validate a flight log and summarise it."""
    from ._log import read_log

    try:
        flight = read_log(log, resample=resample)
    except LogError as e:
        _fail(str(e))
    typer.echo(f"{log}: ok; {_summary(flight)}")


@app.command()
def effects(
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON")] = False,
):
    """List the library of physical effects (canonical names and parameters)."""
    from ._effects import EFFECTS

    rows = [
        {
            "effect": name if name != "sensor_bias" else "sensor_bias:<channel>",
            "parameter": cls.parameter,
            "description": cls.description,
        }
        for name, cls in EFFECTS.items()
    ]
    if as_json:
        typer.echo(json.dumps(rows))
        return
    for r in rows:
        typer.echo(f"{r['effect']:24s} {r['parameter']:7s} {r['description']}")


# Options shared by the discrepancy commands.
KnotsOption = Annotated[
    int, typer.Option(help="Mach spline functions per coefficient term")
]
AlphaOrderOption = Annotated[
    int, typer.Option(help="Highest power of alpha in the baseline coefficients")
]
RateOption = Annotated[float, typer.Option(help="Model sample rate, Hz")]
NodeOption = Annotated[float, typer.Option(help="Shooting nodes every S s")]
AddOption = Annotated[
    list[str] | None,
    typer.Option("--add", help="Effect to estimate (repeatable), e.g. pitch_damping"),
]


def _settings(knots, alpha_order, rate, node_interval):
    from ._discrepancy import Settings

    if knots < 4:
        _fail(f"--knots must be at least 4, got {knots}")
    if alpha_order < 1:
        _fail(f"--alpha-order must be at least 1, got {alpha_order}")
    return Settings(
        knots=knots, alpha_order=alpha_order, rate=rate, node_interval=node_interval
    )


def _read(log: pathlib.Path, resample: bool):
    from ._log import read_log

    try:
        return read_log(log, resample=resample)
    except LogError as e:
        _fail(str(e))


def _check_addable(names, settings):
    from ._discrepancy._workflow import check_addable

    try:
        check_addable(names, settings)
    except ValueError as e:
        _fail(str(e))


def _finite(x):
    """JSON has no NaN or infinity: such values (e.g. a noise ratio on a noise-free
    log) become null."""
    import math

    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_finite(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def _json_out(result):
    typer.echo(json.dumps(_finite(result), allow_nan=False, default=float))


def _global_fit_failed(result: dict, what: str) -> str | None:
    """The words for a global output-error fit that did not converge, or `None`;
    sets `result["message"]`."""
    its = result.get("iterations")
    after = f" after {its} iterations" if its is not None else ""
    if result.get("converged", True):
        result["message"] = f"{what} converged{after}"
        return None
    result["message"] = (
        f"{what} did not converge{after}, so it estimated nothing: no derivatives "
        "are reported (the log may not excite the vehicle, or the model cannot "
        "follow it; check the log with `diffpegasus check` and the residual plots)"
    )
    return result["message"]


def _banner(report: pathlib.Path, message: str) -> None:
    """Head a written report with the failure, so no one reads its numbers as
    estimates."""
    try:
        if report.exists():
            report.write_text(f"> **{message}**\n\n{report.read_text()}")
    except OSError as e:
        _fail(_os_error(e))


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
):
    """Fit the model by output error and show where it fails: per-channel metrics,
    whiteness, misfit by flight regime, fitted derivatives with standard errors."""
    if model is not None or vehicle != "pegasus":
        _fit_model(
            model or vehicle, [log], columns, fix, None, None, None, out, as_json,
            show_channels=True,
        )
        return
    from ._discrepancy import run_compare

    settings = _settings(knots, alpha_order, rate, node_interval)
    _check_out(out, "folder")
    flight = _read(log, resample)
    try:
        result, _ = run_compare(flight, settings, out)
    except ValueError as e:
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


def _diagnose_model(which, log, columns, fix, add, as_json):
    from ._identify._run import run_model_diagnose
    from ._vehicles import vehicle_spec

    try:
        spec = vehicle_spec(str(which), add=add, candidates=True)
        report = run_model_diagnose(spec, [log], columns=columns, holds=fix or ())
    except LogError as e:
        _fail(str(e))
    if as_json:
        _json_out(report)
    else:
        for r in report["ranking"]:
            mark = "*" if r["significant"] else " "
            typer.echo(
                f"{mark} {r['effect']:24s} {100 * r['cost_reduction']:6.1f}%  "
                f"p = {r['p_value']:.2g}  estimate {r['estimate']:.4g} "
                f"+/- {r['stderr']:.2g}"
            )
        typer.echo(report["message"])
    if not report["fit"]["converged"]:
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
):
    """Rank the library's effects by how much of the misfit each would explain
    (score test with exact Jacobians); say when none is significant."""
    if model is not None or vehicle != "pegasus":
        _diagnose_model(model or vehicle, log, columns, fix, tuple(add or ()), as_json)
        return
    from ._discrepancy import run_diagnose

    add = tuple(add or ())
    settings = _settings(knots, alpha_order, rate, node_interval)
    _check_addable(add, settings)
    _check_out(out, "folder")
    flight = _read(log, resample)
    try:
        result, base = run_diagnose(flight, settings, out, add)
    except ValueError as e:
        _fail(str(e))
    except OSError as e:
        _fail(_os_error(e))
    if not bool(base.result.converged):
        failed = (
            f"the output-error fit of the model did not converge after "
            f"{int(base.result.iterations)} iterations, so the ranking of effects "
            "measures nothing: none is reported"
        )
        result.update(message=failed, ranking=[], significant=[])
        if out is not None:
            _banner(out / "diagnose.md", failed)
        if as_json:
            _json_out(result)
        typer.echo(f"error: {log}: {failed}", err=True)
        raise typer.Exit(code=FIT_FAILED)
    if as_json:
        _json_out(result)
        return
    typer.echo(result["message"])
    typer.echo(
        f"{'effect':>24s} {'cost fall':>9s} {'p-value':>9s} {'estimate':>12s} {'std err':>9s}"
    )
    for r in result["ranking"][:8]:
        mark = " *" if r["significant"] else ""
        typer.echo(
            f"{r['effect']:>24s} {100 * r['cost_reduction']:8.1f}% {r['p_value']:9.2g} "
            f"{r['estimate']:12.4g} {r['stderr']:9.2g}{mark}"
        )


def _fit_model(
    which,
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
):
    from ._identify import MultipleShooting
    from ._identify._run import format_channels, format_table, run_model_fit
    from ._vehicles import vehicle_spec

    if initial_state not in (None, "fixed", "estimated"):
        _fail(f"--initial-state must be fixed or estimated, got {initial_state!r}")
    if shooting_interval is not None and not shooting_interval > 0:
        _fail(f"--shooting-interval must be positive, got {shooting_interval}")
    _check_out(out, "folder")
    try:
        # with --add, compose every candidate (the others held at zero, left out of
        # the report): the same program as `diagnose` of this vehicle compiled
        spec = vehicle_spec(str(which), add=add, candidates=bool(add))
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
        )
    except LogError as e:
        _fail(str(e))
    except OSError as e:
        _fail(_os_error(e))
    if as_json:
        _json_out(report)
    else:
        typer.echo(format_table(report))
        if show_channels and "channels" in report:
            typer.echo(format_channels(report["channels"]))
    if not report["converged"]:
        typer.echo(f"error: {', '.join(map(str, logs))}: {report['message']}", err=True)
        raise typer.Exit(code=FIT_FAILED)


@app.command()
def vehicles(as_json: JsonOption = False):
    """List the built-in vehicles (use with --vehicle)."""
    from ._vehicles import VEHICLES

    if as_json:
        _json_out(VEHICLES)
        return
    for name, text in VEHICLES.items():
        typer.echo(f"{name:10s} {text}")


@app.command()
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
        typer.Option(help="Estimate a per-record bias on this output (repeatable)"),
    ] = None,
    initial_state: Annotated[
        str | None, typer.Option(help="fixed or estimated (per record)")
    ] = None,
    shooting_interval: Annotated[
        float | None,
        typer.Option(help="Multiple shooting with a node every this many s"),
    ] = None,
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
):
    """Fit a vehicle's or model file's parameters to one or several logs (output
    error; estimates, standard errors, correlations, cost), or, for Pegasus logs,
    refit with the named effects added (--add): before/after metrics and the
    effects' fitted values with standard errors."""
    if model is not None or vehicle != "pegasus":
        _fit_model(
            model or vehicle, logs, columns, fix, bias, initial_state,
            shooting_interval, out, as_json, tuple(add or ()),
        )
        return
    if columns is not None or fix or bias or initial_state or shooting_interval:
        _fail(
            "--columns, --fix, --bias, --initial-state and --shooting-interval go "
            "with --model FILE or --vehicle NAME"
        )
    if len(logs) != 1:
        _fail("the Pegasus effect refit takes one log")
    log = logs[0]
    from ._discrepancy import run_fit

    add = tuple(add or ())
    if not add:
        _fail("name at least one effect with --add NAME (see `diffpegasus effects`)")
    settings = _settings(knots, alpha_order, rate, node_interval)
    _check_addable(add, settings)
    _check_out(out, "folder")
    flight = _read(log, resample)
    try:
        result = run_fit(flight, add, settings, out)
    except ValueError as e:
        _fail(str(e))
    except OSError as e:
        _fail(_os_error(e))
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
        f"{'channel':>8s} {'rms before':>11s} {'rms after':>11s} {'TIC before':>11s} "
        f"{'TIC after':>10s} {'rms/noise before':>17s} {'rms/noise after':>16s}"
    )
    for name in b["channels"]:
        mb, ma = b["channels"][name], a["channels"][name]
        typer.echo(
            f"{name:>8s} {mb['rms']:11.4g} {ma['rms']:11.4g} {mb['tic']:11.4f} "
            f"{ma['tic']:10.4f} {mb['misfit_ratio']:17.2f} {ma['misfit_ratio']:16.2f}"
        )
    for name, e in result["effects"].items():
        typer.echo(
            f"{name}: {e['parameter']} = {e['estimate']:.5g} +/- {e['stderr']:.2g}"
        )


@app.command()
def demo(
    out: Annotated[pathlib.Path, typer.Option(help="Folder for the results")] = (
        pathlib.Path("demo")
    ),
    hidden: Annotated[
        str, typer.Option(help="The effect hidden in the simulated flight, NAME=VALUE")
    ] = "actuator_delay=0.02",
    seed: Annotated[int, typer.Option(help="Seed of the simulated flight")] = 1,
    duration: Annotated[
        float | None, typer.Option(help="Flight length, s (default: to burnout)")
    ] = None,
):
    """The discrepancy workflow end to end: simulate a flight with a hidden effect,
    show the model failing, diagnose, add the top effect, refit, report."""
    from ._discrepancy import run_compare, run_diagnose, run_fit, Settings
    from ._log import write_log
    from ._plotting import plot_trajectory

    out.mkdir(parents=True, exist_ok=True)
    typer.echo(
        f"1. simulating a Pegasus flight (drop to burnout) with a hidden effect ({hidden})..."
    )
    try:
        log = _simulate_to_log(seed, "pulse", [hidden], False, duration, 100.0, True)
    except ValueError as e:
        _fail(str(e))
    path = write_log(out / "flight.csv", log)
    log = dataclasses.replace(log, path=path)  # reports name the file
    plot_trajectory(log, out / "trajectory.png")
    settings = Settings()
    typer.echo("2. compare: fitting the model without it (compiles on first use)...")
    metrics, base = run_compare(log, settings, out)
    for name, m in metrics["channels"].items():
        if m["misfit_ratio"] > 1.5:
            typer.echo(
                f"   {name}: residual rms {m['misfit_ratio']:.1f} x noise, not white (p {m['ljung_box_p']:.1g})"
            )
    typer.echo("3. diagnose: which library effect explains the misfit?")
    diag, _ = run_diagnose(log, settings, out, (), base)
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
    result = run_fit(log, (top,), settings, out, base)
    _print_before_after(result)
    typer.echo(
        f"wrote {path}, trajectory.png and the reports compare.md, diagnose.md, "
        f"fit.md (with their PNGs) in {out}"
    )


@app.command()
def montecarlo(
    samples: Annotated[int, typer.Option(help="Number of perturbed flights")] = 100,
    methods: Annotated[
        str, typer.Option(help="Comma-separated subset of lse,nn,oem")
    ] = "lse,nn,oem",
    seed: Annotated[int, typer.Option(help="Seed of the draws")] = 0,
    out: Annotated[
        pathlib.Path, typer.Option(help="Results folder (a rerun resumes it)")
    ] = pathlib.Path("montecarlo"),
    batch: Annotated[
        int, typer.Option(help="Flights per chunk (sharded over the cores)")
    ] = 10,
    duration: Annotated[float, typer.Option(help="Flight length, s")] = 80.3,
    sample_rate: Annotated[float, typer.Option(help="Log rate, Hz")] = 1000.0,
    nn_epochs: Annotated[
        int, typer.Option(help="Maximum training epochs of the network")
    ] = 1000,
    processes: Annotated[
        int,
        typer.Option(
            help="Run the campaign in N processes on this machine (the cores "
            "shared out among them), coordinated by jax.distributed on 127.0.0.1"
        ),
    ] = 1,
    coordinator: Annotated[
        str | None,
        typer.Option(
            help="Several hosts: HOST:PORT of process 0's coordination service (the "
            "same on every host), with --num-processes and --process-id; `auto` to "
            "take all three from SLURM, Open MPI, ... (jax.distributed.initialize)"
        ),
    ] = None,
    num_processes: Annotated[
        int | None, typer.Option(help="Several hosts: how many processes in all")
    ] = None,
    process_id: Annotated[
        int | None, typer.Option(help="Several hosts: this process's index, 0..N-1")
    ] = None,
):
    """Monte Carlo comparison of LSE, NN+LSE and OEM on perturbed flights (thesis
    chapter 6): per-flight MSE, tables beside the thesis, box plots, coverage and
    wall times in --out. Interrupted runs resume without recomputing; damaged chunk
    files are reported and computed again. With --processes, or --coordinator on
    several hosts, the processes share the chunks out and process 0 writes the
    summary."""
    import os

    from ._montecarlo import launch_local, start_distributed

    if processes < 1:
        _fail(f"--processes must be at least 1, got {processes}")
    if processes > 1:
        if coordinator is not None:
            _fail("use either --processes (one machine) or --coordinator (hosts)")
        args = [
            f"--samples={samples}",
            f"--methods={methods}",
            f"--seed={seed}",
            f"--out={out}",
            f"--batch={batch}",
            f"--duration={duration!r}",
            f"--sample-rate={sample_rate!r}",
            f"--nn-epochs={nn_epochs}",
        ]
        try:
            launch_local(["montecarlo", *args], processes)
        except (ValueError, OSError) as e:
            _fail(str(e))
        summary = json.loads((out / "summary.json").read_text())
    else:
        # one CPU device per core (or per core of this process's share), before
        # JAX starts its backend
        if "xla_force_host_platform_device_count" not in os.environ.get(
            "XLA_FLAGS", ""
        ):
            flag = f"--xla_force_host_platform_device_count={os.cpu_count()}"
            os.environ["XLA_FLAGS"] = (
                f"{os.environ.get('XLA_FLAGS', '')} {flag}".strip()
            )
        try:
            start_distributed(coordinator, num_processes, process_id)
        except (ValueError, RuntimeError) as e:
            _fail(str(e))
        import jax

        from ._montecarlo import Campaign, run_campaign

        devices = len(jax.local_devices())
        if batch % devices:
            batch = -(-batch // devices) * devices
            typer.echo(
                f"--batch rounded up to {batch}, a multiple of the {devices} devices",
                err=True,
            )
        try:
            campaign = Campaign(
                samples=samples,
                methods=tuple(m.strip() for m in methods.split(",") if m.strip()),
                seed=seed,
                batch=batch,
                t_final=duration,
                sample_rate=sample_rate,
                decimate=max(1, int(round(sample_rate / 200.0))),
                nn_epochs=nn_epochs,
            )
            summary = run_campaign(campaign, out)
        except (ValueError, OSError) as e:
            _fail(str(e))
        if jax.process_index() != 0:
            return  # process 0 prints the tables
    typer.echo((out / "tables.md").read_text())
    if "oem_coverage_2sigma" in summary:
        cov = summary["oem_coverage_2sigma"]["overall"]
        typer.echo(f"OEM 2-sigma coverage: {100 * cov:.1f}% of windows")
    typer.echo(
        f"wrote mse.csv, mse_means.csv, mse_std.csv, tables.md, figures, times.json "
        f"and summary.json in {out}"
    )


@app.command("design-input")
def design_input(
    criterion: Annotated[
        str, typer.Option(help="D (log det) or A (trace) of the relative CRB")
    ] = "D",
    max_deflection: Annotated[float, typer.Option(help="Peak excitation, deg")] = 2.0,
    max_rate: Annotated[float, typer.Option(help="Peak rate, deg/s")] = 40.0,
    max_alpha: Annotated[
        float, typer.Option(help="Peak alpha excursion from the unexcited flight, deg")
    ] = 2.0,
    start: Annotated[float, typer.Option(help="Segment start, s")] = 20.0,
    length: Annotated[float, typer.Option(help="Segment length, s")] = 5.0,
    steps: Annotated[int, typer.Option(help="Optimiser steps")] = 150,
    out: Annotated[pathlib.Path, typer.Option(help="Folder for the results")] = (
        pathlib.Path("design")
    ),
):
    """Optimise the elevator excitation for the OEM (Cramér-Rao criterion through
    the differentiable model) and compare it with hand-picked inputs under the same
    limits: design.json, design_inputs.png, design_stderr.png."""
    import numpy as np

    from ._aerodynamics import DERIVATIVE_NAMES
    from ._design import Limits, pegasus_design, run_design
    from ._plotting import plot_design

    if criterion not in ("D", "A"):
        _fail(f"--criterion must be D or A, got {criterion!r}")
    if min(max_deflection, max_rate, max_alpha, length) <= 0:
        _fail("limits and --length must be positive")
    out.mkdir(parents=True, exist_ok=True)
    typer.echo("building the design model and optimising (compiles first)...", err=True)
    design = pegasus_design((start, start + length))
    limits = Limits(
        float(np.deg2rad(max_deflection)),
        float(np.deg2rad(max_rate)),
        float(np.deg2rad(max_alpha)),
    )
    result = run_design(design, limits, kind=criterion, steps=steps)
    plot_design(design, result, out)
    report = _design_report(result, criterion, limits, (start, start + length))
    (out / "design.json").write_text(json.dumps(report, indent=2))
    typer.echo(
        f"predicted standard errors, 1/deg (criterion {criterion}, lower is better):"
    )
    typer.echo("  input       " + "".join(f"{n:>10s}" for n in DERIVATIVE_NAMES))
    for name, row in report["inputs"].items():
        typer.echo(
            f"  {name:10s}  "
            + "".join(f"{row['stderr_per_deg'][n]:10.2e}" for n in DERIVATIVE_NAMES)
        )
    typer.echo(f"wrote design.json, design_inputs.png, design_stderr.png in {out}")


def _design_report(result, criterion, limits, segment) -> dict:
    import numpy as np

    from ._aerodynamics import DERIVATIVE_NAMES

    best = result["inputs"]["optimised"]
    return {
        "criterion": criterion,
        "segment_s": list(segment),
        "limits": {
            "max_deflection_deg": float(np.rad2deg(limits.max_deflection)),
            "max_rate_deg_s": float(np.rad2deg(limits.max_rate)),
            "max_alpha_excursion_deg": float(np.rad2deg(limits.max_excursion)),
        },
        "best_hand_picked": result["best_hand_picked"],
        "criterion_start": result["history"]["start"],
        "criterion_end": result["history"]["end"],
        "optimised_multisine": {
            "amplitudes_deg": (
                np.asarray(best.inner.amplitudes) * float(best.scale)
            ).tolist(),
            "frequencies_hz": np.asarray(best.inner.frequencies).tolist(),
            "phases_rad": np.asarray(best.inner.phases).tolist(),
        },
        "inputs": {
            name: {
                "criterion": row["criterion"],
                "stderr_per_deg": dict(
                    zip(
                        DERIVATIVE_NAMES,
                        (np.asarray(row["stderr"]) * np.pi / 180).tolist(),
                        strict=True,
                    )
                ),
                "peak_deflection_deg": float(np.rad2deg(row["peaks"]["deflection"])),
                "peak_rate_deg_s": float(np.rad2deg(row["peaks"]["rate"])),
                "peak_alpha_excursion_deg": float(
                    np.rad2deg(row["peaks"]["excursion"])
                ),
            }
            for name, row in result["rows"].items()
        },
    }


estimate_app = typer.Typer(
    help="Estimate the six derivatives per window from a flight log.",
    no_args_is_help=True,
)
app.add_typer(estimate_app, name="estimate")


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
    from ._plotting import plot_estimates

    d = est.to_dict(units)
    message, level = _estimates_verdict(est, d)
    failed = level == "error"
    if failed:
        for table in (d["estimates"], d.get("stderr") or {}):
            for column in table.values():
                column[:] = [None] * len(column)
    d["message"] = message
    if out is not None:
        try:
            out.mkdir(parents=True, exist_ok=True)
            est.write_csv(out / f"{est.method}_estimates.csv", units)
            plot_estimates(est, out / f"{est.method}_estimates.png", units)
        except OSError as e:
            _fail(_os_error(e))
        typer.echo(f"wrote {out / f'{est.method}_estimates.csv'} and .png", err=True)
    if as_json:
        typer.echo(json.dumps(_finite(d), allow_nan=False))
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
    log: Annotated[pathlib.Path, typer.Argument(help="Flight log CSV")],
    window: Annotated[float, typer.Option(help="Window length, s")] = 0.5,
    intercept: Annotated[
        bool, typer.Option(help="Also estimate CL0, CD0, CM0 per window")
    ] = False,
    tol: Annotated[float, typer.Option(help="Rank tolerance for A and A^T A")] = 1e-2,
    units: UnitsOption = "deg",
    out: OutOption = None,
    as_json: JsonOption = False,
    resample: ResampleOption = False,
):
    """Windowed equation-error least squares (thesis chapter 3)."""
    from ._estimators import estimate_lse
    from ._log import read_log

    _check_units(units)
    _check_out(out, "folder")
    try:
        flight = read_log(log, resample=resample)
        est = estimate_lse(flight, window=window, intercept=intercept, tol=tol)
    except (LogError, ValueError) as e:
        _fail(str(e))
    _emit_estimates(est, out, as_json, units)


@estimate_app.command("oem")
def estimate_oem_command(
    log: Annotated[pathlib.Path, typer.Argument(help="Flight log CSV")],
    shooting: Annotated[str, typer.Option(help="single or multiple")] = "multiple",
    window: Annotated[float, typer.Option(help="Parameter window, s")] = 0.5,
    node_interval: Annotated[
        float, typer.Option(help="Shooting nodes every S s")
    ] = 2.0,
    decimate: Annotated[
        int, typer.Option(help="Fit at 1/n of the log rate (means of n samples)")
    ] = 5,
    start: Annotated[
        str, typer.Option(help="Starting values: lse, database or truth10")
    ] = "lse",
    axes: Annotated[
        str, typer.Option(help="Estimate body or wind derivatives")
    ] = "body",
    parameters: Annotated[
        str,
        typer.Option(
            help="Derivatives linear in time between window boundaries, or "
            "constant per window (the thesis's model); multiple shooting only"
        ),
    ] = "linear",
    min_qbar: Annotated[
        float,
        typer.Option(
            help="Windows below this mean dynamic pressure (Pa) are not fitted"
        ),
    ] = 2000.0,
    units: UnitsOption = "deg",
    out: OutOption = None,
    as_json: JsonOption = False,
    resample: ResampleOption = False,
):
    """Output-error maximum likelihood, single or multiple shooting (thesis ch. 5)."""
    from ._estimators import estimate_oem
    from ._log import read_log

    _check_units(units)
    _check_out(out, "folder")
    if shooting not in ("single", "multiple"):
        _fail(f"--shooting must be single or multiple, got {shooting!r}")
    try:
        flight = read_log(log, resample=resample)
        typer.echo("fitting (compiles on first use)...", err=True)
        est = estimate_oem(
            flight,
            window=window,
            node_interval=node_interval,
            shooting=shooting,
            decimate=decimate,
            start=start,
            axes=axes,
            parameters=parameters,
            min_qbar=min_qbar,
        )
    except (LogError, ValueError) as e:
        _fail(str(e))
    _emit_estimates(est, out, as_json, units)


def _default_training_logs():
    """Three simulated training flights with different inputs and seeds."""
    import jax

    from ._simulate import elevator_command, flight_to_log, PegasusConfig, simulate

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
    log: Annotated[pathlib.Path, typer.Argument(help="Flight log CSV")],
    model: Annotated[
        pathlib.Path | None,
        typer.Option(
            help="Trained network (.eqx); trained on three simulated flights if omitted"
        ),
    ] = None,
    save_model: Annotated[
        pathlib.Path | None, typer.Option(help="Where to save a newly trained network")
    ] = None,
    derivatives: Annotated[str, typer.Option(help="lse or central")] = "lse",
    window: Annotated[float, typer.Option(help="Window length, s")] = 0.5,
    units: UnitsOption = "deg",
    out: OutOption = None,
    as_json: JsonOption = False,
    resample: ResampleOption = False,
):
    """Neural model plus least squares (thesis chapter 4)."""
    import jax

    from ._estimators import estimate_nn, load_network, save_network, train_network
    from ._log import read_log

    _check_units(units)
    _check_out(out, "folder")
    try:
        flight = read_log(log, resample=resample)
        if model is None:
            typer.echo(
                "no --model given: training a network on three simulated flights "
                "(pulse, 3-2-1-1, multisine); this takes a few minutes",
                err=True,
            )
            net, _ = train_network(_default_training_logs(), jax.random.key(0))
            if save_model is not None:
                save_network(save_model, net)
                typer.echo(f"saved the network to {save_model}", err=True)
        else:
            net = load_network(model)
        est = estimate_nn(flight, net, window=window, derivatives=derivatives)
    except (LogError, ValueError, OSError) as e:
        _fail(str(e))
    _emit_estimates(est, out, as_json, units)


def main() -> None:
    """Entry point of the `diffpegasus` script."""
    import os

    from ._cache import enable_cache

    # `--no-cache` anywhere on the line (before a `--`) is the same as
    # DIFFPEGASUS_NO_CACHE=1: no persistent compilation cache for this run
    args = sys.argv[1:]
    end = args.index("--") if "--" in args else len(args)
    if "--no-cache" in args[:end]:
        sys.argv = [sys.argv[0], *(a for a in args[:end] if a != "--no-cache")]
        sys.argv += args[end:]
        os.environ["DIFFPEGASUS_NO_CACHE"] = "1"
    enable_cache()
    try:
        app()
    except LogError as e:
        typer.echo(f"error: {e}", err=True)
        sys.exit(2)
    except OSError as e:
        # a file the command reads or writes that the checks could not foresee
        typer.echo(f"error: {_os_error(e)}", err=True)
        sys.exit(2)
