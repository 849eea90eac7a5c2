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
boundary, the same number of unknowns), or a mix of the two, chosen per parameter
(`linear` a tuple of bools). The linear form follows derivatives that change within a
window (a pull-up sweeps alpha by several degrees in 0.5 s); a window's estimate is
then the mean of its parameters over the window. A parameter constant per window in
a mixed fit uses the knot at the window's start for the whole window (the knot after
the last window is not estimated). A parameter may be held at its starting value in
some windows (`held`): e.g. a window term whose regressor is collinear with another's
in that window, which would otherwise wander along the flat direction and keep the
iteration from stopping.
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .._cache import kept_call
from ._engine import (
    AbstractLayout,
    coloured_information as _coloured_information,
    RESULTS,
    solve,
)
from ._global_oem import VectorModel
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
    linear parameters; `held` `(windows, params)` which parameters were held at their
    starting values in each window (their `stderr` zero); `nodes` `(segments,
    states)`; `cost` det(R); `R` `(outputs,)`
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
    held: Bool[Array, "windows params"]
    nodes: Float[Array, "segments states"]
    cost: Float[Array, ""]
    R: Float[Array, " outputs"]
    outputs: Float[Array, "samples outputs"]
    tic: Float[Array, " outputs"]
    defect: Float[Array, ""]
    iterations: Int[Array, ""]
    converged: Bool[Array, ""]


class _Layout(AbstractLayout):
    """The engine's layout for parameters per window: where each unknown lives in
    the flat vector `[blocks (S nb), tail (P)]`: a block is `[node (nx), k knots x
    P]`; with linear parameters the knot at the end of the last window is the tail.
    Carries the problem (data, model functions), the traced `active` window mask and
    the traced `held` mask (parameters held at their start per window).
    """

    problem: OEMProblem
    active: Bool[Array, " windows"]
    held: Bool[Array, "windows params"]
    measured: Float[Array, "segments length outputs"]
    valid: Bool[Array, "segments length"]
    link: Bool[Array, " links"]
    scale: Float[Array, " states"]
    n_seg: int = eqx.field(static=True)
    nx: int = eqx.field(static=True)
    p: int = eqx.field(static=True)
    k: int = eqx.field(static=True)
    linear: bool = eqx.field(static=True)
    n_windows: int = eqx.field(static=True)
    # with `linear`: which parameters are constant per window instead (their knot j
    # holds window j's value)
    stepped: tuple[bool, ...] = eqx.field(static=True)

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
                if self.linear and not self.stepped[i]:
                    a[self.nx + j * self.p + i, col] = 0.5
                    a[self.nx + (j + 1) * self.p + i, col] = 0.5
                else:
                    a[self.nx + j * self.p + i, col] = 1.0
        return a

    def local_columns(self, nx, p):
        del nx, p
        return jnp.asarray(self.local_cols())

    def node_columns(self, nx, p):
        return self.local_columns(nx, p)[:, :nx]

    def segment(self, model, s, v, nx, p):
        del model, nx, p
        return _segment(self.problem, self, s, v)

    def free_columns(self, free_params, nx, p):
        del free_params, nx, p
        knot_cols = self.knot_cols()
        free = np.ones(self.size, bool)
        free[knot_cols[self.used_knots() :].ravel()] = False
        free[knot_cols[:, ~np.asarray(self.problem.free)].ravel()] = False
        # a knot is estimated if an active window that uses it does not hold it
        uses = self.active[:, None] & ~self.held
        if self.linear:
            none = jnp.zeros((1, self.p), bool)
            padded = jnp.concatenate([none, uses, none])
            # a stepped parameter's knot belongs to its window alone (the last none)
            knot_active = jnp.where(
                jnp.asarray(self.stepped)[None, :],
                padded[1:],
                padded[:-1] | padded[1:],
            )
        else:
            knot_active = uses
        n_k = knot_active.shape[0]
        return (
            jnp.asarray(free)
            .at[knot_cols[:n_k]]
            .set(jnp.asarray(free)[knot_cols[:n_k]] & knot_active)
        )


