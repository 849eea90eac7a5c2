"""The Pegasus simulator's dynamics: the vehicle's database, motor and mass model
plugged into the one flight model ([`pitch_plane`][] in `_flight.py`).

Flat, non-rotating Earth frame fixed at the drop point (x along the initial track,
z down); body axes x to the nose, z down. The state is `y = [u, w, q, theta, x, h]`
(body velocities m/s, pitch rate rad/s, pitch attitude rad, downrange m, altitude m).
"""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from ..._custom_types import Scalar, ScalarLike
from ..._inputs import AbstractInput
from .._atmosphere import isa
from .._effects import AbstractEffect, FlightCondition
from .._flight import elevator_delay, pitch_plane
from .._gravity import gravity
from ._aerodynamics import AeroDerivatives, coefficients
from ._vehicle import Vehicle


STATE_NAMES = ("u", "w", "q", "theta", "x", "h")


class FlightModel(eqx.Module):
    """Vehicle, elevator command and planted effects: everything the dynamics need."""

    vehicle: Vehicle
    elevator: AbstractInput
    effects: tuple[AbstractEffect, ...] = ()


class Evaluation(eqx.Module):
    """The dynamics evaluated at one instant: state rate and every flight quantity."""

    rates: Float[Array, "6"]
    condition: FlightCondition
    derivatives: AeroDerivatives
    channels: dict[str, Scalar]


def evaluate(t: ScalarLike, y: Float[Array, "6"], model: FlightModel) -> Evaluation:
    """The state rate and the noise-free measured channels at `(t, y)`.

    Channels follow the flight-log names (`ax`, `az`, `q`, `qdot`, `alpha`, `V`,
    `theta`, `h`, `mach`, `qbar`, `thrust`, `mass`, `Iyy`, `Iyy_dot`, `xcg`, `xcp`,
    `de`), plus `true_CL`, `true_CD`, `true_CM` (total coefficients, effects included),
    `u`, `w`, `x`, `gamma`. `de` is the recorded command; an actuator delay acts on
    the surface, not on the record. The physics is [`pitch_plane`][]'s.
    """
    vehicle, effects = model.vehicle, model.effects
    u, w, q, theta, _, h = y
    de_command = model.elevator(t)
    de = model.elevator(t - elevator_delay(effects))
    atm = isa(h)
    props = vehicle.mass.at(t, vehicle.motor)

    def aero(c):
        base = coefficients(vehicle.aero.derivatives(c.alpha, c.mach), c.alpha, c.de)
        return base.CL, base.CD, base.CM

    pp = pitch_plane(
        t,
        u,
        w,
        q,
        theta,
        h,
        de=de,
        aero=aero,
        effects=effects,
        s_ref=vehicle.s_ref,
        c_ref=vehicle.c_ref,
        density=atm.density,
        speed_of_sound=atm.speed_of_sound,
        g=gravity(h),
        thrust=vehicle.motor.net_thrust(t, atm.pressure),
        mass=props.mass,
        iyy=props.Iyy,
        iyy_dot=props.Iyy_dot,
        xcg=props.xcg,
        xcp=vehicle.xcp,
        recorded={"de": de_command, "Iyy": props.Iyy, "Iyy_dot": props.Iyy_dot},
    )
    xdot = u * jnp.cos(theta) + w * jnp.sin(theta)
    channels = {
        **pp.channels,
        "true_CL": pp.cl,
        "true_CD": pp.cd,
        "true_CM": pp.cm,
        "u": u,
        "w": w,
        "x": y[4],
        "gamma": jnp.arctan2(pp.hdot, xdot),
    }
    return Evaluation(
        rates=jnp.stack([pp.udot, pp.wdot, pp.qdot, q, xdot, pp.hdot]),
        condition=pp.condition,
        derivatives=vehicle.aero.derivatives(pp.condition.alpha, pp.condition.mach),
        channels=channels,
    )
