"""Windowed equation-error least squares (thesis chapter 3).

Each of CL, CD and CM, reconstructed from the measurements, is regressed on
`[alpha, de]` (optionally with an intercept) over consecutive windows. Every window's
regressor matrix A and normal matrix A^T A are rank-checked with an absolute
singular-value tolerance (MATLAB's `rank(A, tol)`, tolerance 1e-2 as in the thesis);
a rank-deficient window keeps the previous window's estimate and is flagged.

An absolute tolerance depends on the units of the regressors. The thesis regresses and
reports per degree, so the rank check sees the angle columns in degrees (the estimates
themselves do not depend on this). In radians even the thesis's 2 Hz sine input would
fail the A^T A test.
"""

import functools

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .._log._format import FlightLog, TRUTH_CHANNELS
from ._coefficients import reconstruct_coefficients
from ._result import Estimates
from ._windows import WindowLayout


def _solve_window(a, y, mask, tol, column_scale):
    # Everything goes through the p x p normal matrix: the singular values of A are
    # the square roots of the eigenvalues of A^T A, so no (samples x samples) SVD
    # workspace is ever allocated (it was 0.3 GB per 1 kHz flight).
    aw = a * mask[:, None]
    yw = y * mask[:, None]
    p = a.shape[1]
    ata = aw.T @ aw
    scaled = ata * column_scale[:, None] * column_scale[None, :]
    eig = jnp.clip(jnp.linalg.eigvalsh(scaled), 0.0)
    rank_a = jnp.sum(jnp.sqrt(eig) > tol)
    rank_ata = jnp.sum(eig > tol)
    cov = jnp.linalg.pinv(ata, hermitian=True)
    theta = cov @ (aw.T @ yw)
    resid = yw - aw @ theta
    dof = jnp.maximum(jnp.sum(mask) - p, 1.0)
    sigma2 = jnp.sum(resid**2, axis=0) / dof
    stderr = jnp.sqrt(jnp.clip(jnp.diag(cov), 0.0))[:, None] * jnp.sqrt(sigma2)[None, :]
    return theta, stderr, rank_a, rank_ata


def _hold(values, stderr, ok):
    """Replace the estimates of windows that are not `ok` by the last good one (NaN
    before the first)."""

    def step(carry, x):
        v, s, good = x
        carry = jax.tree_util.tree_map(
            lambda new, old: jnp.where(good, new, old), (v, s), carry
        )
        return carry, carry

    init = (jnp.full_like(values[0], jnp.nan), jnp.full_like(stderr[0], jnp.nan))
    _, (v, s) = jax.lax.scan(step, init, (values, stderr, ok))
    return v, s


def windowed_least_squares(
    a: Float[Array, "windows per p"],
    y: Float[Array, "windows per k"],
    mask: Float[Array, "windows per"],
    *,
    tol: float = 1e-2,
    column_scale: Float[Array, " p"] | None = None,
    require_full_normal_rank: bool = True,
) -> tuple[
    Float[Array, "windows p k"],
    Float[Array, "windows p k"],
    Int[Array, " windows"],
    Int[Array, " windows"],
    Bool[Array, " windows"],
]:
    """Least squares `y = a theta` in every window, with the thesis's rank rule.

    **Arguments:**

    - `a`: regressors, `y`: regressands, `mask`: 1 for real samples, 0 for padding.
    - `tol`: absolute singular-value tolerance for the ranks of A and A^T A.
    - `column_scale`: factors on the columns of A for the rank check only (e.g.
      180/pi to check angles in degrees); default 1.
    - `require_full_normal_rank`: the thesis's rule needs both A and A^T A full rank;
      `False` needs A only (the relaxed rule of its pulse-input study).

    **Returns:** `(theta, stderr, rank_A, rank_ATA, ok)`: estimates held from the last
    `ok` window where a window is not `ok` (NaN before the first), their standard
    errors (residual variance times the diagonal of (A^T A)^-1), the ranks, and
    whether each window met the rule.
    """
    p = a.shape[-1]
    scale = jnp.ones(p) if column_scale is None else jnp.asarray(column_scale)
    theta, stderr, rank_a, rank_ata = jax.vmap(
        functools.partial(_solve_window, tol=tol, column_scale=scale)
    )(a, y, mask)
    ok = rank_a == p
    if require_full_normal_rank:
        ok = ok & (rank_ata == p)
    theta, stderr = _hold(theta, stderr, ok)
    return theta, stderr, rank_a, rank_ata, ok


