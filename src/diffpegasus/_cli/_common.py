"""What every command shares: the Typer apps, failing with one line, shared options."""

import json
import math
import os
import pathlib
import sys
from typing import Annotated

import typer

from .._errors import LogError


app = typer.Typer(
    help="Identify aerodynamic derivatives from flight logs and find what a model is "
    "missing: aircraft, launch vehicles and your own models.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
    # docstrings are Markdown: paragraphs reflow to the terminal's width
    rich_markup_mode="markdown",
)


def _version(value: bool) -> None:
    if value:
        from .. import __version__

        typer.echo(f"diffpegasus {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[
        bool,
        typer.Option(
            "--version",
            callback=_version,
            is_eager=True,
            help="Print the version and exit.",
        ),
    ] = False,
) -> None:
    del version


estimate_app = typer.Typer(
    help="Per-window derivatives of a Pegasus log (lse, oem, nn).",
    no_args_is_help=True,
    rich_markup_mode="markdown",
)
app.add_typer(
    estimate_app, name="estimate", rich_help_panel="Pegasus thesis reproduction"
)


def _fail(message: str) -> None:
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(code=2)


# Exit code of a command whose input was fine but whose fit failed (nothing estimated).
FIT_FAILED = 3


# Option validators: typer callbacks that refuse a value in one `error:` line while
# the command line is parsed, before any file is read or anything compiled. Use as
# `typer.Option(..., callback=positive)`.


def _option(param) -> str:
    names = [n for n in getattr(param, "opts", ()) if n.startswith("--")]
    return names[0] if names else f"--{param.name.replace('_', '-')}"


def _skip(ctx) -> bool:
    return ctx is not None and getattr(ctx, "resilient_parsing", False)


def _validator(ok, requirement: str, doc: str):
    """A callback that passes `None` and every value `ok` accepts, and refuses the
    others with "OPTION VALUE: `requirement`"."""

    def check(ctx: typer.Context, param: typer.CallbackParam, value):
        if _skip(ctx) or value is None:
            return value
        if not ok(value):
            _fail(f"{_option(param)} {value}: {requirement}")
        return value

    check.__doc__ = doc
    return check


finite = _validator(
    math.isfinite, "not a finite number", "A finite number (or `None`)."
)
positive = _validator(
    lambda v: math.isfinite(v) and v > 0,
    "must be a positive finite number",
    "A finite number above zero (or `None`).",
)
at_least_one = _validator(
    lambda v: not v < 1, "must be at least 1", "An integer of at least 1 (or `None`)."
)


def parse_assignment_text(option: str, text: str, *, need_value: bool):
    """`NAME` or `NAME=VALUE` of `option`: `(name, float or None)`; one `error:` line
    for an empty name, a missing `=VALUE` where one is needed, or a VALUE that is not
    a finite number."""
    name, sep, value = text.partition("=")
    name = name.strip()
    if not name:
        _fail(f"{option} {text!r}: no name before '='")
    if not sep:
        if need_value:
            _fail(f"{option} {text}: expected NAME=VALUE")
        return name, None
    try:
        number = float(value)
    except ValueError:
        _fail(f"{option} {text}: {value.strip()!r} is not a number")
    if not math.isfinite(number):
        _fail(f"{option} {text}: {value.strip()!r} is not a finite number")
    return name, number


def assignments(ctx: typer.Context, param: typer.CallbackParam, value):
    """Repeatable `NAME=VALUE` (VALUE finite), each NAME once (`--hidden`)."""
    return _assignments(ctx, param, value, need_value=True)


def holds(ctx: typer.Context, param: typer.CallbackParam, value):
    """Repeatable `NAME` or `NAME=VALUE` (VALUE finite), each NAME once (`--fix`,
    `--process-noise`)."""
    return _assignments(ctx, param, value, need_value=False)


def _assignments(ctx, param, value, *, need_value):
    if _skip(ctx) or not value:
        return value
    texts = [value] if isinstance(value, str) else list(value)
    seen: dict[str, str] = {}
    for text in texts:
        name, _ = parse_assignment_text(_option(param), text, need_value=need_value)
        if name in seen:
            _fail(
                f"{_option(param)} is given twice for {name!r} ({seen[name]} and "
                f"{text}); give it once"
            )
        seen[name] = text
    return value


def model_or_vehicle(ctx: typer.Context, param: typer.CallbackParam, value):
    """`--model FILE` and `--vehicle NAME` name the same thing: refuse both."""
    if _skip(ctx) or value is None:
        return value
    other = "vehicle" if param.name == "model" else "model"
    given = ctx.params.get(other)
    on_line = [
        getattr(ctx.get_parameter_source(name), "name", None) == "COMMANDLINE"
        for name in (param.name, other)
    ]
    if all(on_line) and given is not None:
        model, vehicle = (value, given) if param.name == "model" else (given, value)
        _fail(
            f"--model {model} and --vehicle {vehicle} both say what to fit; give one "
            "(a model file defines its own vehicle or model)"
        )
    return value