def _make_layout(
    problem, active, n_seg, nx, p, k, linear, n_windows, stepped=None, held=None
) -> _Layout:
    if stepped is None:
        stepped = (not linear,) * p
    if held is None:
        held = jnp.zeros((n_windows, p), bool)
    per = k * problem.window_samples
    # numpy: static shapes, so no small programs compiled per call
    index = np.arange(n_seg)[:, None] * per + np.arange(per)[None, :]
    in_window = np.minimum(index // problem.window_samples, n_windows - 1)
    return _Layout(
        problem=problem,
        active=active,
        held=held,
        measured=problem.measured[np.minimum(index, problem.n_samples - 1)],
        valid=(index < problem.n_samples) & active[in_window],
        link=jnp.ones(n_seg - 1, bool),
        scale=problem.state_scale * problem.continuity_tol,
        n_seg=n_seg,
        nx=nx,
        p=p,
        k=k,
        linear=linear,
        n_windows=n_windows,
        stepped=stepped,
    )


def _segment(problem: OEMProblem, layout: _Layout, s, v):
    """Outputs of segment `s` (padded, `(k L, outputs)`) and its end state, from its
    local vector `v = [node, k knots, (next knot)]`."""
    nx, k, p = layout.nx, layout.k, layout.p
    length = problem.window_samples
    knots = v[nx : nx + k * p].reshape(k, p)
    if layout.linear:
        ends = jnp.concatenate([knots[1:], v[nx + k * p :][None]])
        ends = jnp.where(jnp.asarray(layout.stepped)[None, :], knots, ends)
    else:
        ends = None
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


@functools.partial(jax.jit, static_argnames=("structure", "max_iter"))
def _fit(problem, structure, z0, active, held, rtol, max_iter):
    layout = _make_layout(problem, active, *structure, held=held)
    nx, p = layout.nx, layout.p
    model = VectorModel(problem.rates, problem.outputs, problem.input_delay)
    sol = solve(
        model,
        layout,
        z0,
        jnp.asarray(problem.free),
        nx=nx,
        p=p,
        rtol=rtol,
        max_iter=max_iter,
        coloured=False,
    )
    z, cov, jyw, ew = sol.z, sol.covariance, sol.jacobian, sol.whitened
    local = layout.local_columns(nx, p)
    knot_cols = layout.knot_cols()

    # each window's parameters as a linear map of the unknowns
    n_win = layout.n_windows
    a = knot_cols[:n_win]
    b = knot_cols[1 : n_win + 1] if layout.linear else a
    b = np.where(np.asarray(layout.stepped)[None, :], a, b)
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
    outputs = sol.outputs.reshape(-1, sol.outputs.shape[-1])[: problem.n_samples]
    converged = (sol.result == RESULTS.successful) & jnp.all(jnp.isfinite(params))
    return WindowedFit(
        params=params,
        stderr=sd,
        stderr_corrected=sd * jnp.sqrt(ratio),
        correlation=correlation,
        knots=knots,
        active=active,
        held=held,
        nodes=z[local[:, :nx]],
        cost=sol.cost,
        R=sol.R,
        outputs=outputs,
        tic=theil_inequality(problem.measured, outputs),
        defect=sol.defect * problem.continuity_tol,
        iterations=sol.iterations,
        converged=converged,
    )


def fit_windowed_oem(
    problem: OEMProblem,
    theta0: Float[Array, "windows params"],
    nodes0: Float[Array, "segments states"],
    *,
    linear: bool | tuple[bool, ...] = False,
    active=None,
    held=None,
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
    values start from the mean of the neighbouring windows' `theta0`), or one bool
    per parameter to mix the two (a parameter constant per window starts from its
    `theta0`); `active`
    `(windows,)` which windows are fitted (default all; an inactive window's samples
    are not used and its own knots stay at their starting values — with `linear` the
    knot it shares with an active neighbour is estimated, so report inactive windows
    as having no estimate, as `estimate_oem` does; e.g. where the dynamic pressure is
    too low to tell anything; a traced array, so it batches); `held` `(windows,
    params)` parameters held at their starting values in a window (default none; a
    linear parameter's knot is estimated if an active window using it does not hold
    it; traced, so it batches), e.g. a window term that the window's data cannot tell
    from another.

    **Returns:** a [`WindowedFit`][]. Pure and jitted: `jax.vmap` over problems
    (e.g. the flights of a campaign) batches it.
    """
    if problem.window is None or problem.node_interval is None:
        raise ValueError("fit_windowed_oem needs both window and node_interval")
    theta0 = jnp.asarray(theta0, float)
    nodes0 = jnp.asarray(nodes0, float)
    if isinstance(linear, bool):
        linear = (linear,) * theta0.shape[1]
    if len(linear) != theta0.shape[1]:
        raise ValueError(
            f"linear has {len(linear)} entries for {theta0.shape[1]} parameters"
        )
    stepped = tuple(not bool(x) for x in linear)
    linear = not all(stepped)
    structure = (
        problem.n_segments,
        nodes0.shape[1],
        theta0.shape[1],
        problem.windows_per_segment,
        linear,
        problem.n_windows,
        stepped,
    )
    active = (
        jnp.ones(problem.n_windows, bool)
        if active is None
        else jnp.asarray(active, bool)
    )
    held = jnp.zeros(theta0.shape, bool) if held is None else jnp.asarray(held, bool)
    if held.shape != theta0.shape:
        raise ValueError(
            f"held {held.shape} must have the shape of theta0 {theta0.shape}"
        )
    layout = _make_layout(problem, active, *structure, held=held)
    if theta0.shape[0] != layout.n_windows or nodes0.shape[0] != layout.n_seg:
        raise ValueError(
            f"theta0 {theta0.shape} and nodes0 {nodes0.shape} must have one row per "
            f"window ({layout.n_windows}) and per segment ({layout.n_seg})"
        )
    if linear:
        mid = 0.5 * (theta0[1:] + theta0[:-1])
        theta0 = jnp.where(
            jnp.asarray(stepped)[None, :],
            jnp.concatenate([theta0, theta0[-1:]]),
            jnp.concatenate([theta0[:1], mid, theta0[-1:]]),
        )
    cols = layout.knot_cols()
    knots = jnp.concatenate(
        [theta0, jnp.repeat(theta0[-1:], cols.shape[0] - theta0.shape[0], axis=0)]
    )
    z0 = jnp.zeros(layout.size).at[cols].set(knots)
    z0 = z0.at[layout.local_cols()[:, : layout.nx]].set(nodes0)
    # through the cache's kept programs: a later process skips tracing
    return kept_call(
        _fit,
        {"structure": structure, "max_iter": max_iter},
        {
            "problem": problem,
            "z0": z0,
            "active": active,
            "held": held,
            "rtol": np.asarray(rtol),
        },
    )
