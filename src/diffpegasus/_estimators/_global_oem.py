"""Output error with parameters global over a long record: multiple shooting by a
structured Gauss-Newton, with a score test for parameters held at zero.

The unknowns are the model parameters (one set for the whole record) and a node state
at the start of every shooting segment. A segment's output residuals depend on its own
node and the parameters, a continuity defect on two neighbouring nodes and the
parameters, so each segment's Jacobian (exact, forward mode through its diffrax
solve) is computed in one vmapped call with `states + params` tangents, instead of
one tangent per unknown of the whole record, and the normal equations (an
"arrowhead": block-tridiagonal in the nodes, bordered by the parameters) are
assembled from the blocks and solved by Cholesky. R is diagonal and re-estimated
every iteration; the step is halved until the cost falls; the iteration stops when
det(R) changes by less than `rtol` relatively.

Which parameters are estimated is a traced mask, not a static choice: every parameter
has its Jacobian column, fixed ones get a zero step. So fitting with different free
sets (the baseline, the baseline plus an effect) reuses one compiled function, and the
score test of the fixed parameters at the optimum comes from the same blocks.
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from ._oem import (
    _coloured_information,
    _input_at,
    _window_solve,
    OEMProblem,
    theil_inequality,
)


class GlobalFit(eqx.Module):
    """Result of [`fit_global_oem`][].

    **Fields:** `params` `(params,)` (fixed ones at their given values); `stderr`
    (Cramér-Rao) and `stderr_corrected` (Morelli-Klein correction for coloured
    residuals), 0 for fixed parameters; `correlation` `(params, params)` (fixed rows
    0); `nodes` `(segments, states)`; `cost` det(R); `R` `(outputs,)` diagonal;
    `outputs` `(samples, outputs)`; `defect` largest continuity defect relative to the
    state scale; `iterations`; `converged`; `tic` `(outputs,)` Theil's inequality
    coefficient.
    """

    params: Float[Array, " params"]
    free: Bool[Array, " params"]
    stderr: Float[Array, " params"]
    stderr_corrected: Float[Array, " params"]
    correlation: Float[Array, "params params"]
    nodes: Float[Array, "segments states"]
    cost: Float[Array, ""]
    R: Float[Array, " outputs"]
    outputs: Float[Array, "samples outputs"]
    defect: Float[Array, ""]
    iterations: Int[Array, ""]
    converged: Bool[Array, ""]
    tic: Float[Array, " outputs"]


def _segment(problem: OEMProblem, s, node, theta):
    """Outputs of segment `s` `(per, outputs)` and its end state."""
    per = problem.window_samples
    t_start = problem.t0 + s * per * problem.dt
    xs, ts = _window_solve(problem, node, theta, t_start)
    u = jax.vmap(lambda t: _input_at(problem, t, theta))(ts[:-1])
    ys = jax.vmap(lambda t, x_, u_: problem.outputs(t, x_, u_, theta))(
        ts[:-1], xs[:-1], u
    )
    return ys, xs[-1]


class _Setup(eqx.Module):
    index: Int[Array, "segments per"]
    valid: Bool[Array, "segments per"]
    measured: Float[Array, "segments per outputs"]
    scale: Float[Array, " states"]

    @classmethod
    def make(cls, problem, n_seg):
        per = problem.window_samples
        index = jnp.arange(n_seg)[:, None] * per + jnp.arange(per)[None, :]
        valid = index < problem.n_samples
        measured = problem.measured[jnp.minimum(index, problem.n_samples - 1)]
        return cls(index, valid, measured, problem.state_scale * problem.continuity_tol)


def _residuals(problem, setup, theta, nodes):
    seg = jnp.arange(nodes.shape[0])
    ys, ends = jax.vmap(lambda s, x0: _segment(problem, s, x0, theta))(seg, nodes)
    e = jnp.where(setup.valid[..., None], setup.measured - ys, 0.0)
    d = (ends[:-1] - nodes[1:]) / setup.scale[None, :]
    return e, d, ys


def _blocks(problem, setup, theta, nodes):
    """Per segment: Jacobians of the outputs and of the end state with respect to
    `[node, theta]`."""
    nx = nodes.shape[1]
    seg = jnp.arange(nodes.shape[0])

    def local(s, node):
        def f(z):
            return _segment(problem, s, z[:nx], z[nx:])

        return jax.jacfwd(f)(jnp.concatenate([node, theta]))

    return jax.vmap(local)(seg, nodes)  # (S, per, ny, nx + P), (S, nx, nx + P)


def _scatter(h, g, cols, jac, res):
    """Add `J^T J` and `J^T r` of local blocks to the dense normal equations.

    `cols`: `(S, k)` global columns of each block's local unknowns; `jac`: `(S, rows,
    k)`; `res`: `(S, rows)`. Columns shared by two blocks accumulate."""
    hh = jnp.einsum("sra,srb->sab", jac, jac)
    gg = jnp.einsum("sra,sr->sa", jac, res)
    h = h.at[cols[:, :, None], cols[:, None, :]].add(hh)
    g = g.at[cols].add(gg)
    return h, g


def _normal_equations(problem, setup, theta, nodes, r):
    """Dense normal matrix and gradient over `[nodes (S nx), theta (P)]` of the
    R-weighted least squares, plus the whitened output Jacobian and residuals."""
    n_seg, nx = nodes.shape
    p = theta.shape[0]
    jy, jx = _blocks(problem, setup, theta, nodes)
    e, d, _ = _residuals(problem, setup, theta, nodes)
    w = 1.0 / jnp.sqrt(r)
    # residual = measured - model, so its Jacobian is minus the model's
    # (padded samples past the record are masked with where: their values may be
    # non-finite, and 0 * nan is nan)
    jyw = jnp.where(setup.valid[..., None, None], -jy * w[None, None, :, None], 0.0)
    ew = e * w[None, None, :]
    n = n_seg * nx + p
    h = jnp.zeros((n, n))
    g = jnp.zeros(n)
    node_cols = jnp.arange(n_seg)[:, None] * nx + jnp.arange(nx)[None, :]
    par_cols = n_seg * nx + jnp.arange(p)

    local_cols = jnp.concatenate(
        [node_cols, jnp.broadcast_to(par_cols, (n_seg, p))], axis=1
    )
    jyr = jyw.reshape(n_seg, -1, nx + p)
    h, g = _scatter(h, g, local_cols, jyr, ew.reshape(n_seg, -1))
    if n_seg > 1:
        # defect_j = (end_j - node_{j+1}) / scale
        jd = jx[:-1] / setup.scale[None, :, None]
        minus = -jnp.eye(nx)[None] / setup.scale[None, :, None]
        jd_full = jnp.concatenate(
            [jd, jnp.broadcast_to(minus, (n_seg - 1, nx, nx))], axis=2
        )
        cols = jnp.concatenate([local_cols[:-1], node_cols[1:]], axis=1)
        h, g = _scatter(h, g, cols, jd_full, d)
    return h, g, jyw, ew


def _cost_ls(problem, setup, theta, nodes, r):
    e, d, _ = _residuals(problem, setup, theta, nodes)
    return jnp.sum(e**2 / r[None, None, :]) + jnp.sum(d**2)


def _solve(h, g, free_cols, damping):
    """Levenberg-Marquardt step `(H + damping diag(H)) step = -g`, fixed columns held
    (zero step); `damping = 0` is the Gauss-Newton step."""
    m = free_cols.astype(h.dtype)
    hm = h * m[:, None] * m[None, :] + jnp.diag(1.0 - m)
    scale = jnp.sqrt(jnp.clip(jnp.diag(hm), 1e-300))
    hs = hm / scale[:, None] / scale[None, :]
    hs = hs + (damping + 1e-12) * jnp.eye(h.shape[0])
    step = jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(hs), -g * m / scale)
    return step / scale * m


@functools.partial(jax.jit, static_argnames=("max_iter",))
def _fit(problem, theta0, nodes0, free, rtol, max_iter):
    n_seg, nx = nodes0.shape
    setup = _Setup.make(problem, n_seg)
    free_cols = jnp.concatenate([jnp.ones(n_seg * nx, bool), free])

    def covariance(e):
        return jnp.sum(e**2, axis=(0, 1)) / jnp.sum(setup.valid)

    def unpack(z):
        return z[n_seg * nx :], z[: n_seg * nx].reshape(n_seg, nx)

    def body(carry):
        z, r, cost_prev, it, _, damping, _ = carry
        theta, nodes = unpack(z)
        h, g, _, _ = _normal_equations(problem, setup, theta, nodes, r)
        j0 = _cost_ls(problem, setup, theta, nodes, r)

        def trial(lam):
            new = z + _solve(h, g, free_cols, lam)
            return new, _cost_ls(problem, setup, *unpack(new), r)

        def increase(c):
            lam, _, _ = c
            lam = jnp.maximum(10.0 * lam, 1e-8)
            return (lam, *trial(lam))

        damping, new, j1 = jax.lax.while_loop(
            lambda c: ~(c[2] < j0) & (c[0] < 1e8), increase, (damping, *trial(damping))
        )
        accepted = j1 < j0
        new = jnp.where(accepted, new, z)
        e, _, _ = _residuals(problem, setup, *unpack(new))
        r_new = covariance(e)
        cost = jnp.prod(r_new)
        small = jnp.abs(cost_prev - cost) <= rtol * jnp.abs(cost)
        # no decrease at any damping: a minimum if the normal equations are finite,
        # a failure (e.g. a diverged segment) if not
        broken = ~(jnp.all(jnp.isfinite(h)) & jnp.all(jnp.isfinite(g)))
        return new, r_new, cost, it + 1, small | ~accepted, damping / 10.0, broken

    z0 = jnp.concatenate([nodes0.reshape(-1), theta0])
    e0, _, _ = _residuals(problem, setup, theta0, nodes0)
    r0 = covariance(e0)
    z, r, cost, iterations, done, _, broken = jax.lax.while_loop(
        lambda c: (c[3] < max_iter) & ~c[4],
        body,
        (
            z0,
            r0,
            jnp.prod(r0),
            jnp.array(0),
            jnp.array(False),
            jnp.array(0.0),
            jnp.array(False),
        ),
    )
    done = done & ~broken
    theta, nodes = unpack(z)
    h, _, jyw, ew = _normal_equations(problem, setup, theta, nodes, r)
    m = free_cols.astype(h.dtype)
    hm = h * m[:, None] * m[None, :] + jnp.diag(1.0 - m)
    cov = jnp.linalg.inv(hm) * m[:, None] * m[None, :]
    sandwich = _coloured(jyw, ew, cov[:, n_seg * nx :], n_seg, nx)
    var = jnp.diag(cov)[n_seg * nx :]
    sd = jnp.sqrt(jnp.clip(var, 0.0))
    sd_c = jnp.sqrt(jnp.clip(jnp.diag(sandwich), 0.0))
    block = cov[n_seg * nx :, n_seg * nx :]
    dd = jnp.sqrt(jnp.clip(jnp.diag(block), 1e-300))
    correlation = block / (dd[:, None] * dd[None, :])
    e, d, ys = _residuals(problem, setup, theta, nodes)
    outputs = ys.reshape(-1, ys.shape[-1])[: problem.n_samples]
    tic = theil_inequality(problem.measured, outputs)
    defect = jnp.max(jnp.abs(d)) * problem.continuity_tol if n_seg > 1 else 0.0
    converged = done & jnp.isfinite(cost) & jnp.all(jnp.isfinite(theta))
    return GlobalFit(
        params=theta,
        free=free,
        stderr=sd,
        stderr_corrected=jnp.maximum(sd_c, sd),
        correlation=correlation,
        nodes=nodes,
        cost=cost,
        R=r,
        outputs=outputs,
        defect=jnp.asarray(defect),
        iterations=iterations,
        converged=converged,
        tic=tic,
    )


def _row_jacobian(jyw, n_seg, nx, cols):
    """Whitened output Jacobian rows times `cols` `(S nx + P, k)`: `(rows, ny, k)`,
    in chronological order."""
    node_part = cols[: n_seg * nx].reshape(n_seg, nx, -1)
    par_part = cols[n_seg * nx :]
    out = jnp.einsum("snoa,sak->snok", jyw[..., :nx], node_part) + jnp.einsum(
        "snoa,ak->snok", jyw[..., nx:], par_part
    )
    return out.reshape(-1, out.shape[2], out.shape[3])


def _coloured(jyw, ew, cov_cols, n_seg, nx):
    """Coloured-residual covariance of the parameters: `K^T Sigma K` with `K = J
    cov[:, params]` and Sigma the residual autocovariance (per output channel)."""
    k = _row_jacobian(jyw, n_seg, nx, cov_cols)
    return _coloured_information(k, ew.reshape(-1, ew.shape[-1]))


def fit_global_oem(
    problem: OEMProblem,
    theta0: Float[Array, " params"],
    nodes0: Float[Array, "segments states"],
    free: Bool[Array, " params"] | None = None,
    *,
    rtol: float = 1e-5,
    max_iter: int = 40,
) -> GlobalFit:
    """Multiple-shooting output error with one parameter set for the record.

    **Arguments:** `problem` with `node_interval` set, `window=None` and
    `state_scale`; `theta0` `(params,)` starting (and fixed) values; `nodes0`
    `(segments, states)` starting node states (all estimated); `free` which
    parameters to estimate (an array: changing it does not recompile; default all;
    `problem.free` is ignored).

    **Returns:** a [`GlobalFit`][]. Pure and jitted; `jax.vmap` batches it.
    """
    if problem.window is not None or problem.node_interval is None:
        raise ValueError("fit_global_oem needs window=None and a node_interval")
    theta0 = jnp.asarray(theta0, float)
    free = jnp.ones(theta0.shape, bool) if free is None else jnp.asarray(free, bool)
    nodes0 = jnp.asarray(nodes0, float)
    if nodes0.shape[0] != problem.n_segments:
        raise ValueError(
            f"nodes0 has {nodes0.shape[0]} rows but the problem has "
            f"{problem.n_segments} shooting segments"
        )
    return _fit(problem, theta0, nodes0, free, rtol, max_iter)


class ScoreTest(eqx.Module):
    """Score (Lagrange-multiplier) test of fixed parameters at a fit, one parameter
    at a time, each with all free parameters and nodes re-adjusted.

    **Fields** (one entry per tested parameter): `statistic` (chi-square, 1 degree
    of freedom, with the score's variance corrected for coloured residuals);
    `p_value`; `estimate` (the Gauss-Newton step from zero: the parameter's
    predicted value) and `stderr` (corrected, from the residuals after that step); `cost_ratio` (predicted det(R) after
    the step over det(R) now); `ls_reduction` (predicted fraction of the weighted
    residual sum of squares removed); `correlation` `(k, k)` between the tested
    parameters' sensitivities once the free unknowns are projected out (near +/-1:
    the data cannot tell them apart).
    """

    statistic: Float[Array, " k"]
    p_value: Float[Array, " k"]
    estimate: Float[Array, " k"]
    stderr: Float[Array, " k"]
    cost_ratio: Float[Array, " k"]
    ls_reduction: Float[Array, " k"]
    correlation: Float[Array, "k k"]


@jax.jit
def _score(problem, fit, candidates):
    n_seg, nx = fit.nodes.shape
    setup = _Setup.make(problem, n_seg)
    h, g, jyw, ew = _normal_equations(problem, setup, fit.params, fit.nodes, fit.R)
    nb = n_seg * nx
    free_cols = jnp.concatenate([jnp.ones(nb, bool), fit.free])
    m = free_cols.astype(h.dtype)
    hb = h * m[:, None] * m[None, :] + jnp.diag(1.0 - m)
    cand = nb + candidates
    e_c = jnp.zeros((h.shape[0], cand.shape[0]))
    e_c = e_c.at[cand, jnp.arange(cand.shape[0])].set(1.0)
    # projected sensitivity direction: the candidate column minus its best fit by the
    # free unknowns
    coef = jnp.linalg.solve(hb, h[:, cand] * m[:, None])
    direction = e_c - coef * m[:, None]
    s = jnp.einsum("ik,ij,jk->k", direction, h, direction)
    score = direction.T @ g
    step = -score / s
    rows = _row_jacobian(jyw, n_seg, nx, direction)  # (N, ny, k)
    ewf = ew.reshape(-1, ew.shape[-1])

    def robust_variance(col, a):
        # the score's variance with the residuals' colour, from the residuals the
        # step leaves: at the current point the residual still contains the
        # candidate's signature, whose zero-lag product would cancel the score
        after = ewf + a * col
        return _coloured_information(col[:, :, None], after)[0, 0]

    coloured = jax.vmap(robust_variance, in_axes=(2, 0))(rows, step)
    variance = jnp.maximum(coloured, s)
    statistic = score**2 / variance
    # per channel: mean of (e_w + step * rows)^2 relative to 1 (R is the residual
    # variance, so whitened channels have unit mean square)
    cross = jnp.einsum("no,nok->ok", ewf, rows)
    sq = jnp.einsum("nok,nok->ok", rows, rows)
    now = jnp.sum(ewf**2, axis=0)[:, None]
    ratio_ch = (now + 2.0 * step[None, :] * cross + step[None, :] ** 2 * sq) / now
    total = jnp.sum(ewf**2) + jnp.sum(
        _residuals(problem, setup, fit.params, fit.nodes)[1] ** 2
    )
    norms = jnp.sqrt(s)
    return ScoreTest(
        statistic=statistic,
        p_value=jax.scipy.special.gammaincc(0.5, statistic / 2.0),
        estimate=fit.params[candidates] + step,
        stderr=jnp.sqrt(variance) / s,
        cost_ratio=jnp.prod(jnp.clip(ratio_ch, 1e-12), axis=0),
        ls_reduction=score**2 / s / total,
        correlation=(direction.T @ h @ direction) / (norms[:, None] * norms[None, :]),
    )


def score_test(problem: OEMProblem, fit: GlobalFit, candidates) -> ScoreTest:
    """Score test of the parameters `candidates` (indices, held fixed in `fit`)."""
    return _score(problem, fit, jnp.asarray(candidates, int))
