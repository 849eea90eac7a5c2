"""The a-priori aerodynamic database and the longitudinal coefficient model.

CL = CLa alpha + CLde de, CD = CDa alpha + CDde de, CM = CMa alpha + CMde de, where the
six derivatives are tabulated over (alpha, Mach) and interpolated with a C1 bicubic
(Catmull-Rom) interpolant, so trajectories and Jacobians see no kinks at grid lines.
CM is the pitching moment about the centre-of-pressure station; the simulator adds the
moment of the normal force placed at the cp. Provenance: `scripts/make_aero_database.py`.
"""

import importlib.resources

import equinox as eqx
import jax.lax as lax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..._custom_types import Scalar, ScalarLike
from .._axes import wind_body


DERIVATIVE_NAMES = ("CLa", "CLde", "CDa", "CDde", "CMa", "CMde")


class AeroDerivatives(eqx.Module):
    """The six longitudinal derivatives (1/rad) at one flight condition."""

    CLa: Scalar
    CLde: Scalar
    CDa: Scalar
    CDde: Scalar
    CMa: Scalar
    CMde: Scalar

    def as_array(self) -> Float[Array, "6"]:
        """Stacked in the order of `DERIVATIVE_NAMES`."""
        return jnp.stack([getattr(self, n) for n in DERIVATIVE_NAMES])


class AeroCoefficients(eqx.Module):
    """Lift, drag and pitching-moment (about the cp station) coefficients."""

    CL: Scalar
    CD: Scalar
    CM: Scalar


def _catmull_rom_weights(s: Scalar) -> Float[Array, "4"]:
    s2 = s * s
    s3 = s2 * s
    return 0.5 * jnp.stack(
        [-s3 + 2 * s2 - s, 3 * s3 - 5 * s2 + 2, -3 * s3 + 4 * s2 + s, s3 - s2]
    )


def _pad_linear(table: np.ndarray, axis: int) -> np.ndarray:
    """Add one linearly extrapolated ghost point at each end of `axis`."""
    t = np.moveaxis(table, axis, 0)
    padded = np.concatenate([2 * t[:1] - t[1:2], t, 2 * t[-1:] - t[-2:-1]])
    return np.moveaxis(padded, 0, axis)


class AeroDatabase(eqx.Module):
    """Derivative tables on a uniform (alpha, Mach) grid.

    **Fields:**

    - `alpha0`, `dalpha`: first alpha breakpoint and spacing, rad.
    - `mach0`, `dmach`: first Mach breakpoint and spacing.
    - `tables`: shape `(6, n_alpha + 2, n_mach + 2)`, the derivatives in the order of
      `DERIVATIVE_NAMES` (1/rad), padded with one linearly extrapolated ghost point on
      each side for the cubic stencil.
    - `scale`: shape `(3,)`, factors on the CL, CD and CM derivatives (Monte Carlo
      perturbations). Kept apart from the tables so a batch of perturbed vehicles
      shares one copy of the tables.

    Queries outside the grid are clamped to its edge (constant extrapolation).
    """

    alpha0: float = eqx.field(static=True)
    dalpha: float = eqx.field(static=True)
    mach0: float = eqx.field(static=True)
    dmach: float = eqx.field(static=True)
    tables: Float[Array, "6 na2 nm2"]
    scale: Float[Array, "3"] = eqx.field(default_factory=lambda: jnp.ones(3))

    @property
    def alpha_range(self) -> tuple[float, float]:
        """Smallest and largest alpha breakpoint, rad."""
        n = self.tables.shape[1] - 2
        return self.alpha0, self.alpha0 + (n - 1) * self.dalpha

    @property
    def mach_range(self) -> tuple[float, float]:
        """Smallest and largest Mach breakpoint."""
        n = self.tables.shape[2] - 2
        return self.mach0, self.mach0 + (n - 1) * self.dmach

    def derivatives(self, alpha: ScalarLike, mach: ScalarLike) -> AeroDerivatives:
        """Interpolated derivatives (1/rad) at `alpha` (rad) and `mach`."""
        n_alpha = self.tables.shape[1] - 2
        n_mach = self.tables.shape[2] - 2
        xa = jnp.clip((alpha - self.alpha0) / self.dalpha, 0.0, n_alpha - 1.0)
        xm = jnp.clip((mach - self.mach0) / self.dmach, 0.0, n_mach - 1.0)
        ia = jnp.clip(jnp.floor(xa), 0, n_alpha - 2).astype(int)
        im = jnp.clip(jnp.floor(xm), 0, n_mach - 2).astype(int)
        wa = _catmull_rom_weights(xa - ia)
        wm = _catmull_rom_weights(xm - im)
        # In the padded tables, grid point i - 1 sits at index i.
        block = lax.dynamic_slice(self.tables, (0, ia, im), (6, 4, 4))
        values = jnp.einsum("kij,i,j->k", block, wa, wm) * jnp.repeat(self.scale, 2)
        return AeroDerivatives(*values)

    def scaled(
        self, lift: ScalarLike = 1.0, drag: ScalarLike = 1.0, moment: ScalarLike = 1.0
    ) -> "AeroDatabase":
        """A copy with the CL, CD and CM derivatives multiplied by the given factors."""
        factors = jnp.stack([jnp.asarray(f, float) for f in (lift, drag, moment)])
        return eqx.tree_at(lambda d: d.scale, self, self.scale * factors)


