"""One diffrax solve per flight, sampled at the log rate, with noise and truth.

`simulate(config, key)` is a pure function of a [`PegasusConfig`][] (a PyTree), so a
batch of configurations simulates in one call with `simulate_batch` (`jax.vmap`).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, PRNGKeyArray

from .._custom_types import ScalarLike
from .._log._format import FlightLog, PEGASUS_METADATA
from .._vehicle._atmosphere import isa
from .._vehicle._effects import AbstractEffect
from .._vehicle._pegasus._aerodynamics import DERIVATIVE_NAMES
from .._vehicle._pegasus._dynamics import evaluate, FlightModel
from .._vehicle._pegasus._vehicle import Vehicle
from ._inputs import AbstractInput, excitation, Schedule, Sum
from ._sensors import SensorModel


# Nominal open-loop pull-up (time s, elevator deg; negative is trailing edge up).
NOMINAL_SCHEDULE = (
    (0.0, 5.0, 6.0, 20.0, 30.0, 40.0, 60.0, 80.3),
    (-2.0, -2.0, -20.0, -22.0, -20.0, -12.0, -5.0, -3.0),
)


def nominal_elevator() -> Schedule:
    """The nominal pull-up schedule (no excitation)."""
    times, degrees = NOMINAL_SCHEDULE
    return Schedule(times=jnp.asarray(times), degrees=jnp.asarray(degrees))


def elevator_command(input_name: str = "pulse") -> Sum:
    """The nominal pull-up plus the named excitation (see [`excitation`][])."""
    return Sum((nominal_elevator(), excitation(input_name)))


class InitialCondition(eqx.Module):
    """Drop conditions: altitude (m), Mach, flight-path angle and alpha (deg)."""

    altitude: ScalarLike = 12_500.0
    mach: ScalarLike = 0.8
    flight_path_deg: ScalarLike = 0.0
    alpha_deg: ScalarLike = 2.0

    def state(self) -> Float[Array, "6"]:
        """`[u, w, q, theta, x, h]` at drop."""
        v = self.mach * isa(self.altitude).speed_of_sound
        alpha = jnp.deg2rad(self.alpha_deg)
        theta = jnp.deg2rad(self.flight_path_deg) + alpha
        zero = jnp.zeros(())
        h = jnp.asarray(self.altitude, float)
        return jnp.stack([v * jnp.cos(alpha), v * jnp.sin(alpha), zero, theta, zero, h])


class PegasusConfig(eqx.Module):
    """Everything that defines one simulated flight.

    **Fields:**

    - `vehicle`: geometry, aerodynamics, motor, mass model.
    - `elevator`: the elevator command (nominal pull-up plus excitation).
    - `sensors`: noise and biases.
    - `effects`: planted physical effects (none by default).
    - `initial`: drop conditions.
    - `t_final`: end of the flight, s (default burnout, 80.3 s).
    - `sample_rate`: log rate, Hz (default 1000).
    - `dt`: the solver's fixed step, s (default 5 ms; samples between steps come from
      Tsit5's fourth-order dense output).
    """

    vehicle: Vehicle = eqx.field(default_factory=Vehicle)
    elevator: AbstractInput = eqx.field(default_factory=elevator_command)
    sensors: SensorModel = eqx.field(default_factory=SensorModel)
    effects: tuple[AbstractEffect, ...] = ()
    initial: InitialCondition = eqx.field(default_factory=InitialCondition)
    t_final: float = eqx.field(static=True, default=80.3)
    sample_rate: float = eqx.field(static=True, default=1000.0)
    dt: float = eqx.field(static=True, default=5e-3)

    @property
    def model(self) -> FlightModel:
        return FlightModel(self.vehicle, self.elevator, self.effects)

    @property
    def times(self) -> np.ndarray:
        """Sample times, s."""
        n = int(round(self.t_final * self.sample_rate)) + 1
        return np.arange(n) / self.sample_rate


class Flight(eqx.Module):
    """A simulated flight: sample times and every log channel.

    **Fields:** `t` (s, shape `(time,)`), `channels` (name to array of shape
    `(time,)`, SI units, radians: the measured channels with noise, the bookkeeping
    channels, and the `true_*` derivatives per rad), `states` (`(time, 6)`, the
    noise-free `[u, w, q, theta, x, h]`).
    """

    t: Float[Array, " time"]
    channels: dict[str, Float[Array, " time"]]
    states: Float[Array, "time 6"]


def _vector_field(t, y, model):
    return evaluate(t, y, model).rates


@eqx.filter_jit
def simulate(
    config: PegasusConfig, key: PRNGKeyArray | None = None, *, noise: bool = True
) -> Flight:
    """Simulate one flight from drop to `config.t_final`.

    **Arguments:**

    - `config`: the flight's [`PegasusConfig`][].
    - `key`: PRNG key for the sensor noise (default `jax.random.key(0)`).
    - `noise`: `False` gives the noise-free measurements (biases still apply).

    **Returns:** a [`Flight`][] sampled at `config.sample_rate`. One diffrax solve with
    Tsit5 at the fixed step `config.dt`.
    """
    if key is None:
        key = jax.random.key(0)
    times = config.times
    ts = jnp.asarray(times)
    model = config.model
    import diffrax  # here, not at the top: commands that never simulate skip it

    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(_vector_field),
        diffrax.Tsit5(),
        t0=0.0,
        t1=float(times[-1]),
        dt0=config.dt,
        y0=config.initial.state(),
        args=model,
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.ConstantStepSize(),
        max_steps=int(times[-1] / config.dt) + 16,
    )
    states = sol.ys
    ev = jax.vmap(lambda t, y: evaluate(t, y, model))(ts, states)
    channels = dict(ev.channels)
    for name in DERIVATIVE_NAMES:
        channels[f"true_{name}"] = getattr(ev.derivatives, name)
    if noise:
        channels = config.sensors.apply(channels, key)
    else:
        channels = eqx.tree_at(lambda s: s.sigma, config.sensors, {}).apply(
            channels, key
        )
    return Flight(t=ts, channels=channels, states=states)


class Perturbation(eqx.Module):
    """Monte Carlo perturbation factors (thesis Table 6.1).

    `lift`, `drag`, `moment` scale the CL, CD, CM tables; `mass` every mass; `thrust`
    the thrust; `cg_shift` (m) moves the CG station.
    """

    lift: ScalarLike = 1.0
    drag: ScalarLike = 1.0
    moment: ScalarLike = 1.0
    mass: ScalarLike = 1.0
    thrust: ScalarLike = 1.0
    cg_shift: ScalarLike = 0.0

    @classmethod
    def sample(cls, key: PRNGKeyArray) -> "Perturbation":
        """Uniform draws: tables x (1 +/- 10%), mass x (1 +/- 5%), thrust x
        (1 +/- 20%), CG station +/- 0.5 m."""
        u = jax.random.uniform(key, (6,), minval=-1.0, maxval=1.0)
        return cls(
            lift=1 + 0.1 * u[0],
            drag=1 + 0.1 * u[1],
            moment=1 + 0.1 * u[2],
            mass=1 + 0.05 * u[3],
            thrust=1 + 0.2 * u[4],
            cg_shift=0.5 * u[5],
        )

    def apply(self, config: PegasusConfig) -> PegasusConfig:
        """The configuration with this perturbation applied to its vehicle."""
        vehicle = config.vehicle.perturbed(
            self.lift, self.drag, self.moment, self.mass, self.thrust, self.cg_shift
        )
        return eqx.tree_at(lambda c: c.vehicle, config, vehicle)


def sample_perturbations(key: PRNGKeyArray, n: int) -> Perturbation:
    """`n` seeded draws of [`Perturbation.sample`][], stacked on a leading axis."""
    return jax.vmap(Perturbation.sample)(jax.random.split(key, n))


@eqx.filter_jit
def simulate_batch(
    config: PegasusConfig,
    keys: PRNGKeyArray,
    perturbations: Perturbation | None = None,
    *,
    noise: bool = True,
) -> Flight:
    """Simulate a batch of flights in one vmapped call.

    **Arguments:**

    - `config`: the common, unbatched configuration.
    - `keys`: noise keys, shape `(batch,)`.
    - `perturbations`: a [`Perturbation`][] with a leading batch axis on every field
      (from [`sample_perturbations`][]), or `None` for the same vehicle throughout.
    - `noise`: as in [`simulate`][].

    **Returns:** a [`Flight`][] whose arrays have a leading batch axis. Only the
    perturbed leaves are batched (the tables, inputs and mass model are shared), which
    keeps the vmapped vector field as cheap as the unbatched one. For other sweeps,
    `jax.vmap` over [`simulate`][] directly.
    """
    if perturbations is None:
        return jax.vmap(lambda k: simulate(config, k, noise=noise))(keys)
    return jax.vmap(lambda p, k: simulate(p.apply(config), k, noise=noise))(
        perturbations, keys
    )


def flight_to_log(
    flight: Flight, metadata: dict | None = None, vehicle: Vehicle | None = None
) -> FlightLog:
    """A single (unbatched) simulated [`Flight`][] as a [`FlightLog`][], its sidecar
    stamped with the reference area and length of `vehicle` (the one simulated;
    default the standard Pegasus)."""
    channels = {"t": np.asarray(flight.t)}
    channels.update({k: np.asarray(v) for k, v in flight.channels.items()})
    if channels["t"].ndim != 1:
        raise ValueError("flight_to_log takes one flight; index a batch first")
    vehicle = Vehicle() if vehicle is None else vehicle
    meta = {
        **PEGASUS_METADATA,
        "S_ref": vehicle.s_ref,
        "c_ref": vehicle.c_ref,
        "sample_rate_hz": float(1.0 / (channels["t"][1] - channels["t"][0])),
    }
    meta.update(metadata or {})
    return FlightLog(channels=channels, metadata=meta)
