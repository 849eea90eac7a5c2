"""Score (Lagrange-multiplier) test of parameters held at a fit, from the engine's
exact Jacobian blocks: per candidate, the step it would take with every free unknown
re-adjusted, the predicted fall of det(R), and a chi-square statistic whose variance
includes the residuals' colour (Morelli-Klein) and their correlation between output
channels."""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from .._estimate._engine import Linearisation, linearise, row_jacobian


class ScoreTest(eqx.Module):
    """Score (Lagrange-multiplier) test of fixed parameters at a fit, one parameter
    at a time, each with all free parameters and nodes re-adjusted.

    **Fields** (one entry per tested parameter): `statistic` (chi-square, 1 degree
    of freedom, with the score's variance corrected for coloured residuals);
    `p_value`; `estimate` (the Gauss-Newton step from zero: the parameter's
    predicted value) and `stderr` (corrected, from the residuals after that step);
    `cost_ratio` (predicted det(R) after the step over det(R) now); `ls_reduction`
    (predicted fraction of the weighted residual sum of squares removed);
    `correlation` `(k, k)` between the tested parameters' sensitivities once the
    free unknowns are projected out (near +/-1: the data cannot tell them apart).

    What a calibration of the statistic against the log needs (see
    `diffpegasus._diagnose._calibration`): `rows` `(samples, outputs, k)`, the
    whitened output sensitivities of each tested direction with the free unknowns
    projected out (the efficient score is `sum rows * residuals`); `residuals`
    `(samples, outputs)`, the whitened output residuals; `valid` `(samples,)`,
    which rows are samples (not padding of the last shooting segment); `curvature`
    `(k,)`, the information of each projected direction; `slope` `(k,)`, the
    score (the cost's derivative along each projected direction, continuity
    defects included); `basis` `(samples, outputs, unknowns)`, whitened output
    sensitivities of the free unknowns scaled so that `e - basis (basis^T e)` is
    the residual a linearised refit of them to residuals `e` leaves (continuity
    defects' weight included; columns of held unknowns are zero).
    """

    statistic: Float[Array, " k"]
    p_value: Float[Array, " k"]
    estimate: Float[Array, " k"]
    stderr: Float[Array, " k"]
    cost_ratio: Float[Array, " k"]
    ls_reduction: Float[Array, " k"]
    correlation: Float[Array, "k k"]
    rows: Float[Array, "samples outputs k"]
    residuals: Float[Array, "samples outputs"]
    valid: Bool[Array, " samples"]
    curvature: Float[Array, " k"]
    slope: Float[Array, " k"]
    basis: Float[Array, "samples outputs unknowns"] | None = None


@jax.jit
def score_variance(
    rows: Float[Array, "samples outputs"],
    residuals: Float[Array, "samples outputs"],
) -> Float[Array, ""]:
    """Variance of the score `sum_t sum_o rows[t, o] residuals[t, o]` when the
    residuals are a stationary series correlated in time and between outputs:
    `sum_lag sum_(o, o') rows cross-correlation x residual cross-covariance`, each
    covariance estimated over all lags, by FFT; never below the sum of each
    output's own term (Morelli and Klein's per-output correction).

    The score adds every output's evidence; a structural misfit of the model (one
    wrong moment shows in q, qdot, theta, alpha and az at once) makes those terms
    move together, and counting only each output's own colour misses their
    covariance. With independent white noise in every output the cross terms vanish
    on average and this is the usual variance; the more a structural misfit
    dominates the noise (a 1 kHz log reduced to 50 Hz by block means has sqrt(20)
    less noise), the more they count. Measured on the independent generator's clean
    1 kHz flights: the thrust-misalignment statistic of seed 17 is 102 with the
    cross terms, 312 without. Negative cross terms (outputs whose evidence cancels)
    are not credited below the per-output sum: estimated over all lags from one
    record they scatter, and a low variance there is a false alarm (measured: an
    `ax` bias scored 19.8 instead of 6.5 at the filter-error fit of an HFB-320 flight
    with a planted `az` bias).

    **Arguments:** `rows` `(samples, outputs)`: whitened output sensitivities of
    the tested direction; `residuals` `(samples, outputs)`: whitened residuals.

    **Returns:** the variance, a scalar, in the units of `rows x residuals` squared.
    """
    n = rows.shape[0]
    m = 2 * n  # zero-padded: linear, not circular, correlations
    products = jnp.conj(jnp.fft.fft(residuals, n=m, axis=0)) * jnp.fft.fft(
        rows, n=m, axis=0
    )
    joint = jnp.sum(jnp.abs(jnp.sum(products, axis=1)) ** 2)
    own = jnp.sum(jnp.abs(products) ** 2)
    return jnp.maximum(joint, own) / (n * m)


