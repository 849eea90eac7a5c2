"""Open-loop elevator schedules: a nominal pull-up plus excitation shapes.

Every input is an `eqx.Module` whose `__call__(t)` gives the deflection in radians at
time `t` (s after drop). Step-like shapes switch with a C1 ramp of `rise` seconds
(an actuator cannot jump), so the ODE solver and the Jacobians see finite rates.
Parameters are given in degrees (as flight-test engineers specify them) and
converted once.
"""

import abc

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ._custom_types import Scalar, ScalarLike


def smoothstep(x: ScalarLike) -> Scalar:
    """C1 step from 0 (x <= 0) to 1 (x >= 1)."""
    x = jnp.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


class AbstractInput(eqx.Module):
    """An elevator deflection schedule `t -> de` (rad)."""

    @abc.abstractmethod
    def __call__(self, t: ScalarLike) -> Scalar:
        """Deflection (rad) at time `t` (s)."""


def _edge(t: ScalarLike, t_on: ScalarLike, rise: float) -> Scalar:
    return smoothstep((t - t_on) / rise)


class NoInput(AbstractInput):
    """Zero deflection."""

    def __call__(self, t):
        return jnp.zeros_like(jnp.asarray(t, float))


class Schedule(AbstractInput):
    """Piecewise-linear schedule through `(times, degrees)` knots, held at the ends."""

    times: Float[Array, " knots"]
    degrees: Float[Array, " knots"]

    def __call__(self, t):
        return jnp.deg2rad(jnp.interp(t, self.times, self.degrees))


class Step(AbstractInput):
    """A step of `amplitude` deg at `start` s."""

    amplitude: float = 5.0
    start: float = 10.0
    rise: float = eqx.field(static=True, default=0.02)

    def __call__(self, t):
        return jnp.deg2rad(self.amplitude) * _edge(t, self.start, self.rise)


class Ramp(AbstractInput):
    """A ramp of `rate` deg/s from `start` s (zero before)."""

    rate: float = 0.05
    start: float = 0.0

    def __call__(self, t):
        return jnp.deg2rad(self.rate) * jnp.maximum(t - self.start, 0.0)


class Sine(AbstractInput):
    """`amplitude sin(2 pi f (t - start))` deg from `start` to `stop` s."""

    amplitude: float = 1.0
    frequency: float = 2.0
    start: float = 5.0
    stop: float = 1e9

    def __call__(self, t):
        on = (t >= self.start) & (t <= self.stop)
        phase = 2 * jnp.pi * self.frequency * (t - self.start)
        return jnp.where(on, jnp.deg2rad(self.amplitude) * jnp.sin(phase), 0.0)


class PulseTrain(AbstractInput):
    """Rectangular pulses of `amplitude` deg, `width` s long, every `period` s.

    `bias` (deg) is added throughout; pulses run from `start` to `stop` s.
    """

    amplitude: float = 2.0
    period: float = 0.5
    width: float = 0.2
    bias: float = 0.0
    start: float = 5.0
    stop: float = 1e9
    rise: float = eqx.field(static=True, default=0.02)

    def __call__(self, t):
        phase = jnp.mod(t - self.start, self.period)
        pulse = _edge(phase, 0.0, self.rise) - _edge(phase, self.width, self.rise)
        on = (t >= self.start) & (t <= self.stop)
        return jnp.deg2rad(self.bias + jnp.where(on, self.amplitude * pulse, 0.0))


class Sequence(AbstractInput):
    """A sequence of held levels: `levels[i]` (deg) for `durations[i]` s from `start`.

    The doublet and the 3-2-1-1 are sequences; `repeat` restarts it every `repeat` s.
    """

    levels: Float[Array, " n"]
    durations: Float[Array, " n"]
    start: float = 5.0
    repeat: float = 1e9
    rise: float = eqx.field(static=True, default=0.02)

    def __call__(self, t):
        local = jnp.where(t >= self.start, jnp.mod(t - self.start, self.repeat), -1.0)
        edges = jnp.concatenate([jnp.zeros(1), jnp.cumsum(self.durations)])
        on = _edge(local, edges[:-1], self.rise) - _edge(local, edges[1:], self.rise)
        return jnp.deg2rad(jnp.sum(self.levels * on))


