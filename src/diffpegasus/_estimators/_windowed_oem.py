"""Output error with windowed parameters over a long record: multiple shooting by a
structured Levenberg-Marquardt.

For a launch-vehicle record the unknowns are six derivatives per 0.5 s window (966
for the Pegasus first stage) plus a node state every 2 s. A dense Jacobian of all
residuals would have hundreds of thousands of rows; but a segment's output residuals
depend only on its own node state and parameters, and a continuity defect only on two
neighbouring segments. So each segment's Jacobian block (exact, forward mode through
its diffrax solves) is computed in one vmapped call, the normal equations are
assembled from the blocks (block-tridiagonal) and solved by Cholesky. R is diagonal
and re-estimated every iteration; the step is a Levenberg-Marquardt step whose
damping grows tenfold until the cost falls; the iteration stops when det(R) changes
by less than `rtol` relatively. Continuity is enforced by defect residuals
`(x_end(j) - node(j + 1)) / (state_scale * continuity_tol)`.

The parameters are either constant over each window (the thesis's model) or
continuous and linear in time between window boundaries (`linear=True`: one knot per
boundary, the same number of unknowns). The linear form follows derivatives that
change within a window (a pull-up sweeps alpha by several degrees in 0.5 s); a
window's estimate is then the mean of its parameters over the window.
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .._identify._engine import (
    _scatter,
    coloured_information as _coloured_information,
    lm_step as _solve,
)
from ._oem import (
    _input_at,
    _window_solve,
    OEMProblem,
    theil_inequality,
)


class WindowedFit(eqx.Module):
    """Result of [`fit_windowed_oem`][].

    **Fields:** `params` `(windows, params)` (each window's mean parameters);
    `stderr` (Cramér-Rao) and `stderr_corrected` (Morelli-Klein correction for
    coloured residuals) of `params`; `correlation` `(windows, params, params)` of each
    window's parameters; `knots` the estimated parameter values, `(windows, params)`
    for constant and `(windows + 1, params)` (values at the window boundaries) for
    linear parameters; `nodes` `(segments, states)`; `cost` det(R); `R` `(outputs,)`
    diagonal; `outputs` `(samples, outputs)`; `tic` `(outputs,)` Theil's inequality
    coefficient; `defect` largest continuity defect relative to the state scale;
    `iterations`; `converged`.
    """

    params: Float[Array, "windows params"]
    stderr: Float[Array, "windows params"]
    stderr_corrected: Float[Array, "windows params"]
    correlation: Float[Array, "windows params params"]
    knots: Float[Array, "knots params"]
    active: Bool[Array, " windows"]
    nodes: Float[Array, "segments states"]
    cost: Float[Array, ""]
    R: Float[Array, " outputs"]
    outputs: Float[Array, "samples outputs"]
    tic: Float[Array, " outputs"]
    defect: Float[Array, ""]
    iterations: Int[Array, ""]
    converged: Bool[Array, ""]


class _Layout(eqx.Module):
    """Where each unknown lives in the flat vector `[blocks (S nb), tail (P)]`: a
    block is `[node (nx), k knots x P]`; with linear parameters the knot at the end
    of the last window is the tail."""

    n_seg: int = eqx.field(static=True)
    nx: int = eqx.field(static=True)
    p: int = eqx.field(static=True)
    k: int = eqx.field(static=True)
    linear: bool = eqx.field(static=True)
    n_windows: int = eqx.field(static=True)

    @property
    def nb(self):
        return self.nx + self.k * self.p

    @property
    def size(self):
        return self.n_seg * self.nb + (self.p if self.linear else 0)

    def knot_cols(self) -> np.ndarray:
        """`(knots, P)` columns of every knot (padded ones included)."""
        n = self.n_seg * self.k + (1 if self.linear else 0)
        w = np.arange(n)[:, None]
        i = np.arange(self.p)[None, :]
        inside = (w // self.k) * self.nb + self.nx + (w % self.k) * self.p + i
        return np.where(w < self.n_seg * self.k, inside, self.n_seg * self.nb + i)

    def local_cols(self) -> np.ndarray:
        """`(S, nl)` columns of each segment's local vector `[block, next knot]`."""
        s = np.arange(self.n_seg)[:, None]
        own = s * self.nb + np.arange(self.nb)[None, :]
        if not self.linear:
            return own
        return np.concatenate([own, self.knot_cols()[(s[:, 0] + 1) * self.k]], axis=1)

    def used_knots(self) -> int:
        return self.n_windows + (1 if self.linear else 0)

    def window_map(self) -> np.ndarray:
        """`(nl, k P)`: window means of a segment's parameters from its local vector."""
        a = np.zeros((self.nb + (self.p if self.linear else 0), self.k * self.p))
        for j in range(self.k):
            for i in range(self.p):
                col = j * self.p + i
                if self.linear:
                    a[self.nx + j * self.p + i, col] = 0.5
                    a[self.nx + (j + 1) * self.p + i, col] = 0.5
                else:
                    a[self.nx + j * self.p + i, col] = 1.0
        return a


def _segment(problem: OEMProblem, layout: _Layout, s, v):
    """Outputs of segment `s` (padded, `(k L, outputs)`) and its end state, from its
    local vector `v = [node, k knots, (next knot)]`."""
    nx, k, p = layout.nx, layout.k, layout.p
    length = problem.window_samples
    knots = v[nx : nx + k * p].reshape(k, p)
    ends = (
        jnp.concatenate([knots[1:], v[nx + k * p :][None]]) if layout.linear else None
    )
    frac = jnp.arange(length)[:, None] / length

    def step(x, inp):
        j, th0, th1 = inp
        t_start = problem.t0 + (s * k + j) * length * problem.dt
        xs, ts = _window_solve(problem, x, th0, t_start, th1)
        if th1 is None:
            th = jnp.broadcast_to(th0, (length, p))
        else:
            th = th0[None, :] + frac * (th1 - th0)[None, :]
        u = jax.vmap(lambda t, th_: _input_at(problem, t, th_))(ts[:-1], th)
        y = jax.vmap(problem.outputs)(ts[:-1], xs[:-1], u, th)
        return xs[-1], y

    x_end, ys = jax.lax.scan(step, v[:nx], (jnp.arange(k), knots, ends))
    return ys.reshape(k * length, -1), x_end


@functools.partial(jax.jit, static_argnames=("layout", "max_iter"))
def _fit(problem, layout, z0, active, rtol, max_iter):
    n_seg, nx = layout.n_seg, layout.nx
    per = layout.k * problem.window_samples
    index = jnp.arange(n_seg)[:, None] * per + jnp.arange(per)[None, :]
    in_window = jnp.minimum(index // problem.window_samples, layout.n_windows - 1)
    valid = (index < problem.n_samples) & active[in_window]
    measured = problem.measured[jnp.minimum(index, problem.n_samples - 1)]
    c = problem.state_scale * problem.continuity_tol
    seg_ids = jnp.arange(n_seg)
    local = jnp.asarray(layout.local_cols())
    node_cols = local[:, :nx]
    knot_cols = layout.knot_cols()
    free = np.ones(layout.size, bool)
    free[knot_cols[layout.used_knots() :].ravel()] = False
    free[knot_cols[:, ~np.asarray(problem.free)].ravel()] = False
    # a knot is estimated if a window that uses it is active
    if layout.linear:
        padded = jnp.concatenate([jnp.zeros(1, bool), active, jnp.zeros(1, bool)])
        knot_active = padded[:-1] | padded[1:]
    else:
        knot_active = active
    n_k = knot_active.shape[0]
    free_cols = (
        jnp.asarray(free)
        .at[knot_cols[:n_k]]
        .set(jnp.asarray(free)[knot_cols[:n_k]] & knot_active[:, None])
    )

    def residuals(z):
        ys, ends = jax.vmap(lambda s, cols: _segment(problem, layout, s, z[cols]))(
            seg_ids, local
        )
        e = jnp.where(valid[..., None], measured - ys, 0.0)
        d = (ends[:-1] - z[node_cols[1:]]) / c[None, :]
        return e, d, ys

    def covariance(e):
        return jnp.sum(e**2, axis=(0, 1)) / jnp.sum(valid)

    def cost_ls(z, r):
        e, d, _ = residuals(z)
        return jnp.sum(e**2 / r[None, None, :]) + jnp.sum(d**2)

    def normal_equations(z, r):
        def jac(s, cols):
            return jax.jacfwd(lambda v: _segment(problem, layout, s, v))(z[cols])

        jy, jx = jax.vmap(jac)(seg_ids, local)  # (S, n, ny, nl), (S, nx, nl)
        e, d, _ = residuals(z)
        w = 1.0 / jnp.sqrt(r)
        # padded samples past the record are masked with where: their values may be
        # non-finite, and 0 * nan is nan
        jyw = jnp.where(valid[..., None, None], -jy * w[None, None, :, None], 0.0)
        ew = e * w[None, None, :]
        h = jnp.zeros((layout.size, layout.size))
        g = jnp.zeros(layout.size)
        h, g = _scatter(
            h, g, local, jyw.reshape(n_seg, -1, jy.shape[-1]), ew.reshape(n_seg, -1)
        )
        if n_seg > 1:
            minus = jnp.broadcast_to(-jnp.eye(nx) / c[:, None], (n_seg - 1, nx, nx))
            jd = jnp.concatenate([jx[:-1] / c[None, :, None], minus], axis=2)
            cols = jnp.concatenate([local[:-1], node_cols[1:]], axis=1)
            h, g = _scatter(h, g, cols, jd, d)
        return h, g, jyw, ew

    def body(carry):
        z, r, cost_prev, it, _, damping, _ = carry
        h, g, _, _ = normal_equations(z, r)
        j0 = cost_ls(z, r)

        def trial(lam):
            new = z + _solve(h, g, free_cols, lam)
            return new, cost_ls(new, r)

        def increase(c_):
            lam = jnp.maximum(10.0 * c_[0], 1e-8)
            return (lam, *trial(lam))

        damping, new, j1 = jax.lax.while_loop(
            lambda c_: ~(c_[2] < j0) & (c_[0] < 1e8),
            increase,
            (damping, *trial(damping)),
        )
        accepted = j1 < j0
        new = jnp.where(accepted, new, z)
        e, _, _ = residuals(new)
        r_new = covariance(e)
        cost = jnp.prod(r_new)
        small = jnp.abs(cost_prev - cost) <= rtol * jnp.abs(cost)
        broken = ~(jnp.all(jnp.isfinite(h)) & jnp.all(jnp.isfinite(g)))
        return new, r_new, cost, it + 1, small | ~accepted, damping / 10.0, broken

    e0, _, _ = residuals(z0)
    r0 = covariance(e0)
    init = (z0, r0, jnp.prod(r0), jnp.array(0), jnp.array(False), jnp.array(0.0))
    z, r, cost, iterations, done, _, broken = jax.lax.while_loop(
        lambda c_: (c_[3] < max_iter) & ~c_[4], body, (*init, jnp.array(False))
    )
    h, _, jyw, ew = normal_equations(z, r)
    m = free_cols.astype(h.dtype)
    cov = jnp.linalg.inv(h * m[:, None] * m[None, :] + jnp.diag(1.0 - m))
    cov = cov * m[:, None] * m[None, :]

    # each window's parameters as a linear map of the unknowns
    n_win, p = layout.n_windows, layout.p
    a = knot_cols[:n_win]
    b = knot_cols[1 : n_win + 1] if layout.linear else a
    knots = z[knot_cols[: layout.used_knots()]]
    params = 0.5 * (z[a] + z[b])

    def block(x, y):
        return cov[x[:, :, None], y[:, None, :]]

    cov_w = 0.25 * (block(a, a) + block(b, b) + block(a, b) + block(b, a))
    var = jnp.clip(jnp.diagonal(cov_w, axis1=1, axis2=2), 0.0)
    sd = jnp.sqrt(var)
    dd = jnp.sqrt(jnp.clip(var, 1e-300))
    correlation = cov_w / (dd[:, :, None] * dd[:, None, :])

    # coloured-residual correction, per segment from its own rows: the ratio of the
    # Morelli-Klein sandwich to the white-residual one, applied to the Cramér-Rao SE
    amap = jnp.asarray(layout.window_map())

    def inflation(jyw_s, ew_s, cols):
        kk = jnp.einsum(
            "noa,ab,bc->noc", jyw_s, cov[cols[:, None], cols[None, :]], amap
        )
        coloured = jnp.diagonal(_coloured_information(kk, ew_s))
        white = jnp.einsum("noc,noc->c", kk, kk)
        return jnp.maximum(coloured / jnp.clip(white, 1e-300), 1.0)

    ratio = jax.vmap(inflation)(jyw, ew, local).reshape(-1, p)[:n_win]
    e, d, ys = residuals(z)
    outputs = ys.reshape(-1, ys.shape[-1])[: problem.n_samples]
    defect = jnp.max(jnp.abs(d)) * problem.continuity_tol if n_seg > 1 else 0.0
    converged = done & ~broken & jnp.isfinite(cost) & jnp.all(jnp.isfinite(params))
    return WindowedFit(
        params=params,
        stderr=sd,
        stderr_corrected=sd * jnp.sqrt(ratio),
        correlation=correlation,
        knots=knots,
        active=active,
        nodes=z[node_cols],
        cost=cost,
        R=r,
        outputs=outputs,
        tic=theil_inequality(problem.measured, outputs),
        defect=jnp.asarray(defect),
        iterations=iterations,
        converged=converged,
    )


def fit_windowed_oem(
    problem: OEMProblem,
    theta0: Float[Array, "windows params"],
    nodes0: Float[Array, "segments states"],
    *,
    linear: bool = False,
    active=None,
    rtol: float = 1e-5,
    max_iter: int = 30,
) -> WindowedFit:
    """Multiple-shooting output error with parameters per window.

    **Arguments:** `problem` with `window` and `node_interval` set and `state_scale`
    given (parameters fixed by `problem.free` stay at their starting values: with
    `linear`, knots at the means of neighbouring windows' `theta0`); `theta0` starting
    parameters per window; `nodes0` starting node states (usually the measured states
    at the node times), all estimated; `linear`: parameters continuous and linear in
    time between window boundaries instead of constant per window (the boundary
    values start from the mean of the neighbouring windows' `theta0`); `active`
    `(windows,)` which windows are fitted (default all; an inactive window's samples
    are not used and its own knots stay at their starting values — with `linear` the
    knot it shares with an active neighbour is estimated, so report inactive windows
    as having no estimate, as `estimate_oem` does; e.g. where the dynamic pressure is
    too low to tell anything; a traced array, so it batches).

    **Returns:** a [`WindowedFit`][]. Pure and jitted: `jax.vmap` over problems
    (e.g. the flights of a campaign) batches it.
    """
    if problem.window is None or problem.node_interval is None:
        raise ValueError("fit_windowed_oem needs both window and node_interval")
    theta0 = jnp.asarray(theta0, float)
    nodes0 = jnp.asarray(nodes0, float)
    layout = _Layout(
        n_seg=problem.n_segments,
        nx=nodes0.shape[1],
        p=theta0.shape[1],
        k=problem.windows_per_segment,
        linear=linear,
        n_windows=problem.n_windows,
    )
    if theta0.shape[0] != layout.n_windows or nodes0.shape[0] != layout.n_seg:
        raise ValueError(
            f"theta0 {theta0.shape} and nodes0 {nodes0.shape} must have one row per "
            f"window ({layout.n_windows}) and per segment ({layout.n_seg})"
        )
    if linear:
        mid = 0.5 * (theta0[1:] + theta0[:-1])
        theta0 = jnp.concatenate([theta0[:1], mid, theta0[-1:]])
    cols = layout.knot_cols()
    knots = jnp.concatenate(
        [theta0, jnp.repeat(theta0[-1:], cols.shape[0] - theta0.shape[0], axis=0)]
    )
    z0 = jnp.zeros(layout.size).at[cols].set(knots)
    z0 = z0.at[layout.local_cols()[:, : layout.nx]].set(nodes0)
    active = (
        jnp.ones(layout.n_windows, bool)
        if active is None
        else jnp.asarray(active, bool)
    )
    return _fit(problem, layout, z0, active, rtol, max_iter)
