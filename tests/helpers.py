"""Shared small configurations, so tests reuse compiled functions."""

import functools

import jax
import numpy as np

import diffpegasus as dp


def short_config(**kwargs) -> dp.PegasusConfig:
    """A 20 s flight logged at 100 Hz: long enough for ignition and the pull-up."""
    defaults = dict(
        t_final=20.0, sample_rate=100.0, sensors=dp.SensorModel.noise_free()
    )
    return dp.PegasusConfig(**{**defaults, **kwargs})


@functools.cache
def nominal_flight() -> dict[str, np.ndarray]:
    """The default flight, drop to burnout at 1 kHz, noise-free."""
    flight = dp.simulate(dp.PegasusConfig(), jax.random.key(1), noise=False)
    out = {k: np.asarray(v) for k, v in flight.channels.items()}
    out["t"] = np.asarray(flight.t)
    return out


def numpy_channels(flight: dp.Flight) -> dict[str, np.ndarray]:
    out = {k: np.asarray(v) for k, v in flight.channels.items()}
    out["t"] = np.asarray(flight.t)
    return out
