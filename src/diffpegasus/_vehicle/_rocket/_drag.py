"""Drag coefficient against Mach number: knots whose values are parameters.

`CD(M)` is piecewise linear between knots at fixed Mach numbers and constant beyond
the first and last, so it is linear in the knot values: the band of `CD(M)` follows
from the knots' covariance exactly, `var CD(M) = w(M)' C w(M)`.
"""

import pathlib

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._errors import LogError


class DragKnots(eqx.Module):
    """Knot positions of a piecewise-linear `CD(Mach)`.

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

    def __call__(self, mach, values):
        """`CD` at `mach` (jax scalar) from the knot `values` `(knots,)`."""
        if len(self.mach) == 1:
            return values[0]
        return jnp.interp(mach, jnp.asarray(self.mach), values)

    def weights(self, mach) -> np.ndarray:
        """`(len(mach), knots)` interpolation weights (numpy), rows summing to 1."""
        mach = np.atleast_1d(np.asarray(mach, float))
        eye = np.eye(len(self.mach))
        if len(self.mach) == 1:
            return np.ones((len(mach), 1))
        return np.stack([np.interp(mach, self.mach, e) for e in eye], axis=1)


def read_drag_curve(path) -> tuple[np.ndarray, np.ndarray]:
    """A team's `CD(Mach)` table: two columns (Mach, CD), a header row allowed,
    in any order and with repeated Mach numbers (rows of a simulated trajectory are
    averaged per Mach number). Returns sorted `(mach, cd)`."""
    path = pathlib.Path(path)
    try:
        lines = path.read_text(errors="replace").splitlines()
    except OSError as e:
        raise LogError(f"{path}: cannot read the drag curve ({e.strerror})") from None
    rows = []
    for i, line in enumerate(lines, 1):
        parts = line.replace(",", " ").split()
        if not parts:
            continue
        try:
            m, c = float(parts[0]), float(parts[1])
        except (ValueError, IndexError):
            if not rows:
                continue  # header
            raise LogError(
                f"{path}: row {i}: {line.strip()!r} is not 'Mach CD'"
            ) from None
        if not (np.isfinite(m) and np.isfinite(c)) or m < 0 or c < 0:
            raise LogError(f"{path}: row {i}: Mach {m:g}, CD {c:g} is not plausible")
        rows.append((m, c))
    if not rows:
        raise LogError(f"{path}: no (Mach, CD) rows")
    a = np.asarray(rows)
    mach, inverse = np.unique(np.round(a[:, 0], 6), return_inverse=True)
    cd = np.bincount(inverse, a[:, 1]) / np.bincount(inverse)
    return mach, cd
