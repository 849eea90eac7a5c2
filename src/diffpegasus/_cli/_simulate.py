"""`simulate`, `check`, `effects`: make and inspect flight logs."""

import pathlib
from typing import Annotated

import typer

from .._errors import LogError
from ._common import (
    _check_out,
    _fail,
    _json_out,
    _os_error,
    app,
    assignments,
    ColumnsOption,
    JsonOption,
    MODEL,
    OUTPUT,
    positive,
    ResampleOption,
)


LOGS_PANEL = "Logs and simulation"
SIM = "Simulation"


@app.command(rich_help_panel=LOGS_PANEL)
def simulate(
    out: Annotated[
        pathlib.Path,
        typer.Option(
            help="Log CSV to write (plus .json sidecar, .png)", rich_help_panel=OUTPUT
        ),
    ] = pathlib.Path("flight.csv"),
    seed: Annotated[
        int,
        typer.Option(
            help="Seed for noise, perturbations and turbulence", rich_help_panel=SIM
        ),
    ] = 0,
    input: Annotated[
        str,
        typer.Option(
            "--input",
            help="Excitation on top of the nominal pull-up: pulse, sine, ramp, step, "
            "doublet, 3211, multisine, none (hfb320-lateral: aileron or rudder, the "
            "surface with the 3-2-1-1)",
            rich_help_panel=SIM,
        ),
    ] = "pulse",
    hidden: Annotated[
        list[str] | None,
        typer.Option(
            help="Plant an effect, NAME=VALUE in SI units (repeatable), e.g. "
            "pitch_damping=-800 or sensor_bias:az=0.3, or turbulence=SIGMA (Dryden "
            "gusts, m/s, realisation drawn from --seed); see `diffpegasus effects`",
            callback=assignments,
            rich_help_panel=SIM,
        ),
    ] = None,
    perturb: Annotated[
        bool,
        typer.Option(
            help="Apply a random Monte Carlo perturbation (pegasus: the thesis's "
            "Table 6.1)",
            rich_help_panel=SIM,
        ),
    ] = False,
    duration: Annotated[
        float | None,
        typer.Option(
            help="Flight length, s (default: to burnout)",
            callback=positive,
            rich_help_panel=SIM,
        ),
    ] = None,
    sample_rate: Annotated[
        float | None,
        typer.Option(
            help="Log rate, Hz (default the vehicle's: pegasus 1000, hfb320 10)",
            callback=positive,
            rich_help_panel=SIM,
        ),
    ] = None,
    noise: Annotated[
        bool, typer.Option(help="Add sensor noise", rich_help_panel=SIM)
    ] = True,
    plot: Annotated[
        bool, typer.Option(help="Write the trajectory PNG", rich_help_panel=OUTPUT)
    ] = True,
    vehicle: Annotated[
        str,
        typer.Option(
            help="A built-in vehicle (see `diffpegasus vehicles`) or a vehicle file "
            "FILE.py (flown from its x0 with a 3-2-1-1 on its first input)",
            rich_help_panel=MODEL,
        ),
    ] = "pegasus",
):
    """Simulate a vehicle's flight and write its log.

    The Pegasus first stage by default (drop to burnout), any built-in vehicle or
    a vehicle file with `--vehicle`; effects planted with `--hidden` are recorded
    in the log's sidecar.
    """
    from .._log._format import write_log
    from .._registry import vehicle_entry
    from .._report._plotting import plot_trajectory

    _check_out(out, "file")
    try:
        log = vehicle_entry(vehicle).simulate(
            seed=seed,
            hidden=tuple(hidden or ()),
            duration=duration,
            sample_rate=sample_rate,
            noise=noise,
            input=input,
            perturb=perturb,
        )
    except (LogError, ValueError) as e:
        _fail(str(e))
    try:
        path = write_log(out, log)
        typer.echo(f"wrote {path} and {path.with_suffix('.json')}")
        # the trajectory figure is of a launch vehicle's channels
        if plot and all(c in log.channels for c in TRAJECTORY_CHANNELS):
            plot_trajectory(log, path.with_suffix(".png"))
            typer.echo(f"wrote {path.with_suffix('.png')}")
    except OSError as e:
        _fail(_os_error(e))
    summary = _summary(log)
    if summary:
        typer.echo(summary)


TRAJECTORY_CHANNELS = (
    "alpha",
    "de",
    "h",
    "mach",
    "mass",
    "qbar",
    "thrust",
    "xcg",
    "xcp",
)


