"""Drag coefficient against Mach number: knots whose values are parameters.

`CD(M)` is the natural cubic spline through the knots at fixed Mach numbers (two
knots: the straight line) and constant beyond the first and last. A spline, not
straight lines: drag curves are smooth, and straight lines between points on one
leave it by up to `h^2 CD'' / 8` between knots `h` apart (1.5 to 2% of CD on the
simulated flights' curves at 0.1 Mach spacing; the spline 0.6 to 0.9%, in its end
intervals), an error the knots' band does not carry. The spline is linear
in the knot values, `CD(M) = w(M)' cd` with weights from the knot positions alone,
so the band of `CD(M)` follows from the knots' covariance exactly,
`var CD(M) = w(M)' C w(M)`.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import scipy.interpolate

from ..._errors import LogError
from ._rows import read_rows


def _coefficients(x: np.ndarray) -> np.ndarray:
    """`(4, knots - 1, knots)`: the natural cubic spline through the knots `x` of
    each unit knot vector, as per-segment polynomial coefficients in `M - x[i]`
    (highest power first), scipy's `CubicSpline` of the identity."""
    n = len(x)
    if n == 2:  # the straight line
        c = np.zeros((4, 1, 2))
        c[2, 0] = np.array([-1.0, 1.0]) / (x[1] - x[0])
        c[3, 0] = np.array([1.0, 0.0])
        return c
    return scipy.interpolate.CubicSpline(x, np.eye(n), bc_type="natural").c


class DragKnots(eqx.Module):
    """Knot positions of `CD(Mach)`, a natural cubic spline through the knots.

    **Fields:**

    - `mach` `(knots,)`: increasing Mach numbers.
    """

    mach: tuple[float, ...] = eqx.field(static=True)

    def __check_init__(self):
        if len(self.mach) < 1 or np.any(np.diff(self.mach) <= 0):
            raise ValueError(f"drag knots must increase, got {self.mach}")

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names of the knot values, `cd_0`, `cd_1`, ..."""
        return tuple(f"cd_{i}" for i in range(len(self.mach)))

    def _basis(self, mach, xp):
        """`(..., knots)` weights at `mach` with array module `xp` (numpy or jax)."""
        x = np.asarray(self.mach, float)
        c = xp.asarray(_coefficients(x))
        m = xp.clip(mach, x[0], x[-1])
        i = xp.clip(xp.searchsorted(x, m, side="right") - 1, 0, len(x) - 2)
        d = (m - xp.asarray(x)[i])[..., None]
        return ((c[0][i] * d + c[1][i]) * d + c[2][i]) * d + c[3][i]

    def __call__(self, mach, values):
        """`CD` at `mach` (jax scalar) from the knot `values` `(knots,)`."""
        if len(self.mach) == 1:
            return values[0]
        return jnp.dot(self._basis(jnp.asarray(mach), jnp), values)

    def weights(self, mach) -> np.ndarray:
        """`(len(mach), knots)` weights (numpy), rows summing to 1:
        `CD(mach) = weights(mach) @ values`."""
        mach = np.atleast_1d(np.asarray(mach, float))
        if len(self.mach) == 1:
            return np.ones((len(mach), 1))
        return self._basis(mach, np)


# a team's curve beyond these is in other units (CD in percent) or other columns:
# rockets' CD stays below 2 (1.5 with air brakes out), sounding rockets fly below Mach 10
CD_HIGHEST = 5.0
MACH_HIGHEST = 25.0


def read_drag_curve(path) -> tuple[np.ndarray, np.ndarray]:
    """A team's `CD(Mach)` table: two columns (Mach, CD), a header row allowed,
    in any order and with repeated Mach numbers (rows of a simulated trajectory are
    averaged per Mach number). Returns sorted `(mach, cd)`."""
    a, lines, _ = read_rows(path, ("Mach", "CD"), "the drag curve")
    bad = np.flatnonzero((a[:, 0] < 0) | (a[:, 1] < 0))
    if len(bad):
        j = bad[0]
        raise LogError(
            f"{path}: row {lines[j]}: Mach {a[j, 0]:g}, CD {a[j, 1]:g} is not plausible"
        )
    high = np.flatnonzero((a[:, 0] > MACH_HIGHEST) | (a[:, 1] > CD_HIGHEST))
    if len(high):
        j = high[0]
        raise LogError(
            f"{path}: row {lines[j]}: Mach {a[j, 0]:g}, CD {a[j, 1]:g} is beyond any "
            f"rocket's (Mach up to {MACH_HIGHEST:g}, CD up to {CD_HIGHEST:g}); a CD in "
            "percent, or the columns swapped? (Mach first, then CD)"
        )
    mach, inverse = np.unique(np.round(a[:, 0], 6), return_inverse=True)
    cd = np.bincount(inverse, a[:, 1]) / np.bincount(inverse)
    return mach, cd