@functools.partial(jax.jit, static_argnames=("model", "nx", "p"))
def score(model, layout, z, r, free, candidates, *, nx, p) -> ScoreTest:
    """Score test, at the unknowns `z` with residual variances `r` `(outputs,)`, of
    the parameters `candidates` (indices into theta, held in `free`): the model
    linearised at `z`, then `score_linearised`."""
    h, g, jyw, ew, _, d, _ = linearise(model, layout, z, nx, p, r)
    return _score(layout, z, h, g, jyw, ew, d, free, candidates, nx, p)


@functools.partial(jax.jit, static_argnames=("nx", "p"))
def score_linearised(
    layout, z, linearisation: Linearisation, free, candidates, *, nx, p
) -> ScoreTest:
    """`score` from the `Linearisation` an output-error fit stopped with
    at `z` (`Fit.linearisation`): the same test without evaluating the model, so
    its program holds no copy of the model's Jacobian."""
    lin = linearisation
    return _score(
        layout,
        z,
        lin.normal,
        lin.gradient,
        lin.jacobian,
        lin.whitened,
        lin.defects,
        free,
        candidates,
        nx,
        p,
    )


def _score(layout, z, h, g, jyw, ew, d, free, candidates, nx, p) -> ScoreTest:
    free_cols = layout.free_columns(free, nx, p)
    m = free_cols.astype(h.dtype)
    hb = h * m[:, None] * m[None, :] + jnp.diag(1.0 - m)
    cand = layout.n_segments * nx + candidates
    e_c = jnp.zeros((h.shape[0], cand.shape[0]))
    e_c = e_c.at[cand, jnp.arange(cand.shape[0])].set(1.0)
    # projected sensitivity direction: the candidate column minus its best fit by the
    # free unknowns
    coef = jnp.linalg.solve(hb, h[:, cand] * m[:, None])
    direction = e_c - coef * m[:, None]
    s = jnp.einsum("ik,ij,jk->k", direction, h, direction)
    slope = direction.T @ g
    step = -slope / s
    rows = row_jacobian(layout, jyw, direction, nx, p)  # (N, ny, k)
    ewf = ew.reshape(-1, ew.shape[-1])

    def robust_variance(col, a):
        # from the residuals the step leaves: at the current point the residual
        # still contains the candidate's signature, whose zero-lag product would
        # cancel the score
        return score_variance(col, ewf + a * col)

    coloured = jax.vmap(robust_variance, in_axes=(2, 0))(rows, step)
    variance = jnp.maximum(coloured, s)
    statistic = slope**2 / variance
    # per channel: mean of (e_w + step * rows)^2 relative to 1 (R is the residual
    # variance, so whitened channels have unit mean square)
    # the refit operator: with hb = L L^T, a linearised refit of the free unknowns
    # to residuals e removes J hb^-1 J^T e = B B^T e, B = J L^-T (free columns)
    chol = jnp.linalg.cholesky(hb)
    inv_t = jax.scipy.linalg.solve_triangular(chol, jnp.eye(h.shape[0]), lower=True).T
    basis = row_jacobian(layout, jyw, inv_t * m[:, None], nx, p)
    cross = jnp.einsum("no,nok->ok", ewf, rows)
    sq = jnp.einsum("nok,nok->ok", rows, rows)
    now = jnp.sum(ewf**2, axis=0)[:, None]
    ratio_ch = (now + 2.0 * step[None, :] * cross + step[None, :] ** 2 * sq) / now
    total = jnp.sum(ewf**2) + jnp.sum(d**2)
    norms = jnp.sqrt(s)
    return ScoreTest(
        statistic=statistic,
        p_value=jax.scipy.special.gammaincc(0.5, statistic / 2.0),
        estimate=z[layout.n_segments * nx + candidates] + step,
        stderr=jnp.sqrt(variance) / s,
        cost_ratio=jnp.prod(jnp.clip(ratio_ch, 1e-12), axis=0),
        ls_reduction=slope**2 / s / total,
        correlation=(direction.T @ h @ direction) / (norms[:, None] * norms[None, :]),
        rows=rows,
        residuals=ewf,
        valid=layout.valid.reshape(-1),
        curvature=s,
        slope=slope,
        basis=basis,
    )
