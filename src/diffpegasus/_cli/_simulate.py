"""`simulate`, `check`, `effects`: make and inspect flight logs."""

import json
import pathlib
from typing import Annotated

import typer

from .._errors import LogError
from ._common import (
    _check_out,
    _fail,
    _os_error,
    app,
    assignments,
    positive,
)


@app.command()
def simulate(
    out: Annotated[
        pathlib.Path, typer.Option(help="Log CSV to write (plus .json sidecar, .png)")
    ] = pathlib.Path("flight.csv"),
    seed: Annotated[
        int, typer.Option(help="Seed for noise, perturbations and turbulence")
    ] = 0,
    input: Annotated[
        str,
        typer.Option(
            "--input",
            help="Excitation on top of the nominal pull-up: pulse, sine, ramp, step, "
            "doublet, 3211, multisine, none (hfb320-lateral: aileron or rudder, the "
            "surface with the 3-2-1-1)",
        ),
    ] = "pulse",
    hidden: Annotated[
        list[str] | None,
        typer.Option(
            help="Plant an effect, NAME=VALUE in SI units (repeatable), e.g. "
            "pitch_damping=-800 or sensor_bias:az=0.3, or turbulence=SIGMA (Dryden "
            "gusts, m/s, realisation drawn from --seed); see `diffpegasus effects`",
            callback=assignments,
        ),
    ] = None,
    perturb: Annotated[
        bool, typer.Option(help="Apply a random Monte Carlo perturbation (Table 6.1)")
    ] = False,
    duration: Annotated[
        float | None,
        typer.Option(help="Flight length, s (default: to burnout)", callback=positive),
    ] = None,
    sample_rate: Annotated[
        float | None,
        typer.Option(
            help="Log rate, Hz (default the vehicle's: pegasus 1000, hfb320 10)",
            callback=positive,
        ),
    ] = None,
    noise: Annotated[bool, typer.Option(help="Add sensor noise")] = True,
    plot: Annotated[bool, typer.Option(help="Write the trajectory PNG")] = True,
    vehicle: Annotated[
        str,
        typer.Option(
            help="A built-in vehicle (see `diffpegasus vehicles`) or a vehicle file "
            "FILE.py (flown from its x0 with a 3-2-1-1 on its first input)"
        ),
    ] = "pegasus",
):
    """Simulate a flight of a vehicle (Pegasus first stage by default) and write
    its flight log."""
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


@app.command()
def check(
    log: Annotated[pathlib.Path, typer.Argument(help="Flight log CSV")],
    resample: Annotated[
        bool, typer.Option(help="Resample a non-uniformly sampled log")
    ] = False,
):
    """Validate a flight log and summarise it."""
    from .._log._format import read_log

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
        typer.echo(json.dumps(rows))
        return
    for r in rows:
        typer.echo(f"{r['effect']:24s} {r['parameter']:7s} {r['description']}")
