"""Windowed parameters: a parameter layout on the output-error engine.

A `dp.Model`'s parameters may change along a long record: over a launch vehicle's
ascent the flight condition sweeps Mach 0.8 to 8, and the thesis estimates the
derivatives window by window (six per 0.5 s window, 966 unknowns for the Pegasus
first stage). Here the windows are a parameter layout of the one engine
(`_engine.py`): the record is cut into windows of `window` samples (the engine's
segments of a data [`Layout`][], simulated by its `segment_outputs`), `k`
consecutive windows form a shooting segment with its own node state, and the
unknowns are

    z = [per segment: node (nx), k knots x P] + [the knot after the last window (P)]

A segment's output residuals depend only on its own node and knots (and, with
parameters linear in time, the next segment's first knot), a continuity defect only
on two neighbouring segments; so the engine computes each segment's Jacobian block
exactly in one vmapped forward-mode call and solves the block normal equations.

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
from .._model import Model, Record
from ._engine import (
    AbstractLayout,
    coloured_information as _coloured_information,
    iteration_bound,
    Layout,
    RESULTS,
    segment_outputs,
    solve,
)
from ._oem import OEMProblem, theil_inequality


class WindowedFit(eqx.Module):
    """Result of [`fit_windowed`][].

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


class Windows(eqx.Module):
    """How a record is cut: `window` samples per parameter window, `per_segment`
    windows per shooting segment, `segments` segments (the last may hold padded
    windows), `n_windows` windows with data, `samples` in the record, and the
    continuity tolerance (relative to the model's state scale). All static."""

    window: int = eqx.field(static=True)
    per_segment: int = eqx.field(static=True)
    segments: int = eqx.field(static=True)
    n_windows: int = eqx.field(static=True)
    samples: int = eqx.field(static=True)
    continuity_tol: float = eqx.field(static=True, default=1e-4)

    @classmethod
    def make(cls, samples: int, window: int, node_interval: int, continuity_tol=1e-4):
        """Windows of `window` samples, a shooting node every `node_interval`
        samples (a multiple of `window`)."""
        if node_interval % window:
            raise ValueError(
                f"node_interval ({node_interval} samples) must be a multiple of the "
                f"parameter window ({window} samples)"
            )
        n_windows = -(-samples // window)
        k = node_interval // window
        return cls(window, k, -(-n_windows // k), n_windows, samples, continuity_tol)

    def node_samples(self) -> np.ndarray:
        """Sample index of every shooting node."""
        return np.arange(self.segments) * self.per_segment * self.window


def window_data(model: Model, record: Record, windows: Windows) -> Layout:
    """The record as the engine's data [`Layout`][] with one segment per window
    (padded windows after the record's end included): what the windowed layout
    simulates, window by window."""
    length, n = windows.window, len(record.t)
    first = np.arange(windows.segments * windows.per_segment) * length
    index = first[:, None] + np.arange(length)[None, :]
    scale = model.state_scale
    if scale is None:
        raise ValueError("a windowed fit needs the model's state_scale")
    put = jax.device_put
    return Layout(
        inputs=put(np.asarray(record.inputs, float)[None]),
        t0=put(np.array([record.t[0]], float)),
        dt=put(np.array([record.dt], float)),
        n=put(np.array([n])),
        record=put(np.zeros(len(first), int)),
        first=put(first),
        measured=put(record.measured[np.minimum(index, n - 1)]),
        valid=put(index < n),
        link=put(np.ones(len(first) - 1, bool)),
        scale=put(np.asarray(scale, float) * windows.continuity_tol),
        node_free=put(np.ones((len(first), len(model.states)), bool)),
        length=length,
        bias_channels=(),
    )


def _knot_cols(n_seg, k, nx, p, linear) -> np.ndarray:
    # `(knots, P)`: a block is `[node (nx), k knots x P]`, the tail the last knot
    nb = nx + k * p
    w = np.arange(n_seg * k + (1 if linear else 0))[:, None]
    i = np.arange(p)[None, :]
    inside = (w // k) * nb + nx + (w % k) * p + i
    return np.where(w < n_seg * k, inside, n_seg * nb + i)


def _local_cols(n_seg, k, nx, p, linear) -> np.ndarray:
    # `(S, nl)`: a segment's own block, then (linear) the next segment's first knot
    s = np.arange(n_seg)[:, None]
    own = s * (nx + k * p) + np.arange(nx + k * p)[None, :]
    if not linear:
        return own
    knots = _knot_cols(n_seg, k, nx, p, linear)
    return np.concatenate([own, knots[(s[:, 0] + 1) * k]], axis=1)


class _Layout(AbstractLayout):
    """The engine's layout for parameters per window: where each unknown lives in
    the flat vector `[blocks (S nb), tail (P)]`: a block is `[node (nx), k knots x
    P]`; with linear parameters the knot at the end of the last window is the tail.
    Carries the windows' data, the traced `active` window mask and the traced
    `held` mask (parameters held at their start per window).
    """

    data: Layout
    active: Bool[Array, " windows"]
    held: Bool[Array, "windows params"]
    measured: Float[Array, "segments length outputs"]
    valid: Bool[Array, "segments length"]
    link: Bool[Array, " links"]
    scale: Float[Array, " states"]
    free_params: tuple[bool, ...] = eqx.field(static=True)
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
        return _knot_cols(self.n_seg, self.k, self.nx, self.p, self.linear)

    def local_cols(self) -> np.ndarray:
        """`(S, nl)` columns of each segment's local vector `[block, next knot]`."""
        return _local_cols(self.n_seg, self.k, self.nx, self.p, self.linear)

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
        """Outputs of segment `s` (padded, `(k L, outputs)`) and its end state, from
        its local vector `v = [node, k knots, (next knot)]`: its windows one after
        another, each the engine's segment of the data layout."""
        del nx, p
        nx, k, p = self.nx, self.k, self.p
        knots = v[nx : nx + k * p].reshape(k, p)
        if self.linear:
            ends = jnp.concatenate([knots[1:], v[nx + k * p :][None]])
            ends = jnp.where(jnp.asarray(self.stepped)[None, :], knots, ends)
        else:
            ends = None

        def step(x, inp):
            j, th0, th1 = inp
            y, x_end = segment_outputs(
                model, self.data, s * k + j, x, th0, jnp.zeros(0), th1
            )
            return x_end, y

        x_end, ys = jax.lax.scan(step, v[:nx], (jnp.arange(k), knots, ends))
        return ys.reshape(k * self.data.length, -1), x_end

    def free_columns(self, free_params, nx, p):
        del free_params, nx, p
        knot_cols = self.knot_cols()
        free = np.ones(self.size, bool)
        free[knot_cols[self.used_knots() :].ravel()] = False
        free[knot_cols[:, ~np.asarray(self.free_params)].ravel()] = False
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
    model: Model, data: Layout, windows: Windows, active, held, stepped
) -> _Layout:
    n_seg, k = windows.segments, windows.per_segment
    per = k * windows.window
    # numpy: static shapes, so no small programs compiled per call
    index = np.arange(n_seg)[:, None] * per + np.arange(per)[None, :]
    in_window = np.minimum(index // windows.window, windows.n_windows - 1)
    measured = data.measured.reshape(n_seg, per, -1)
    return _Layout(
        data=data,
        active=active,
        held=held,
        measured=measured,
        valid=data.valid.reshape(n_seg, per) & active[in_window],
        link=jnp.ones(n_seg - 1, bool),
        scale=data.scale,
        free_params=tuple(bool(f) for f in model.free),
        n_seg=n_seg,
        nx=len(model.states),
        p=len(model.parameters),
        k=k,
        linear=not all(stepped),
        n_windows=windows.n_windows,
        stepped=stepped,
    )


@functools.partial(jax.jit, static_argnames=("model", "windows", "stepped", "max_iter"))
def _fit(model, windows, stepped, data, z0, active, held, rtol, max_iter):
    layout = _make_layout(model, data, windows, active, held, stepped)
    nx, p = layout.nx, layout.p
    sol = solve(
        model,
        layout,
        z0,
        jnp.asarray(model.free),
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
    outputs = sol.outputs.reshape(-1, sol.outputs.shape[-1])[: windows.samples]
    measured = layout.measured.reshape(-1, outputs.shape[-1])[: windows.samples]
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
        tic=theil_inequality(measured, outputs),
        defect=sol.defect * windows.continuity_tol,
        iterations=sol.iterations,
        converged=converged,
    )


def _stepped(linear, p: int) -> tuple[bool, ...]:
    if isinstance(linear, bool):
        linear = (linear,) * p
    if len(linear) != p:
        raise ValueError(f"linear has {len(linear)} entries for {p} parameters")
    return tuple(not bool(x) for x in linear)


def windowed_start(
    model: Model,
    windows: Windows,
    theta0: Float[Array, "windows params"],
    nodes0: Float[Array, "segments states"],
    linear: bool | tuple[bool, ...] = False,
) -> Float[Array, " unknowns"]:
    """The engine's starting unknowns from per-window parameters and node states
    (linear parameters' boundary knots start at the mean of the neighbouring
    windows' `theta0`). Pure: it runs under `jax.vmap`."""
    theta0 = jnp.asarray(theta0, float)
    stepped = _stepped(linear, theta0.shape[1])
    shape = (windows.segments, windows.per_segment, len(model.states))
    shape = (*shape, theta0.shape[1], not all(stepped))
    if not all(stepped):
        mid = 0.5 * (theta0[1:] + theta0[:-1])
        theta0 = jnp.where(
            jnp.asarray(stepped)[None, :],
            jnp.concatenate([theta0, theta0[-1:]]),
            jnp.concatenate([theta0[:1], mid, theta0[-1:]]),
        )
    cols = _knot_cols(*shape)
    knots = jnp.concatenate(
        [theta0, jnp.repeat(theta0[-1:], cols.shape[0] - theta0.shape[0], axis=0)]
    )
    size = windows.segments * (shape[2] + shape[1] * shape[3])
    z0 = jnp.zeros(size + (shape[3] if shape[4] else 0)).at[cols].set(knots)
    return z0.at[_local_cols(*shape)[:, : shape[2]]].set(jnp.asarray(nodes0, float))


def fit_windowed_data(
    model: Model,
    windows: Windows,
    data: Layout,
    z0: Float[Array, " unknowns"],
    *,
    linear: bool | tuple[bool, ...] = False,
    active: Bool[Array, " windows"],
    held: Bool[Array, "windows params"],
    rtol: float = 1e-5,
    max_iter: int | None = None,
) -> WindowedFit:
    """[`fit_windowed`][] on a prepared data layout ([`window_data`][]) and start
    ([`windowed_start`][]): pure and jitted, so `jax.vmap` batches it over the
    flights of a campaign."""
    stepped = _stepped(linear, len(model.parameters))
    # through the cache's kept programs: a later process skips tracing
    return kept_call(
        _fit,
        {
            # not `structure()`: the held parameters are part of the layout
            "model": model,
            "windows": windows,
            "stepped": stepped,
            "max_iter": iteration_bound(max_iter),
        },
        {
            "data": data,
            "z0": z0,
            "active": active,
            "held": held,
            "rtol": np.asarray(rtol),
        },
    )


def fit_windowed(
    model: Model,
    record: Record,
    theta0: Float[Array, "windows params"],
    nodes0: Float[Array, "segments states"],
    *,
    window: int,
    node_interval: int,
    continuity_tol: float = 1e-4,
    linear: bool | tuple[bool, ...] = False,
    active=None,
    held=None,
    rtol: float = 1e-5,
    max_iter: int | None = None,
) -> WindowedFit:
    """Multiple-shooting output error of `model` on `record` with its parameters per
    window (see the module).

    **Arguments:** `model` a [`Model`][] with a `state_scale` (its `fixed`
    parameters stay at their starting values in every window); `record` a
    [`Record`][]; `theta0` `(windows, params)` starting parameters per window;
    `nodes0` `(segments, states)` starting node states (usually the measured states
    at [`Windows.node_samples`][]), all estimated; `window` samples per parameter
    window; `node_interval` samples per shooting segment (a multiple of `window`);
    `continuity_tol` the allowed defect relative to the state scale; `linear`:
    parameters continuous and linear in time between window boundaries instead of
    constant per window (the boundary values start from the mean of the
    neighbouring windows' `theta0`), or one bool per parameter to mix the two;
    `active` `(windows,)` which windows are fitted (default all; an inactive
    window's samples are not used and its own knots stay at their starting values —
    with `linear` the knot it shares with an active neighbour is estimated, so
    report inactive windows as having no estimate); `held` `(windows, params)`
    parameters held at their starting values in a window (default none; a linear
    parameter's knot is estimated if an active window using it does not hold it);
    `rtol` the relative change of det(R) that ends the iteration; `max_iter` an
    iteration bound (default `None`: run to convergence, the engine's adaptive
    budget, whose bound only ends a fit that keeps creeping and says so).

    **Returns:** a [`WindowedFit`][].
    """
    record.check(model)
    windows = Windows.make(len(record.t), window, node_interval, continuity_tol)
    theta0 = jnp.asarray(theta0, float)
    nodes0 = jnp.asarray(nodes0, float)
    if theta0.shape != (windows.n_windows, len(model.parameters)):
        raise ValueError(
            f"theta0 {theta0.shape} must have one row per window "
            f"({windows.n_windows}) and one column per parameter "
            f"({len(model.parameters)})"
        )
    if nodes0.shape != (windows.segments, len(model.states)):
        raise ValueError(
            f"nodes0 {nodes0.shape} must have one row per shooting segment "
            f"({windows.segments}) and one column per state ({len(model.states)})"
        )
    active = (
        jnp.ones(windows.n_windows, bool)
        if active is None
        else jnp.asarray(active, bool)
    )
    held = jnp.zeros(theta0.shape, bool) if held is None else jnp.asarray(held, bool)
    if held.shape != theta0.shape:
        raise ValueError(
            f"held {held.shape} must have the shape of theta0 {theta0.shape}"
        )
    return fit_windowed_data(
        model,
        windows,
        window_data(model, record, windows),
        windowed_start(model, windows, theta0, nodes0, linear),
        linear=linear,
        active=active,
        held=held,
        rtol=rtol,
        max_iter=max_iter,
    )


class _VectorFunction(eqx.Module):
    """A function of a parameter vector as a `dp.Model` function of named ones."""

    fn: object = eqx.field(static=True)
    names: tuple[str, ...] = eqx.field(static=True)

    def __call__(self, *args):
        *head, p = args
        return self.fn(*head, jnp.stack([jnp.asarray(p[n], float) for n in self.names]))


def problem_model(problem: OEMProblem) -> tuple[Model, Record]:
    """An [`OEMProblem`][] as a [`Model`][] (parameters `p0, p1, ...`, states
    `x0, ...`, inputs `u0, ...`, outputs `y0, ...`) and its [`Record`][]."""
    n, n_out = problem.measured.shape
    nx = np.asarray(problem.state_scale).shape[0]
    names = tuple(f"p{i}" for i in range(len(problem.free)))
    model = Model(
        states=tuple(f"x{i}" for i in range(nx)),
        inputs=tuple(f"u{i}" for i in range(problem.inputs.shape[1])),
        outputs=tuple(f"y{i}" for i in range(n_out)),
        parameters=names,
        rates=_VectorFunction(problem.rates, names),
        observe=_VectorFunction(problem.outputs, names),
        fixed=tuple(nm for nm, f in zip(names, problem.free, strict=True) if not f),
        delays=None
        if problem.input_delay is None
        else _VectorFunction(problem.input_delay, names),
        state_scale=tuple(float(v) for v in np.asarray(problem.state_scale)),
    )
    t = float(problem.t0) + problem.dt * np.arange(n)
    record = Record(t, np.asarray(problem.inputs)[:n], np.asarray(problem.measured))
    return model, record


def fit_windowed_oem(
    problem: OEMProblem,
    theta0: Float[Array, "windows params"],
    nodes0: Float[Array, "segments states"],
    *,
    linear: bool | tuple[bool, ...] = False,
    active=None,
    held=None,
    rtol: float = 1e-5,
    max_iter: int | None = None,
) -> WindowedFit:
    """Deprecated: [`fit_windowed`][] on a `dp.Model` and a `dp.Record`. This
    form takes an [`OEMProblem`][] with `window`, `node_interval` and
    `state_scale` set (arguments as [`fit_windowed`][]'s) and converts it."""
    import warnings

    warnings.warn(
        "fit_windowed_oem(problem, ...) is deprecated: use "
        "diffpegasus.pegasus.fit_windowed(model, record, ...)",
        DeprecationWarning,
        stacklevel=2,
    )
    if problem.window is None or problem.node_interval is None:
        raise ValueError("fit_windowed_oem needs both window and node_interval")
    if problem.state_scale is None:
        raise ValueError("fit_windowed_oem needs the problem's state_scale")
    model, record = problem_model(problem)
    return fit_windowed(
        model,
        record,
        theta0,
        nodes0,
        window=problem.window,
        node_interval=problem.node_interval,
        continuity_tol=problem.continuity_tol,
        linear=linear,
        active=active,
        held=held,
        rtol=rtol,
        max_iter=max_iter,
    )
