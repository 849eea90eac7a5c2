"""Output error with per-window parameters over a long record: multiple shooting by a
structured Gauss-Newton.

For a launch-vehicle record the unknowns are six derivatives in every 0.5 s window
(966 for the Pegasus first stage) plus a node state every 2 s. A dense Jacobian of
all residuals would have hundreds of thousands of rows; but a segment's output
residuals depend only on its own node state and windows, and a continuity defect only
on two neighbouring segments. So each segment's Jacobian block (exact, forward mode
through its diffrax solves) is computed in one vmapped call, the Gauss-Newton normal
equations are assembled from the blocks (block-tridiagonal), and solved with a
Cholesky factorisation. R is re-estimated every iteration (diagonal), the step is
halved until the cost falls, and the iteration stops when det(R) changes by less than
`rtol` relatively. Continuity is enforced by defect residuals
`(x_end(j) - node(j + 1)) / (state_scale * continuity_tol)`.

This path exists because optimistix's Gauss-Newton materialises the dense Jacobian;
for problems of moderate size [`fit_oem`][] (optimistix) is the general engine.
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from ._oem import _input_at, _window_solve, OEMProblem


class WindowedFit(eqx.Module):
    """Result of [`fit_windowed_oem`][]: `params` `(windows, params)`, `stderr`
    (Cramér-Rao, same shape), `nodes` `(segments, states)`, `cost` det(R), `R`
    `(outputs,)` (diagonal), `outputs` `(samples, outputs)`, `defect` (largest
    continuity defect relative to the state scale), `iterations`, `converged`."""

    params: Float[Array, "windows params"]
    stderr: Float[Array, "windows params"]
    nodes: Float[Array, "segments states"]
    cost: Float[Array, ""]
    R: Float[Array, " outputs"]
    outputs: Float[Array, "samples outputs"]
    defect: Float[Array, ""]
    iterations: Int[Array, ""]
    converged: Bool[Array, ""]


def _segment_outputs(problem: OEMProblem, s, block):
    """Outputs of segment `s` (padded, `(k L, outputs)`) and its end state, from the
    flat block `[node state, k windows x params]`."""
    nx = problem.state_scale.shape[0]
    k, length = problem.windows_per_segment, problem.window_samples
    x0 = block[:nx]
    thetas = block[nx:].reshape(k, -1)

    def step(x, j):
        w = s * k + j
        t_start = problem.t0 + w * length * problem.dt
        xs, ts = _window_solve(problem, x, thetas[j], t_start)
        u = jax.vmap(lambda t: _input_at(problem, t))(ts[:-1])
        y = jax.vmap(lambda t, x_, u_: problem.outputs(t, x_, u_, thetas[j]))(
            ts[:-1], xs[:-1], u
        )
        return xs[-1], y

    x_end, ys = jax.lax.scan(step, x0, jnp.arange(k))
    return ys.reshape(k * length, -1), x_end


@functools.partial(jax.jit, static_argnames=("max_iter",))
def _fit(problem, blocks0, rtol, max_iter):
    n_seg, nb = blocks0.shape
    nx = problem.state_scale.shape[0]
    per = problem.windows_per_segment * problem.window_samples
    index = jnp.arange(n_seg)[:, None] * per + jnp.arange(per)[None, :]
    valid = index < problem.n_samples
    measured = problem.measured[jnp.minimum(index, problem.n_samples - 1)]
    c = problem.state_scale * problem.continuity_tol
    seg_ids = jnp.arange(n_seg)

    def residuals(blocks):
        ys, ends = jax.vmap(lambda s, b: _segment_outputs(problem, s, b))(
            seg_ids, blocks
        )
        e = jnp.where(valid[..., None], measured - ys, 0.0)
        d = (ends[:-1] - blocks[1:, :nx]) / c[None, :]
        return e, d, ys

    def covariance(e):
        return jnp.sum(e**2, axis=(0, 1)) / jnp.sum(valid)

    def cost_ls(blocks, r):
        e, d, _ = residuals(blocks)
        return jnp.sum(e**2 / r[None, None, :]) + jnp.sum(d**2)

    def normal_equations(blocks, r):
        def local(s, b):
            return jax.jacfwd(lambda bb: _segment_outputs(problem, s, bb))(b)

        jy, jx = jax.vmap(local)(seg_ids, blocks)  # (S, n, ny, nb), (S, nx, nb)
        e, d, _ = residuals(blocks)
        w = 1.0 / jnp.sqrt(r)
        jyw = -jy * w[None, None, :, None] * valid[..., None, None]
        ew = e * w[None, None, :]
        h_diag = jnp.einsum("snoa,snob->sab", jyw, jyw)
        g = jnp.einsum("snoa,sno->sa", jyw, ew)
        dx = jx[:-1] / c[None, :, None]  # d defect / d own block
        h_diag = h_diag.at[:-1].add(jnp.einsum("sia,sib->sab", dx, dx))
        g = g.at[:-1].add(jnp.einsum("sia,si->sa", dx, d))
        eye = jnp.zeros((nx, nb)).at[:, :nx].set(jnp.eye(nx)) / c[:, None]
        h_diag = h_diag.at[1:].add(eye.T @ eye)
        g = g.at[1:].add(jnp.einsum("ia,si->sa", -eye, d))
        h_off = jnp.einsum("sia,ib->sab", dx, -eye)  # coupling of block s and s + 1
        n = n_seg * nb
        h = jnp.zeros((n, n))
        for_blocks = jnp.arange(n_seg) * nb
        rows = for_blocks[:, None] + jnp.arange(nb)[None, :]
        h = h.at[rows[:, :, None], rows[:, None, :]].set(h_diag)
        h = h.at[rows[:-1, :, None], rows[1:, None, :]].set(h_off)
        h = h.at[rows[1:, :, None], rows[:-1, None, :]].set(jnp.swapaxes(h_off, 1, 2))
        return h, g.reshape(-1)

    def solve(h, g):
        scale = jnp.sqrt(jnp.clip(jnp.diag(h), 1e-300))
        hs = h / scale[:, None] / scale[None, :] + 1e-10 * jnp.eye(h.shape[0])
        step = jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(hs), -g / scale)
        return step / scale

    e0, _, _ = residuals(blocks0)
    r0 = covariance(e0)

    def body(carry):
        blocks, r, cost_prev, it, _ = carry
        h, g = normal_equations(blocks, r)
        delta = solve(h, g).reshape(blocks.shape)
        j0 = cost_ls(blocks, r)

        def halve(c_):
            alpha, _ = c_
            return alpha / 2, cost_ls(blocks + alpha / 2 * delta, r)

        alpha, j1 = jax.lax.while_loop(
            lambda c_: (~(c_[1] < j0)) & (c_[0] > 2.0**-10),
            halve,
            (jnp.array(1.0), cost_ls(blocks + delta, r)),
        )
        new = jnp.where(j1 < j0, blocks + alpha * delta, blocks)
        e, _, _ = residuals(new)
        r_new = covariance(e)
        cost = jnp.prod(r_new)
        done = jnp.abs(cost_prev - cost) <= rtol * jnp.abs(cost)
        return new, r_new, cost, it + 1, done

    init = (blocks0, r0, jnp.prod(r0), jnp.array(0), jnp.array(False))
    blocks, r, cost, iterations, done = jax.lax.while_loop(
        lambda c_: (c_[3] < max_iter) & ~c_[4], body, init
    )
    h, _ = normal_equations(blocks, r)
    cov = jnp.linalg.pinv(h, hermitian=True)
    sd = jnp.sqrt(jnp.clip(jnp.diag(cov), 0.0)).reshape(n_seg, nb)
    k = problem.windows_per_segment
    params = blocks[:, nx:].reshape(n_seg * k, -1)[: problem.n_windows]
    stderr = sd[:, nx:].reshape(n_seg * k, -1)[: problem.n_windows]
    e, d, ys = residuals(blocks)
    outputs = ys.reshape(-1, ys.shape[-1])[: problem.n_samples]
    defect = (
        jnp.max(jnp.abs(d)) * problem.continuity_tol if n_seg > 1 else jnp.zeros(())
    )
    converged = done & jnp.isfinite(cost) & jnp.all(jnp.isfinite(params))
    return WindowedFit(
        params, stderr, blocks[:, :nx], cost, r, outputs, defect, iterations, converged
    )


def fit_windowed_oem(
    problem: OEMProblem,
    theta0: Float[Array, "windows params"],
    nodes0: Float[Array, "segments states"],
    *,
    rtol: float = 1e-5,
    max_iter: int = 30,
) -> WindowedFit:
    """Multiple-shooting output error with one parameter set per window.

    **Arguments:** `problem` with `window` and `node_interval` set and `state_scale`
    given; `theta0` starting parameters per window; `nodes0` starting node states
    (usually the measured states at the node times); all are estimated.

    **Returns:** a [`WindowedFit`][]. Pure and jitted: `jax.vmap` over problems
    (e.g. the flights of a campaign) batches it.
    """
    if problem.window is None or problem.node_interval is None:
        raise ValueError("fit_windowed_oem needs both window and node_interval")
    k, n_seg = problem.windows_per_segment, problem.n_segments
    n_win = problem.n_windows
    theta0 = jnp.asarray(theta0, float)
    pad = n_seg * k - n_win
    theta0 = jnp.concatenate([theta0, jnp.repeat(theta0[-1:], pad, axis=0)])
    blocks0 = jnp.concatenate(
        [jnp.asarray(nodes0, float), theta0.reshape(n_seg, -1)], axis=1
    )
    return _fit(problem, blocks0, rtol, max_iter)
