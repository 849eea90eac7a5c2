"""`simulate`, `check`, `effects`: make and inspect flight logs."""

import dataclasses
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


def seeded(effect, seed: int):
    """`effect` with its realisation drawn from `seed` when it is random (the
    turbulence), so that `simulate --seed` picks the gusts as it picks the sensor
    noise; other effects unchanged."""
    from .._vehicle._effects import Turbulence

    if isinstance(effect, Turbulence):
        return dataclasses.replace(effect, seed=int(seed))
    return effect


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

    from .._simulate._solve import (
        elevator_command,
        flight_to_log,
        PegasusConfig,
        Perturbation,
        simulate,
    )
    from .._vehicle._effects import parse_assignment

    effects = tuple(seeded(parse_assignment(h), seed) for h in hidden)
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


def _simulate_lateral(out, seed, hidden, duration, sample_rate, noise, input_name):
    from .._log._format import FlightLog, write_log
    from .._vehicle._lateral_sixdof import simulate_lateral_log

    planted = {}
    for text in hidden:
        spec, sep, value = text.partition("=")
        try:
            planted[spec.strip()] = float(value)
        except ValueError:
            _fail(f"--hidden {text}: expected sensor_bias:CHANNEL=VALUE")
    first = {"pulse": "aileron", "aileron": "aileron", "rudder": "rudder"}.get(
        input_name
    )
    if first is None:
        _fail(
            f"--input {input_name}: a lateral manoeuvre starts with aileron (an "
            "aileron 3-2-1-1, then a rudder doublet) or rudder (the other way round)"
        )
    try:
        channels, meta = simulate_lateral_log(
            duration=25.0 if duration is None else duration,
            rate=25.0 if sample_rate == 1000.0 else sample_rate,
            seed=seed,
            noise=noise,
            first=first,
            hidden=planted,
        )
        path = write_log(out, FlightLog(channels=channels, metadata=meta))
    except ValueError as e:
        _fail(str(e))
    except OSError as e:
        _fail(_os_error(e))
    typer.echo(f"wrote {path} and {path.with_suffix('.json')}")


def _simulate_vehicle(
    name, out, seed, hidden, duration, sample_rate, noise, input_name
):
    from .._log._format import FlightLog, write_log
    from .._vehicle._effects import parse_assignment

    if name == "hfb320-lateral":
        _simulate_lateral(out, seed, hidden, duration, sample_rate, noise, input_name)
        return
    if name != "hfb320":
        _fail(
            f"simulate knows the vehicles pegasus, hfb320 and hfb320-lateral, not "
            f"{name!r}"
        )
    from .._vehicle._effects import Turbulence
    from .._vehicle._hfb320 import CANDIDATES, simulate_log

    planted = {}
    turbulence = 0.0
    for text in hidden:
        try:
            effect = parse_assignment(text)
        except ValueError as e:
            _fail(str(e))
        spec = text.partition("=")[0].strip()
        if isinstance(effect, Turbulence):
            turbulence = float(effect.sigma)
            continue
        if spec not in CANDIDATES:
            _fail(
                f"{spec} does not compose with hfb320; it takes "
                f"{', '.join(CANDIDATES)} and turbulence"
            )
        planted[spec] = float(effect.value())
    rate = 10.0 if sample_rate == 1000.0 else sample_rate
    channels, meta = simulate_log(
        duration=30.0 if duration is None else duration,
        rate=rate,
        seed=seed,
        noise=noise,
        hidden=planted,
        turbulence=turbulence,
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
        float, typer.Option(help="Log rate, Hz", callback=positive)
    ] = 1000.0,
    noise: Annotated[bool, typer.Option(help="Add sensor noise")] = True,
    plot: Annotated[bool, typer.Option(help="Write the trajectory PNG")] = True,
    vehicle: Annotated[
        str,
        typer.Option(
            help="pegasus, hfb320 or hfb320-lateral (see `diffpegasus vehicles`)"
        ),
    ] = "pegasus",
):
    """Simulate a flight of a built-in vehicle (Pegasus first stage by default)
    and write its flight log."""
    from .._log._format import write_log
    from .._report._plotting import plot_trajectory

    _check_out(out, "file")
    if vehicle != "pegasus":
        _simulate_vehicle(
            vehicle, out, seed, hidden or [], duration, sample_rate, noise, input
        )
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
