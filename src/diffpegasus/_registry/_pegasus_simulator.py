"""A simulated Pegasus flight log: the simulator's configuration from the
command line's words (seed, planted effects, excitation, perturbation)."""

import dataclasses


def seeded(effect, seed: int):
    """`effect` with its realisation drawn from `seed` when it is random (the
    turbulence), so that a seed picks the gusts as it picks the sensor noise;
    other effects unchanged."""
    from .._vehicle._effects import Turbulence

    if isinstance(effect, Turbulence):
        return dataclasses.replace(effect, seed=int(seed))
    return effect


def simulate_pegasus_log(
    *,
    seed: int = 0,
    hidden: tuple[str, ...] = (),
    duration: float | None = None,
    sample_rate: float = 1000.0,
    noise: bool = True,
    input: str = "pulse",
    perturb: bool = False,
):
    """A flight from drop to burnout (or `duration` s) at `sample_rate` Hz with
    the effects `hidden` (`NAME=VALUE`, SI units) planted, the nominal pull-up
    plus the excitation `input`, sensor noise drawn from `seed`, and with
    `perturb` a Monte Carlo perturbation of the vehicle; a [`FlightLog`][]."""
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
        elevator=elevator_command(input),
        effects=effects,
        sample_rate=sample_rate,
        **({} if duration is None else {"t_final": duration}),
    )
    noise_key, perturb_key = jax.random.split(jax.random.key(seed))
    metadata = {
        "seed": seed,
        "input": input,
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
