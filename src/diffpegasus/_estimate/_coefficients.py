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


def reconstruct_coefficients(
    channels: dict[str, Float[Array, " n"]], s_ref: float, c_ref: float
) -> MeasuredCoefficients:
    """Reconstruct the aerodynamic coefficients from a flight log's channels.

    - `CX = (m ax - T) / (qbar S)`, `CZ = m az / (qbar S)` (accelerometers measure
      specific force at the CG, so gravity does not appear);
    - `CM = (Iyy qdot + Iyy_dot q - (xcp - xcg) m az) / (qbar S c)`, removing the
      moment of the normal force acting at the cp;
    - `CL`, `CD` by rotating `CX`, `CZ` through the measured alpha.

    **Arguments:** `channels` with `ax, az, q, qdot, alpha, qbar, thrust, mass, Iyy,
    Iyy_dot, xcg, xcp`; reference area `s_ref` (m^2) and length `c_ref` (m).
    """
    c = channels
    qs = c["qbar"] * s_ref
    fz = c["mass"] * c["az"]
    cx = (c["mass"] * c["ax"] - c["thrust"]) / qs
    cz = fz / qs
    moment = c["Iyy"] * c["qdot"] + c["Iyy_dot"] * c["q"] - (c["xcp"] - c["xcg"]) * fz
    cm = moment / (qs * c_ref)
    cl, cd = wind_axis(cx, cz, c["alpha"])
    return MeasuredCoefficients(CX=cx, CZ=cz, CL=cl, CD=cd, CM=jnp.asarray(cm))
