"""Force and moment coefficients reconstructed from measured channels.

The inverse of the flight model's force and moment equations: accelerometers give the
non-gravitational body forces, the pitch acceleration the moment.
"""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._vehicle._pegasus._aerodynamics import wind_axis


class MeasuredCoefficients(eqx.Module):
    """Coefficients per sample: body axes `CX`, `CZ`, wind axes `CL`, `CD`, and `CM`
    about the cp station (the database's convention)."""

    CX: Float[Array, " n"]
    CZ: Float[Array, " n"]
    CL: Float[Array, " n"]
    CD: Float[Array, " n"]
    CM: Float[Array, " n"]


def aerodynamic_loads(
    channels: dict[str, Float[Array, " n"]],
) -> tuple[Float[Array, " n"], Float[Array, " n"], Float[Array, " n"]]:
    """The measured aerodynamic loads per sample: body-axis forces `X = m ax - T`,
    `Z = m az` (N; accelerometers measure specific force at the CG, so gravity does
    not appear) and the pitching moment about the cp station,
    `M = Iyy qdot + Iyy_dot q - (xcp - xcg) m az` (N m), which removes the moment of
    the normal force acting at the cp from the moment about the CG.

    **Arguments:** `channels` with `ax, az, q, qdot, thrust, mass, Iyy, Iyy_dot, xcg,
    xcp`.
    """
    c = channels
    fz = c["mass"] * c["az"]
    fx = c["mass"] * c["ax"] - c["thrust"]
    moment = c["Iyy"] * c["qdot"] + c["Iyy_dot"] * c["q"] - (c["xcp"] - c["xcg"]) * fz
    return fx, fz, jnp.asarray(moment)


def reconstruct_coefficients(
    channels: dict[str, Float[Array, " n"]], s_ref: float, c_ref: float
) -> MeasuredCoefficients:
    """Reconstruct the aerodynamic coefficients from a flight log's channels.

    `CX = X / (qbar S)`, `CZ = Z / (qbar S)`, `CM = M / (qbar S c)` about the cp
    station from the [`aerodynamic_loads`][]; `CL`, `CD` by rotating `CX`, `CZ`
    through the measured alpha.

    **Arguments:** `channels` with `ax, az, q, qdot, alpha, qbar, thrust, mass, Iyy,
    Iyy_dot, xcg, xcp`; reference area `s_ref` (m^2) and length `c_ref` (m).
    """
    fx, fz, moment = aerodynamic_loads(channels)
    qs = channels["qbar"] * s_ref
    cx, cz = fx / qs, fz / qs
    cm = moment / (qs * c_ref)
    cl, cd = wind_axis(cx, cz, channels["alpha"])
    return MeasuredCoefficients(CX=cx, CZ=cz, CL=cl, CD=cd, CM=jnp.asarray(cm))