def load_database(path=None) -> AeroDatabase:
    """Load a database CSV (columns `mach, alpha_deg, CLa, ..., CMde`, per rad).

    **Arguments:**

    - `path`: a CSV file; default the shipped Pegasus database.

    The grid must be uniform in both alpha and Mach.
    """
    if path is None:
        path = importlib.resources.files("diffpegasus") / "data" / "pegasus_aero.csv"
    with open(path) as f:
        header = f.readline().strip().split(",")
        data = np.loadtxt(f, delimiter=",", ndmin=2)
    expected = ["mach", "alpha_deg", *DERIVATIVE_NAMES]
    if header != expected:
        raise ValueError(f"{path}: header must be {','.join(expected)}, got {header}")
    machs = np.unique(data[:, 0])
    alphas = np.unique(data[:, 1])
    if len(data) != len(machs) * len(alphas):
        raise ValueError(
            f"{path}: the (mach, alpha_deg) points do not form a full grid"
        )
    for name, grid in (("mach", machs), ("alpha_deg", alphas)):
        if len(grid) < 2:
            raise ValueError(f"{path}: column {name} needs at least two breakpoints")
        steps = np.diff(grid)
        if not np.allclose(steps, steps[0], rtol=1e-6):
            raise ValueError(f"{path}: column {name} is not uniformly spaced")
    order = np.lexsort((data[:, 1], data[:, 0]))
    values = data[order, 2:].reshape(len(machs), len(alphas), 6)
    tables = np.transpose(values, (2, 1, 0))
    tables = _pad_linear(_pad_linear(tables, 1), 2)
    return AeroDatabase(
        alpha0=float(np.deg2rad(alphas[0])),
        dalpha=float(np.deg2rad(alphas[1] - alphas[0])),
        mach0=float(machs[0]),
        dmach=float(machs[1] - machs[0]),
        tables=jnp.asarray(tables),
    )


def coefficients(
    d: AeroDerivatives, alpha: ScalarLike, de: ScalarLike
) -> AeroCoefficients:
    """CL, CD, CM from the derivatives, alpha and elevator deflection (rad)."""
    return AeroCoefficients(
        CL=d.CLa * alpha + d.CLde * de,
        CD=d.CDa * alpha + d.CDde * de,
        CM=d.CMa * alpha + d.CMde * de,
    )


def body_axis(
    cl: ScalarLike, cd: ScalarLike, alpha: ScalarLike
) -> tuple[Scalar, Scalar]:
    """Body-axis force coefficients `(CX, CZ)` from lift and drag coefficients."""
    return wind_body(cl, cd, alpha)


def wind_axis(
    cx: ScalarLike, cz: ScalarLike, alpha: ScalarLike
) -> tuple[Scalar, Scalar]:
    """Lift and drag coefficients `(CL, CD)` from body-axis force coefficients."""
    return wind_body(cx, cz, alpha)
