"""The interface every physical effect implements.

An effect is a small `eqx.Module` whose fields are its named parameters (SI units,
default zero, so an effect at its defaults changes nothing). It plugs into the flight
model through hooks, each with a do-nothing default; an effect overrides only the
hooks it needs:

| hook | returns | used for |
|---|---|---|
| `elevator_delay()` | s | actuator delay |
| `wind(t, theta)` | body-axis wind `(u, w)`, m/s | wind and gusts |
| `force_coefficients(c)` | `(dCL, dCD)` | extra lift and drag |
| `moment_coefficient(c)` | `dCM` | extra pitching moment (about the cp) |
| `moment(c)` | N m about the CG | moments not scaled by dynamic pressure |
| `measure(channels, c)` | channels | sensor errors |

`c` is the [`FlightCondition`][] at that instant. `force_coefficients` must not use
`c.alpha_dot` (it is only known after the forces are).
"""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from ..._custom_types import Scalar, ScalarLike


class FlightCondition(eqx.Module):
    """Everything an effect may depend on at one instant (SI units, radians).

    **Fields:** `t`, `alpha`, `alpha_dot`, `airspeed`, `mach`, `qbar`, `q`, `theta`,
    `h`, `de`, `thrust`, `c_ref`, `s_ref`, `mass`, `xcg`.
    """

    t: Scalar
    alpha: Scalar
    alpha_dot: Scalar
    airspeed: Scalar
    mach: Scalar
    qbar: Scalar
    q: Scalar
    qdot: Scalar
    theta: Scalar
    h: Scalar
    de: Scalar
    thrust: Scalar
    c_ref: float
    s_ref: float
    mass: Scalar
    xcg: Scalar


class AbstractEffect(eqx.Module):
    """A physical effect with named parameters that default to zero.

    Subclasses set the class variables `name` (canonical name), `description` (one
    line of physics) and `parameter` (the field that `--hidden NAME=VALUE` sets), and
    override the hooks they need.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    parameter: ClassVar[str]

    def elevator_delay(self) -> ScalarLike:
        return 0.0

    def wind(self, t: ScalarLike, theta: ScalarLike) -> tuple[Scalar, Scalar]:
        del t, theta
        return jnp.zeros(()), jnp.zeros(())

    def force_coefficients(self, c: FlightCondition) -> tuple[Scalar, Scalar]:
        del c
        return jnp.zeros(()), jnp.zeros(())

    def moment_coefficient(self, c: FlightCondition) -> Scalar:
        del c
        return jnp.zeros(())

    def moment(self, c: FlightCondition) -> Scalar:
        del c
        return jnp.zeros(())

    def measure(self, channels: dict, c: FlightCondition) -> dict:
        del c
        return channels

    def value(self) -> Scalar:
        """The effect's main parameter."""
        return getattr(self, self.parameter)
