"""Classical fourth-order Runge-Kutta as a diffrax solver (diffrax has none built in).

Used with a constant step equal to the sample interval, as flight-test output-error
codes do: with inputs interpolated linearly between samples, the two middle stages see
the inputs averaged over the step.
"""

from collections.abc import Callable
from typing import ClassVar

import diffrax
import numpy as np


_rk4_tableau = diffrax.ButcherTableau(
    a_lower=(np.array([0.5]), np.array([0.0, 0.5]), np.array([0.0, 0.0, 1.0])),
    b_sol=np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
    b_error=np.zeros(4),
    c=np.array([0.5, 0.5, 1.0]),
)


class RK4(diffrax.AbstractERK):
    """The classical RK4 method (fixed step only: its error estimate is zero)."""

    tableau: ClassVar[diffrax.ButcherTableau] = _rk4_tableau
    interpolation_cls: ClassVar[Callable[..., diffrax.LocalLinearInterpolation]] = (
        diffrax.ThirdOrderHermitePolynomialInterpolation.from_k
    )

    def order(self, terms):
        del terms
        return 4