def _summary(log) -> str:
    import numpy as np

    if not all(c in log.channels for c in ("qbar", "h", "mach", "alpha")):
        return f"{len(log)} samples at {log.sample_rate:g} Hz over {log.t[-1] - log.t[0]:.1f} s"
    i = int(np.argmax(log["qbar"]))
    return (
        f"{len(log)} samples at {log.sample_rate:g} Hz over {log.t[-1] - log.t[0]:.1f} s;"
        f" final: altitude {log['h'][-1] / 1e3:.1f} km, Mach {log['mach'][-1]:.2f};"
        f" peak dynamic pressure {log['qbar'][i] / 1e3:.1f} kPa at Mach "
        f"{log['mach'][i]:.2f}; alpha {np.rad2deg(log['alpha'].min()):.1f} to "
        f"{np.rad2deg(log['alpha'].max()):.1f} deg"
    )


@app.command(rich_help_panel=LOGS_PANEL)
def check(
    log: Annotated[pathlib.Path, typer.Argument(help="Flight log file")],
    columns: ColumnsOption = None,
    resample: ResampleOption = False,
    as_json: JsonOption = False,
):
    """Validate a flight log and summarise it.

    Without `--columns`: a log in the package's own format (CSV with a JSON
    sidecar, as `simulate` writes), every channel of a launch-vehicle log checked.
    With `--columns MAP`: any table (CSV, `.asc`, `.mat`, HDF5) read through the
    column map, as `fit --columns` reads it: each mapped channel converted to SI
    units and checked (finite cells, outliers, ranges, units against the physics
    of the other channels).
    """
    if columns is not None:
        _check_mapped(log, columns, resample, as_json)
        return
    from .._log._format import read_log

    try:
        flight = read_log(log, resample=resample)
    except LogError as e:
        _fail(str(e))
    if as_json:
        _json_out({"file": str(log), "ok": True, "summary": _summary(flight)})
        return
    typer.echo(f"{log}: ok; {_summary(flight)}")


def _check_mapped(log, columns, resample, as_json) -> None:
    import numpy as np

    from .._log._columns import load_columns, read_channels

    if resample:
        _fail("--resample goes with a log in the package's format (no --columns)")
    try:
        channels = read_channels(log, columns)
        cmap = load_columns(columns)
    except LogError as e:
        _fail(str(e))
    t = channels["t"]
    if len(t) < 3:  # as fit refuses it
        _fail(
            f"{log}: only {len(t)} sample(s); a record needs at least 3 (two steps of "
            "the dynamics)"
        )
    steps = np.diff(t)
    if steps.size and not np.all(steps > 0):
        row = int(np.argmax(~(steps > 0))) + 2
        _fail(f"{log}: time row {row}: {t[row - 1]:g} s does not increase")
    rate = 1.0 / float(np.median(steps)) if steps.size else float("nan")
    rows = {
        ch: {
            "column": cmap[ch].column if ch in cmap else ch,
            "unit": cmap[ch].unit if ch in cmap else "",
            "min_si": float(np.min(v)),
            "max_si": float(np.max(v)),
        }
        for ch, v in channels.items()
        if ch != "t"
    }
    summary = (
        f"{len(t)} samples at {rate:.4g} Hz over {t[-1] - t[0]:.4g} s; "
        f"{len(rows)} channels"
    )
    if as_json:
        _json_out({"file": str(log), "ok": True, "summary": summary, "channels": rows})
        return
    typer.echo(f"{log}: ok; {summary}")
    typer.echo(
        f"  {'channel':>10s} {'column':>14s} {'unit':>8s} {'min (SI)':>12s} {'max (SI)':>12s}"
    )
    for ch, r in rows.items():
        typer.echo(
            f"  {ch:>10s} {str(r['column']):>14s} {r['unit'] or 'SI':>8s} "
            f"{r['min_si']:12.4g} {r['max_si']:12.4g}"
        )


@app.command(rich_help_panel="Reference")
def effects(as_json: JsonOption = False):
    """List the library of physical effects (names and parameters)."""
    from .._vehicle._effects import EFFECTS

    rows = [
        {
            "effect": name if name != "sensor_bias" else "sensor_bias:<channel>",
            "parameter": cls.parameter,
            "description": cls.description,
        }
        for name, cls in EFFECTS.items()
    ]
    if as_json:
        _json_out(rows)
        return
    for r in rows:
        typer.echo(f"{r['effect']:24s} {r['parameter']:7s} {r['description']}")