def doublet(amplitude: float = 2.0, half_period: float = 0.25, **kwargs) -> Sequence:
    """A doublet: +amplitude then -amplitude, each `half_period` s."""
    return Sequence(
        levels=jnp.array([amplitude, -amplitude]),
        durations=jnp.full(2, half_period),
        **kwargs,
    )


def three_two_one_one(amplitude: float = 2.0, unit: float = 0.1, **kwargs) -> Sequence:
    """A 3-2-1-1: alternating levels held 3, 2, 1 and 1 `unit` s."""
    return Sequence(
        levels=amplitude * jnp.array([1.0, -1.0, 1.0, -1.0]),
        durations=unit * jnp.array([3.0, 2.0, 1.0, 1.0]),
        **kwargs,
    )


class Multisine(AbstractInput):
    """Sum of harmonics `a_k sin(2 pi f_k (t - start) + phi_k)` (deg) from `start`."""

    amplitudes: Float[Array, " k"]
    frequencies: Float[Array, " k"]
    phases: Float[Array, " k"]
    start: float = 5.0
    stop: float = 1e9

    def __call__(self, t):
        on = (t >= self.start) & (t <= self.stop)
        arg = 2 * jnp.pi * self.frequencies * (t - self.start) + self.phases
        return jnp.where(on, jnp.deg2rad(jnp.sum(self.amplitudes * jnp.sin(arg))), 0.0)


def schroeder_multisine(
    amplitude: float = 2.0, base_frequency: float = 0.5, harmonics: int = 8, **kwargs
) -> Multisine:
    """Equal-amplitude harmonics of `base_frequency` Hz with Schroeder phases.

    The peak is close to `amplitude` deg (the per-harmonic amplitude is scaled by the
    crest factor of the Schroeder phasing, about sqrt(2 / harmonics)).
    """
    k = np.arange(1, harmonics + 1)
    phases = -np.pi * k * (k - 1) / harmonics
    per = amplitude * np.sqrt(2.0 / harmonics) / np.sqrt(2.0)
    return Multisine(
        amplitudes=jnp.full(harmonics, per),
        frequencies=jnp.asarray(base_frequency * k, float),
        phases=jnp.asarray(phases),
        **kwargs,
    )


class Sum(AbstractInput):
    """The sum of several inputs (a nominal schedule plus excitation)."""

    parts: tuple[AbstractInput, ...]

    def __call__(self, t):
        return sum((p(t) for p in self.parts), jnp.zeros(()))


def excitation(name: str, start: float = 5.0) -> AbstractInput:
    """A default excitation by name, from `start` s (default ignition) to the end.

    `pulse` (2 deg, 0.2 s pulses every 0.5 s: the thesis's choice), `sine` (1 deg,
    2 Hz), `ramp` (0.05 deg/s), `step` (2 deg at 10 s), `doublet` (2 deg, 0.25 s
    halves, every 1 s), `3211` (2 deg, 0.1 s unit, every 1 s), `multisine` (Schroeder
    phased, 8 harmonics of 0.5 Hz, about 2 deg peak), `none`.
    """
    factories = {
        "pulse": lambda: PulseTrain(amplitude=2.0, period=0.5, width=0.2, start=start),
        "sine": lambda: Sine(amplitude=1.0, frequency=2.0, start=start),
        "ramp": lambda: Ramp(rate=0.05, start=start),
        "step": lambda: Step(amplitude=2.0, start=max(start, 10.0)),
        "doublet": lambda: doublet(2.0, 0.25, start=start, repeat=1.0),
        "3211": lambda: three_two_one_one(2.0, 0.1, start=start, repeat=1.0),
        "multisine": lambda: schroeder_multisine(2.0, 0.5, 8, start=start),
        "none": NoInput,
    }
    if name not in factories:
        raise ValueError(
            f"unknown input {name!r}; choose one of {', '.join(factories)}"
        )
    return factories[name]()


EXCITATION_NAMES = (
    "pulse",
    "sine",
    "ramp",
    "step",
    "doublet",
    "3211",
    "multisine",
    "none",
)
