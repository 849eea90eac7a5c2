"""What every command shares: the Typer apps, failing with one line, shared options."""

import json
import os
import pathlib
from typing import Annotated

import typer

from .._log._format import LogError


app = typer.Typer(
    help="Differentiable flight simulation and aerodynamic identification: Pegasus, "
    "HFB-320 and your own vehicles.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
estimate_app = typer.Typer(
    help="Estimate the six derivatives per window from a flight log.",
    no_args_is_help=True,
)
app.add_typer(estimate_app, name="estimate")


def _fail(message: str) -> None:
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(code=2)


# Exit code of a command whose input was fine but whose fit failed (nothing estimated).
FIT_FAILED = 3


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


# Options shared by the `estimate` commands.
UnitsOption = Annotated[str, typer.Option(help="deg or rad")]
OutOption = Annotated[pathlib.Path | None, typer.Option(help="Folder for CSV and PNG")]
JsonOption = Annotated[bool, typer.Option("--json", help="Print one JSON object")]
ResampleOption = Annotated[bool, typer.Option(help="Resample a non-uniform log")]
VehicleOption = Annotated[
    str,
    typer.Option(help="Built-in vehicle (see `diffpegasus vehicles`) or a FILE.py"),
]
EstimateVehicleOption = Annotated[
    str,
    typer.Option(
        "--vehicle",
        help="Vehicle whose reference area and length scale the coefficients "
        "(built-in name or a FILE.py defining `vehicle`); default: the log's sidecar",
    ),
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


# Options shared by the discrepancy commands.
KnotsOption = Annotated[
    int, typer.Option(help="Mach spline functions per coefficient term")
]
AlphaOrderOption = Annotated[
    int, typer.Option(help="Highest power of alpha in the baseline coefficients")
]
RateOption = Annotated[float, typer.Option(help="Model sample rate, Hz")]
NodeOption = Annotated[float, typer.Option(help="Shooting nodes every S s")]
MaxIterOption = Annotated[
    int,
    typer.Option(
        help="Iteration budget of the output-error fit (it stops sooner when det(R) "
        "settles, and says why when it does not)"
    ),
]
AddOption = Annotated[
    list[str] | None,
    typer.Option("--add", help="Effect to estimate (repeatable), e.g. pitch_damping"),
]
MethodOption = Annotated[
    str,
    typer.Option(
        help="oem (output error) or fem (filter error: process noise such as "
        "turbulence, estimated with the parameters; --vehicle/--model only)"
    ),
]
ProcessNoiseOption = Annotated[
    list[str] | None,
    typer.Option(
        help="--method fem: a state with process noise, STATE or STATE=F0 (start "
        "intensity, state units/sqrt(s)), repeatable; default the vehicle's or model "
        "file's process_noise (hfb320: V, alpha, theta, q from FVSysID's starts), "
        "else every state"
    ),
]


def _settings(knots, alpha_order, rate, node_interval, max_iter=None):
    from .._diagnose import Settings

    if max_iter is not None and max_iter < 1:
        _fail(f"--max-iter must be at least 1, got {max_iter}")
    if knots < 4:
        _fail(f"--knots must be at least 4, got {knots}")
    if alpha_order < 1:
        _fail(f"--alpha-order must be at least 1, got {alpha_order}")
    budget = {} if max_iter is None else {"max_iter": max_iter}
    return Settings(
        knots=knots,
        alpha_order=alpha_order,
        rate=rate,
        node_interval=node_interval,
        **budget,
    )


def _read(log: pathlib.Path, resample: bool):
    from .._log._format import read_log

    try:
        return read_log(log, resample=resample)
    except LogError as e:
        _fail(str(e))


def _check_addable(names, settings):
    from .._diagnose._workflow import check_addable

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


def vehicle_geometry(name_or_file: str) -> tuple[float, float] | None:
    """Reference area (m^2) and length (m) of a vehicle: `None` for Pegasus (the
    log's own sidecar, else Pegasus's values, as always)."""
    if name_or_file == "pegasus":
        return None
    if name_or_file == "hfb320":
        from .._vehicle._hfb320 import HFB320

        vehicle = HFB320
    else:
        from .._vehicle._registry import vehicle_spec

        try:
            vehicle = vehicle_spec(name_or_file).vehicle
        except LogError as e:
            _fail(str(e))
        if vehicle is None:
            _fail(
                f"--vehicle {name_or_file}: estimate needs the vehicle's reference "
                "area and length, i.e. a file defining `vehicle = dp.FlightVehicle"
                "(...)`; a bare `model` has no geometry"
            )
    return float(vehicle.geometry.s_ref), float(vehicle.geometry.c_ref)


def with_vehicle(flight, name_or_file: str):
    """`flight` with the reference geometry of `--vehicle`, saying so on stderr when
    it differs from the log's sidecar."""
    import dataclasses

    geometry = vehicle_geometry(name_or_file)
    if geometry is None:
        return flight
    s_ref, c_ref = geometry
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