def _check_out(out: pathlib.Path | None, kind: str) -> None:
    """Refuse an `--out` that cannot be written before any work is done."""
    if out is not None and (problem := out_problem(out, kind)) is not None:
        _fail(problem)


def _os_error(e: OSError) -> str:
    where = e.filename if e.filename is not None else "output"
    return f"{where}: cannot write ({e.strerror or e})"


def _check_units(units: str) -> None:
    if units not in ("deg", "rad"):
        _fail(f"--units must be deg or rad, got {units!r}")


# Panels of `--help`: options grouped by what they say (the same panel names in
# every command).
MODEL = "Model"
TUNING = "Model tuning (vehicles that take them)"
DATA = "Data"
FIT = "Fit"
OUTPUT = "Output"

# Options shared by the `estimate` commands.
UnitsOption = Annotated[
    str,
    typer.Option(
        help="Units of the printed derivatives: deg or rad", rich_help_panel=OUTPUT
    ),
]
OutOption = Annotated[
    pathlib.Path | None,
    typer.Option(help="Folder for the CSV, PNG and index.md", rich_help_panel=OUTPUT),
]


def json_mode(ctx: typer.Context, param: typer.CallbackParam, value: bool):
    """With `--json`, stdout carries the one JSON object and nothing else: whatever
    else is printed while the command runs (a model file's prints, progress) goes to
    stderr until the command ends."""
    if _skip(ctx) or not value:
        return value
    _JSON_STDOUT.append(sys.stdout)
    sys.stdout = sys.stderr

    def restore():
        sys.stdout = _JSON_STDOUT.pop()

    ctx.call_on_close(restore)
    return value


_JSON_STDOUT: list = []
JsonOption = Annotated[
    bool,
    typer.Option(
        "--json",
        help="Print one JSON object on stdout (progress goes to stderr)",
        callback=json_mode,
        rich_help_panel=OUTPUT,
    ),
]
ResampleOption = Annotated[
    bool,
    typer.Option(
        help="Resample a log whose time steps are not uniform", rich_help_panel=DATA
    ),
]
ReportOption = Annotated[
    pathlib.Path | None,
    typer.Option(
        help="Folder for the report (markdown, PNGs, index.md)", rich_help_panel=OUTPUT
    ),
]
VehicleOption = Annotated[
    str,
    typer.Option(
        help="Built-in vehicle (see `diffpegasus vehicles`) or a FILE.py",
        callback=model_or_vehicle,
        rich_help_panel=MODEL,
    ),
]
EstimateVehicleOption = Annotated[
    str,
    typer.Option(
        "--vehicle",
        help="Vehicle whose reference area and length scale the coefficients "
        "(built-in name or a FILE.py defining `vehicle`)",
        rich_help_panel=MODEL,
    ),
]
ModelOption = Annotated[
    pathlib.Path | None,
    typer.Option(
        help="Model file (Python defining `model`, and optionally `columns`, "
        "`read`, `candidates`; see the model-file tutorial)",
        callback=model_or_vehicle,
        rich_help_panel=MODEL,
    ),
]
ColumnsOption = Annotated[
    pathlib.Path | None,
    typer.Option(
        help="Column map (JSON or TOML): channel -> column, unit, scale",
        rich_help_panel=DATA,
    ),
]


def _checked(help: str, callback, panel: str):
    """A `typer.Option` with `help`, validated by `callback`, in the help `panel`."""
    return typer.Option(help=help, callback=callback, rich_help_panel=panel)


FixOption = Annotated[
    list[str] | None,
    _checked("Hold a parameter: NAME=VALUE, or NAME at its start value", holds, FIT),
]


