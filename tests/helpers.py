"""Shared small configurations, so tests reuse compiled functions."""

import functools

import jax
import jax.numpy as jnp
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


# a linear short-period model (alpha, q; elevator de; outputs alpha, q, az) in the
# form `Model` takes, shared by the filter-error and input-timing tests
SHORT_PERIOD_SPEED = 50.0  # m/s, so that az = V alpha_dot-ish is of order 1


def short_period_rates(t, x, u, p):
    del t
    a, q = x[0], x[1]
    return jnp.stack(
        [p["Za"] * a + q + p["Zd"] * u[0], p["Ma"] * a + p["Mq"] * q + p["Md"] * u[0]]
    )


def short_period_outputs(t, x, u, p):
    del t
    a = x[0]
    return jnp.stack([a, x[1], SHORT_PERIOD_SPEED * (p["Za"] * a + p["Zd"] * u[0])])


def short_period_model(parameters: dict) -> dp.Model:
    """The short-period model above (states alpha, q; input de; outputs alpha, q,
    az) with `parameters` (`Za, Zd, Ma, Mq, Md`) as its values."""
    return dp.Model(
        ("alpha", "q"),
        ("de",),
        ("alpha", "q", "az"),
        parameters,
        short_period_rates,
        short_period_outputs,
    )


def rocket_parameters(flight, **over) -> dict:
    """A rocket model's parameters (`flight.parameter_names`) with every effect
    absent: the drag knots at 0.5, every scale 1 (drag, power-on, thrust, burn,
    accelerometer, normal force, pitch damping), 288.15 K at the pad with the
    standard lapse, the rest 0; `over` replaces any of them."""
    p = dict.fromkeys(flight.parameter_names, 0.0)
    p.update(dict.fromkeys(flight.knots.names, 0.5))
    p.update(
        cd_scale=1.0,
        power_on_ratio=1.0,
        thrust_scale=1.0,
        burn_scale=1.0,
        temperature=288.15,
        lapse_rate=-6.5,
        accel_scale=1.0,
        cn_alpha_scale=1.0,
        pitch_damping_scale=1.0,
    )
    p.update(over)
    return p