@functools.partial(
    jax.jit, static_argnames=("layout", "intercept", "tol", "s_ref", "c_ref")
)
def lse_arrays(
    channels: dict[str, Float[Array, " n"]],
    layout: WindowLayout,
    *,
    s_ref: float = 13.5,
    c_ref: float = 2.48,
    intercept: bool = False,
    tol: float = 1e-2,
) -> dict[str, Array]:
    """The LSE estimator on arrays: jitted, and `jax.vmap`-able over logs of equal
    length (see [`lse_batch`][]).

    **Returns:** a dict with `values` and `stderr` `(windows, 6)` in 1/rad (held
    estimates where rank-deficient), `intercepts` `(windows, 3)` (CL0, CD0, CM0; zero
    without `intercept`), `rank_A`, `rank_ATA`, `rank_deficient` `(windows,)`.
    """
    coeffs = reconstruct_coefficients(channels, s_ref, c_ref)
    cols = [channels["alpha"], channels["de"]]
    deg = 180.0 / jnp.pi
    scale = [deg, deg]
    if intercept:
        cols = [jnp.ones_like(channels["alpha"]), *cols]
        scale = [1.0, *scale]
    a = layout.split(jnp.stack(cols, axis=-1))
    y = layout.split(jnp.stack([coeffs.CL, coeffs.CD, coeffs.CM], axis=-1))
    theta, stderr, rank_a, rank_ata, ok = windowed_least_squares(
        a, y, layout.mask(), tol=tol, column_scale=jnp.asarray(scale)
    )
    # rows of theta: ([1,] alpha, de); columns: CL, CD, CM
    values = jnp.swapaxes(theta[:, -2:, :], 1, 2).reshape(layout.count, 6)
    errors = jnp.swapaxes(stderr[:, -2:, :], 1, 2).reshape(layout.count, 6)
    intercepts = theta[:, 0, :] if intercept else jnp.zeros((layout.count, 3))
    return {
        "values": values,
        "stderr": errors,
        "intercepts": intercepts,
        "rank_A": rank_a,
        "rank_ATA": rank_ata,
        "rank_deficient": ~ok,
        "held": ~ok & jnp.isfinite(values[:, 0]),
    }


def lse_batch(
    channels: dict[str, Float[Array, "batch n"]], layout: WindowLayout, **kwargs
) -> dict[str, Array]:
    """[`lse_arrays`][] over a batch of logs of equal length, in one vmapped call."""
    return jax.vmap(lambda c: lse_arrays(c, layout, **kwargs))(channels)


def window_truth(channels: dict[str, Array], layout: WindowLayout) -> Array | None:
    """The `true_*` derivatives averaged over each window, `(windows, 6)`, or None."""
    if not all(c in channels for c in TRUTH_CHANNELS):
        return None
    return jnp.stack([layout.window_mean(channels[c]) for c in TRUTH_CHANNELS], axis=-1)


def estimate_lse(
    log: FlightLog,
    *,
    window: float = 0.5,
    intercept: bool = False,
    tol: float = 1e-2,
) -> Estimates:
    """Windowed equation-error least squares on a flight log.

    **Arguments:**

    - `log`: a validated [`FlightLog`][].
    - `window`: window length, s (default 0.5 s, the thesis's 2 Hz).
    - `intercept`: also estimate CL0, CD0, CM0 per window (reported in `flags`).
    - `tol`: rank tolerance.

    **Returns:** [`Estimates`][] with flags `rank_deficient`, `rank_A`, `rank_ATA`
    and, with an intercept, `CL0`, `CD0`, `CM0`.
    """
    layout = WindowLayout.make(len(log), log.sample_rate, window)
    channels = {k: jnp.asarray(v) for k, v in log.channels.items()}
    out = lse_arrays(
        channels,
        layout,
        s_ref=log.s_ref,
        c_ref=log.c_ref,
        intercept=intercept,
        tol=tol,
    )
    start, end = layout.times(float(log.t[0]))
    flags = {k: out[k] for k in ("rank_deficient", "rank_A", "rank_ATA")}
    if intercept:
        for j, name in enumerate(("CL0", "CD0", "CM0")):
            flags[name] = jnp.where(
                out["rank_deficient"], jnp.nan, out["intercepts"][:, j]
            )
    return Estimates(
        method="lse",
        window_start=jnp.asarray(start),
        window_end=jnp.asarray(end),
        values=out["values"],
        stderr=out["stderr"],
        valid=~out["rank_deficient"],
        flags=flags,
        truth=window_truth(channels, layout),
    )
