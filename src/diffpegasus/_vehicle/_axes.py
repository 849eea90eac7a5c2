"""The one rotation between wind (stability) axes and body axes in the pitch plane.

Lift and drag `(L, D)` and the body-axis forces `(X, Z)` are related by

    X =  L sin(alpha) - D cos(alpha)
    Z = -L cos(alpha) - D sin(alpha)

a reflection (its matrix is symmetric and orthogonal), so the same map takes body
axes back to lift and drag. It holds for coefficients and for their derivatives
alike.
"""

import jax.numpy as jnp

from .._custom_types import Scalar, ScalarLike


def wind_body(a: ScalarLike, b: ScalarLike, alpha: ScalarLike) -> tuple[Scalar, Scalar]:
    """`(CX, CZ)` from `(CL, CD)`, or `(CL, CD)` from `(CX, CZ)`, at angle of attack
    `alpha` (rad); any broadcastable shapes."""
    sa, ca = jnp.sin(alpha), jnp.cos(alpha)
    return a * sa - b * ca, -a * ca - b * sa