# Tuning options of a vehicle's model (its registry entry's fields; a vehicle
# without the field refuses the option).
KnotsOption = Annotated[
    int | None,
    _checked(
        "Mach spline functions per coefficient term (pegasus: 6)", at_least_one, TUNING
    ),
]
AlphaOrderOption = Annotated[
    int | None,
    _checked(
        "Highest power of alpha in the baseline coefficients (pegasus: 3)",
        at_least_one,
        TUNING,
    ),
]
RateOption = Annotated[
    float | None, _checked("Model sample rate, Hz (pegasus: 50)", positive, TUNING)
]
NodeOption = Annotated[
    float | None, _checked("Shooting nodes every S s (pegasus: 1)", positive, TUNING)
]
MaxIterOption = Annotated[
    int | None,
    _checked(
        "Iteration bound of the fit (default: iterate until the cost settles, "
        "up to 500; a fit that stops short says why)",
        at_least_one,
        FIT,
    ),
]
AddOption = Annotated[
    list[str] | None,
    typer.Option(
        "--add",
        help="Library effect to estimate with the model (repeatable), e.g. "
        "pitch_damping; see `diffpegasus effects`",
        rich_help_panel=MODEL,
    ),
]
MethodOption = Annotated[
    str,
    typer.Option(
        help="oem (output error), fem (filter error: process noise such as "
        "turbulence, estimated with the parameters; --vehicle/--model only), eqe "
        "(equation error, `fit` only) or another registered estimator",
        rich_help_panel=FIT,
    ),
]
ProcessNoiseOption = Annotated[
    list[str] | None,
    typer.Option(
        help="--method fem: a state with process noise, STATE or STATE=F0 (start "
        "intensity, state units/sqrt(s)), repeatable; default the vehicle's or model "
        "file's process_noise (hfb320: V, alpha, theta, q from FVSysID's starts), "
        "else every state",
        callback=holds,
        rich_help_panel=FIT,
    ),
]


def _entry(vehicle: str, model=None, **tuning):
    """The registry entry of `--model FILE` or `--vehicle NAME|FILE`, with the
    tuning options given (one error line for an option the vehicle does not
    take)."""
    from .._registry import vehicle_entry

    try:
        return vehicle_entry(str(model or vehicle), **tuning)
    except LogError as e:
        _fail(str(e))


def _read(log: pathlib.Path, resample: bool):
    from .._log._format import read_log

    try:
        return read_log(log, resample=resample)
    except LogError as e:
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
    stream = _JSON_STDOUT[-1] if _JSON_STDOUT else sys.stdout
    typer.echo(json.dumps(_finite(result), allow_nan=False, default=float), file=stream)


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
            from .._files import write_text

            write_text(report, f"> **{message}**\n\n{report.read_text()}")
    except OSError as e:
        _fail(_os_error(e))


def out_problem(path: pathlib.Path, kind: str) -> str | None:
    """Why `path` cannot be written as a `kind` (`"file"` or `"folder"`), or `None`.

    Walks up to the first existing ancestor: it must be a folder we may write in,
    and the path itself, if it exists, must be of the right kind.
    """
    path = pathlib.Path(path)
    if path.exists():
        if kind == "folder" and not path.is_dir():
            return f"--out {path} is an existing file, not a folder"
        if kind == "file" and path.is_dir():
            return (
                f"--out {path} is a folder; give a file name such as "
                f"{path / 'flight.csv'}"
            )
        target = path if kind == "folder" else path.parent
        if not os.access(target, os.W_OK | os.X_OK):
            return f"--out {path}: no permission to write in {target}"
        if os.statvfs(target).f_flag & os.ST_RDONLY:
            return f"--out {path}: {target} is on a read-only file system"
        return None
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        return f"--out {path}: {parent} is a file, so nothing can be created under it"
    if not os.access(parent, os.W_OK | os.X_OK):
        return f"--out {path}: no permission to create anything in {parent}"
    if os.statvfs(parent).f_flag & os.ST_RDONLY:
        return f"--out {path}: {parent} is on a read-only file system"
    return None


def vehicle_geometry(name_or_file: str) -> tuple[float, float]:
    """Reference area (m^2) and length (m) of a vehicle: they belong to the
    vehicle (its registry entry), not to a log."""
    geometry = _entry(name_or_file).geometry()
    if geometry is None:
        _fail(
            f"--vehicle {name_or_file}: estimate needs the vehicle's reference "
            "area and length, i.e. a file defining `vehicle = dp.FlightVehicle"
            "(...)`; a bare `model` has no geometry"
        )
    return geometry


def with_vehicle(flight, name_or_file: str):
    """`flight` with the reference geometry of `--vehicle`, saying so on stderr when
    it differs from the log's sidecar."""
    import dataclasses

    s_ref, c_ref = vehicle_geometry(name_or_file)
    if "S_ref" in flight.metadata and (
        abs(flight.s_ref - s_ref) > 1e-9 * s_ref
        or abs(flight.c_ref - c_ref) > 1e-9 * c_ref
    ):
        typer.echo(
            f"note: --vehicle {name_or_file}: S_ref {s_ref:g} m^2, c_ref {c_ref:g} m "
            f"replace the log's {flight.s_ref:g} m^2, {flight.c_ref:g} m",
            err=True,
        )
    meta = {**flight.metadata, "S_ref": s_ref, "c_ref": c_ref}
    return dataclasses.replace(flight, metadata=meta)


def _log_arg(log: pathlib.Path, resample: bool):
    """The log as the entry reads it: a path, or a resampled [`FlightLog`][]."""
    if not resample:
        return log
    from .._log._format import read_log

    try:
        return read_log(log, resample=True)
    except LogError as e:
        _fail(str(e))
