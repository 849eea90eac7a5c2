"""jaxtyping aliases shared across the package."""

from typing import TypeAlias

from jaxtyping import Array, ArrayLike, Float


Scalar: TypeAlias = Float[Array, ""]
ScalarLike: TypeAlias = float | Float[ArrayLike, ""]
Times: TypeAlias = Float[Array, " time"]
