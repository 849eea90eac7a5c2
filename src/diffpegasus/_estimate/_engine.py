"""The output-error engine: one structured Levenberg-Marquardt over a parameter layout.

Unknowns, in one flat vector `z = [nodes (S nx), theta (P), biases (R nb)]`:

- a state at the start of every shooting segment (`S` segments over all records; a
  record's first node is its initial state, held or estimated);
- the model parameters `theta`, shared by every record (a traced mask holds some);
- per record, a bias on each output listed in `biases`.

A segment's output residuals depend only on its own node, `theta` and its record's
biases, and a continuity defect `(x_end(s) - node(s + 1)) / (scale tol)` only on two
neighbouring nodes of the same record and `theta`. So each segment's Jacobian is
computed exactly (forward mode through its RK4 scan) with `nx + P + nb` tangents
in one vmapped call, and the normal equations are assembled from the blocks by index
maps. R is diagonal, re-estimated every iteration (the standard relaxation
of the det(R) cost); the step is Levenberg-Marquardt with damping raised tenfold until
the weighted cost falls and lowered tenfold after a success; the iteration stops when
det(R) changes by less than `rtol` relatively.

Why not `optimistix.LevenbergMarquardt` on the flat residual vector: optimistix
linearises the whole residual function, i.e. `S nx + P + R nb` tangents through every
segment instead of the `nx + P + nb` each segment depends on, and solves the dense
least squares by QR of the stacked Jacobian; with the relaxation of R between steps
it also needs an outer loop. The block form is `S` times less Jacobian work for
multiple shooting; the documentation's speed page has the measurement. The same structured step is
also an optimistix solver (`_solver.py`, [`BlockLevenbergMarquardt`][]): the same
iterates through `optx.least_squares`, measured against this loop in
`benchmarks/engine_vs_optimistix.py`.
"""

import abc
import dataclasses
import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from equinox import AbstractVar
from jaxtyping import Array, Bool, Float, Int

from .._model import Model
from .._rk4 import rk4_scan


class RESULTS(eqx.Enumeration):
    """Why a fit stopped."""

    successful = ""
    max_iterations = (
        "the fit did not converge within the iteration limit (raise max_iter, or "
        "check the model and start values)"
    )
    nonfinite = (
        "the model produced non-finite outputs or derivatives (a diverging "
        "simulation: try multiple shooting or other start values)"
    )
    slow_progress = (
        "the cost was still falling when the iteration budget ran out (raise "
        "max_iter / --max-iter, start nearer the optimum, e.g. from an "
        "equation-error fit, or hold poorly identified parameters)"
    )
    defects = (
        "the continuity defects between shooting segments did not close (shorten "
        "the shooting interval, give node guesses nearer the data, or raise "
        "max_iter / --max-iter)"
    )
    no_excitation = (
        "the information matrix is singular: the records do not excite some "
        "parameters, so their estimates are not unique (hold them, or fit records "
        "whose inputs move them)"
    )


# The adaptive budget's bound when no `max_iter` is given: the iteration stops when
# det(R) settles or no step lowers the cost; this only ends a fit that keeps
# creeping, and the result then says so.
MAX_ITER = 500


def iteration_bound(max_iter: int | None) -> int:
    """`max_iter` as the engine's loops take it: `None` is the adaptive budget,
    whose bound is `MAX_ITER`."""
    return MAX_ITER if max_iter is None else int(max_iter)


class AbstractLayout(eqx.Module):
    """Where the unknowns live and how a segment is simulated: what the engine needs
    of a parameter layout.

    The unknowns are one flat vector `z`. Each shooting segment `s` depends on a
    local vector `z[local_columns()[s]]` only, whose first `states` entries are its
    node state (`node_columns()[s]`); `segment(model, s, v)` gives its outputs
    `(length, outputs)` and its end state. Fields: `measured` `(segments, length,
    outputs)` and `valid` `(segments, length)`; `link` `(segments - 1,)`, whether
    segment `s` continues into `s + 1` (a continuity defect between them); `scale`
    `(states,)`, the state scale times the continuity tolerance.
    """

    measured: AbstractVar[Float[Array, "segments length outputs"]]
    valid: AbstractVar[Bool[Array, "segments length"]]
    link: AbstractVar[Bool[Array, " links"]]
    scale: AbstractVar[Float[Array, " states"]]

    @property
    def n_segments(self) -> int:
        return self.measured.shape[0]

    @abc.abstractmethod
    def local_columns(self, nx: int, p: int) -> Int[Array, "segments local"]:
        """Global column of every entry of each segment's local vector."""

    @abc.abstractmethod
    def node_columns(self, nx: int, p: int) -> Int[Array, "segments states"]:
        """Global columns of each segment's node state."""

    @abc.abstractmethod
    def segment(self, model, s, v, nx: int, p: int):
        """Outputs `(length, outputs)` and end state `(states,)` of segment `s`
        from its local vector `v`."""

    @abc.abstractmethod
    def free_columns(self, free_params, nx: int, p: int) -> Bool[Array, " unknowns"]:
        """Which unknowns are estimated, given the model parameters' mask."""


class Layout(AbstractLayout):
    """The data of a fit, cut into shooting segments of `length` samples.

    **Fields:** `inputs` `(records, samples, inputs)` padded with the last row to
    whole segments; `t0`, `dt`, `n` per record (s, s, samples); per segment
    `record`, `first` (sample index in its record), `measured` `(segments, length,
    outputs)`, `valid` `(segments, length)`; `link` `(segments - 1,)` whether
    segment `s` continues into `s + 1`; `scale` `(states,)` state scale times the
    continuity tolerance; `node_free` `(segments, states)`; `length` and
    `bias_channels` (output indices with a per-record bias) are static.
    """

    inputs: Float[Array, "records samples inputs"]
    t0: Float[Array, " records"]
    dt: Float[Array, " records"]
    n: Int[Array, " records"]
    record: Int[Array, " segments"]
    first: Int[Array, " segments"]
    measured: Float[Array, "segments length outputs"]
    valid: Bool[Array, "segments length"]
    link: Bool[Array, " links"]
    scale: Float[Array, " states"]
    node_free: Bool[Array, "segments states"]
    length: int = eqx.field(static=True)
    bias_channels: tuple[int, ...] = eqx.field(static=True)

    @property
    def n_records(self) -> int:
        return self.t0.shape[0]

    def local_columns(self, nx, p):
        return _columns(self, nx, p)[1]

    def node_columns(self, nx, p):
        return _columns(self, nx, p)[0]

    def segment(self, model, s, v, nx, p):
        return segment_outputs(model, self, s, v[:nx], v[nx : nx + p], v[nx + p :])

    def free_columns(self, free_params, nx, p):
        del p
        nb = len(self.bias_channels)
        return jnp.concatenate(
            [
                self.node_free.reshape(-1),
                free_params,
                jnp.ones(self.n_records * nb, bool),
            ]
        )


def _input_at(layout: Layout, r, t, delay):
    """Known inputs of record `r` at time `t` (s), linearly interpolated, each
    delayed by `delay` `(inputs,)` or not (None)."""
    u = layout.inputs[r]
    x = (t - layout.t0[r]) / layout.dt[r]
    if delay is not None:
        x = x - delay / layout.dt[r]
    i = jnp.clip(jnp.floor(x), 0, layout.n[r] - 2).astype(int)
    frac = jnp.clip(x - i, 0.0, 1.0)
    if delay is None:
        return u[i] * (1 - frac) + u[i + 1] * frac
    cols = jnp.arange(u.shape[1])
    return u[i, cols] * (1 - frac) + u[i + 1, cols] * frac


def _sampled_inputs(layout: Layout, s):
    """Known inputs of segment `s` at its samples and one beyond, `(length + 1,
    inputs)`, the record's last sample held past its end."""
    r = layout.record[s]
    idx = layout.first[s] + jnp.arange(layout.length + 1)
    return layout.inputs[r][jnp.clip(idx, 0, layout.n[r] - 1)]


def segment_solve(model: Model, layout: Layout, s, node, theta, theta_end=None):
    """States at segment `s`'s samples and one step beyond, `(length + 1, states)`,
    and their times: classical RK4 at the record's sample step (the middle stages
    see the inputs averaged over the step, as flight-test codes do). With
    `theta_end` the parameters change linearly in time from `theta` at the
    segment's start to `theta_end` one segment later (a parameter layout's
    derivatives that follow the flight condition, see `_windowed.py`).

    A `lax.scan`, not `diffrax.diffeqsolve`: on the HFB-320 fit the scan compiles in
    half the time and runs twice as fast; the tests check it against diffrax's
    solve with the same tableau ([`RK4`][])."""
    r = layout.record[s]
    dt = layout.dt[r]
    t_start = layout.t0[r] + layout.first[s] * dt
    ts = t_start + dt * jnp.arange(layout.length + 1)
    at = _parameters_at(theta, theta_end, t_start, layout.length * dt)
    delay = model.input_delays(theta)
    if delay is None:
        # inputs at the samples, looked up once rather than at every stage
        u = _sampled_inputs(layout, s)
        return rk4_scan(lambda t, x, u_: model.f(t, x, u_, at(t)), node, ts, dt, u), ts

    def field(t, x):
        return model.f(t, x, _input_at(layout, r, t, delay), at(t))

    return rk4_scan(field, node, ts, dt), ts


def _parameters_at(theta, theta_end, t_start, span):
    """The parameters as a function of time: `theta`, or linear from `theta` at
    `t_start` to `theta_end` at `t_start + span`."""
    if theta_end is None:
        return lambda t: theta
    return lambda t: theta + (theta_end - theta) * ((t - t_start) / span)


def segment_outputs(model: Model, layout: Layout, s, node, theta, bias, theta_end=None):
    """Model outputs of segment `s` `(length, outputs)` (record biases `bias`
    `(nb,)` added) and its end state `(states,)`; `theta_end` as in
    [`segment_solve`][]."""
    xs, ts = segment_solve(model, layout, s, node, theta, theta_end)
    r = layout.record[s]
    delay = model.input_delays(theta)
    if delay is None:
        u = _sampled_inputs(layout, s)[:-1]
    else:
        u = jax.vmap(lambda t: _input_at(layout, r, t, delay))(ts[:-1])
    at = _parameters_at(theta, theta_end, ts[0], layout.length * layout.dt[r])
    ys = jax.vmap(lambda t, x, u_: model.g(t, x, u_, at(t)))(ts[:-1], xs[:-1], u)
    if layout.bias_channels:
        ys = ys.at[:, jnp.asarray(layout.bias_channels)].add(bias[None, :])
    return ys, xs[-1]


def _columns(layout: Layout, nx, p):
    """Global column of each segment's local unknowns `[node, theta, bias]`."""
    n_seg, nb = layout.n_segments, len(layout.bias_channels)
    node = jnp.arange(n_seg)[:, None] * nx + jnp.arange(nx)[None, :]
    par = n_seg * nx + jnp.arange(p)
    bias = n_seg * nx + p + layout.record[:, None] * nb + jnp.arange(nb)[None, :]
    return node, jnp.concatenate(
        [node, jnp.broadcast_to(par, (n_seg, p)), bias], axis=1
    )


def _scatter(h, g, cols, jac, res):
    """Add `J^T J` and `J^T r` of local blocks `jac` `(S, rows, k)`, `res` `(S,
    rows)` at global columns `cols` `(S, k)`; shared columns accumulate."""
    hh = jnp.einsum("sra,srb->sab", jac, jac)
    gg = jnp.einsum("sra,sr->sa", jac, res)
    h = h.at[cols[:, :, None], cols[:, None, :]].add(hh)
    g = g.at[cols].add(gg)
    return h, g


@functools.partial(jax.jit, static_argnames=("model", "nx", "p"))
def _segment(model, layout, s, v, nx, p):
    # jitted so that Python traces the model once per solve: vmap, jvp and the
    # several call sites below transform the cached jaxpr instead of retracing
    return layout.segment(model, s, v, nx, p)


def residuals_at(model, layout: AbstractLayout, z, nx, p):
    """Output residuals `(S, length, outputs)` (0 at padding), defects `(S - 1,
    states)` (0 where segments do not link) and model outputs, at the unknowns `z`."""
    local = layout.local_columns(nx, p)
    nodes = layout.node_columns(nx, p)
    ys, ends = jax.vmap(lambda s, cols: _segment(model, layout, s, z[cols], nx, p))(
        jnp.arange(layout.n_segments), local
    )
    e = jnp.where(layout.valid[..., None], layout.measured - ys, 0.0)
    d = (ends[:-1] - z[nodes[1:]]) / layout.scale[None, :]
    d = jnp.where(layout.link[:, None], d, 0.0)
    return e, d, ys


class Evaluation(eqx.Module):
    """The model at one point `z` of the unknowns: output residuals `e` `(S, length,
    outputs)` (0 at padding), continuity defects `d` `(S - 1, states)` (0 where
    segments do not link), model outputs `ys` `(S, length, outputs)`, and their
    Jacobians in each segment's local unknowns: `jy` `(S, length, outputs, local)`
    of the outputs, `jx` `(S, states, local)` of the segment's end state."""

    e: Float[Array, "segments length outputs"]
    d: Float[Array, "links states"]
    ys: Float[Array, "segments length outputs"]
    jy: Float[Array, "segments length outputs local"]
    jx: Float[Array, "segments states local"]


def evaluate(model, layout: AbstractLayout, z, nx, p) -> Evaluation:
    """Residuals, defects, model outputs and their Jacobians at `z`: one
    forward-mode pass per segment, in its local unknowns only, gives both the values
    and the Jacobian."""
    local = layout.local_columns(nx, p)
    node_cols = layout.node_columns(nx, p)

    def block(s, cols):
        def f(v):
            out = _segment(model, layout, s, v, nx, p)
            return out, out

        return jax.jacfwd(f, has_aux=True)(z[cols])

    (jy, jx), (ys, ends) = jax.vmap(block)(jnp.arange(layout.n_segments), local)
    e = jnp.where(layout.valid[..., None], layout.measured - ys, 0.0)
    d = (ends[:-1] - z[node_cols[1:]]) / layout.scale[None, :]
    d = jnp.where(layout.link[:, None], d, 0.0)
    return Evaluation(e=e, d=d, ys=ys, jy=jy, jx=jx)


def assemble(layout: AbstractLayout, ev: Evaluation, n, nx, p, r):
    """Normal matrix `(n, n)` (`n` unknowns) and gradient of the R-weighted least
    squares from an [`Evaluation`][], with the whitened output Jacobian `(S, length,
    outputs, local)` and whitened output residuals `(S, length, outputs)`."""
    local = layout.local_columns(nx, p)
    node_cols = layout.node_columns(nx, p)
    w = 1.0 / jnp.sqrt(r)
    # residual = measured - model: its Jacobian is minus the model's; padded samples
    # are masked with where (their values may be non-finite, and 0 * nan is nan)
    jyw = jnp.where(layout.valid[..., None, None], -ev.jy * w[None, None, :, None], 0.0)
    ew = ev.e * w[None, None, :]
    h, g = jnp.zeros((n, n)), jnp.zeros(n)
    k = local.shape[1]
    n_seg = layout.n_segments
    h, g = _scatter(h, g, local, jyw.reshape(n_seg, -1, k), ew.reshape(n_seg, -1))
    if n_seg > 1:
        link = layout.link[:, None, None]
        jd = jnp.where(link, ev.jx[:-1] / layout.scale[None, :, None], 0.0)
        minus = jnp.where(link, -jnp.eye(nx)[None] / layout.scale[None, :, None], 0.0)
        h, g = _scatter(
            h,
            g,
            jnp.concatenate([local[:-1], node_cols[1:]], axis=1),
            jnp.concatenate([jd, minus], axis=2),
            ev.d,
        )
    return h, g, jyw, ew


def linearise(model, layout: AbstractLayout, z, nx, p, r):
    """Normal matrix and gradient of the R-weighted least squares at `z`, with the
    whitened output Jacobian `(S, length, outputs, local)`, whitened output
    residuals, output residuals `(S, length, outputs)`, defects and model outputs
    ([`evaluate`][] then [`assemble`][])."""
    ev = evaluate(model, layout, z, nx, p)
    h, g, jyw, ew = assemble(layout, ev, z.shape[0], nx, p, r)
    return h, g, jyw, ew, ev.e, ev.d, ev.ys


def _cost(e, d, r):
    # the R-weighted least-squares cost of output residuals `e` and defects `d`
    return jnp.sum(e**2 / r[None, None, :]) + jnp.sum(d**2)


def weighted_cost(model, layout, z, nx, p, r):
    """The R-weighted least-squares cost at `z`, with the output residuals, defects
    and model outputs."""
    e, d, ys = residuals_at(model, layout, z, nx, p)
    return _cost(e, d, r), e, d, ys


def lm_step(h, g, free, damping):
    """Levenberg-Marquardt step `(H + damping diag(H)) step = -g` (scaled to unit
    diagonal), columns not `free` held at zero step; `damping = 0` is Gauss-Newton."""
    m = free.astype(h.dtype)
    hm = h * m[:, None] * m[None, :] + jnp.diag(1.0 - m)
    scale = jnp.sqrt(jnp.clip(jnp.diag(hm), 1e-300))
    hs = hm / scale[:, None] / scale[None, :]
    hs = hs + (damping + 1e-12) * jnp.eye(h.shape[0])
    step = jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(hs), -g * m / scale)
    return step / scale * m


def damped_step(h, g, free, z, damping, j0, cost_at, guess, active=None, correct=None):
    """The Levenberg-Marquardt damping search from `z`: an [`lm_step`][] at
    `damping`, then the damping raised tenfold (from at least 1e-8) until the cost
    falls below `j0` or the damping reaches 1e8; `active` (traced bool, optional)
    False evaluates nothing.

    **Arguments:** `cost_at(new) -> (cost, *extras)` the trial's cost and what the
    caller keeps of it; `guess` the extras' values (shapes) before any trial;
    `correct(step, damping) -> (step, ok)` (optional) what the trial takes instead
    of the step, a trial not `ok` rejected as one whose cost did not fall.

    **Returns:** `(damping, new, cost, extras, accepted)`: `new` is `z` where no
    trial lowered the cost, `cost` and `extras` those of the last trial.
    """

    def trial(c):
        lam = jnp.where(c[1], jnp.maximum(10.0 * c[0], 1e-8), c[0])
        if correct is None:
            new = z + lm_step(h, g, free, lam)
            return (lam, jnp.array(True), new, *cost_at(new))
        step, ok = correct(lm_step(h, g, free, lam), lam)
        new = z + step
        cost, *extras = cost_at(new)
        return (lam, jnp.array(True), new, jnp.where(ok, cost, jnp.inf), *extras)

    def again(c):
        lam, tried, _, j1 = c[:4]
        go = ~tried | (~(j1 < j0) & (lam < 1e8))
        return go if active is None else active & go

    start = (damping, jnp.array(False), z, jnp.array(jnp.inf), *guess)
    damping, _, new, j1, *extras = jax.lax.while_loop(again, trial, start)
    accepted = j1 < j0
    return damping, jnp.where(accepted, new, z), j1, extras, accepted


class Iterate(eqx.Module):
    """What an iteration of [`solve`][] (or of the optimistix solver's loop) leaves
    for [`finish`][]: the unknowns `z`, R `(outputs,)` and its determinant `cost`,
    `iterations`, whether it is `done` or `broken` (non-finite normal equations),
    the last linearisation (`information` `(unknowns, unknowns)`, the whitened
    output Jacobian `jacobian` and residuals `whitened`, and, where the loop keeps
    it, the `gradient` `(unknowns,)`), the accepted point's continuity `defects`
    `(segments - 1, states)` and model `outputs` `(S, length, outputs)`, and the
    last relative `change` of the cost."""

    z: Float[Array, " unknowns"]
    r: Float[Array, " outputs"]
    cost: Float[Array, ""]
    iterations: Int[Array, ""]
    done: Bool[Array, ""]
    broken: Bool[Array, ""]
    information: Float[Array, "unknowns unknowns"]
    jacobian: Float[Array, "segments length outputs local"]
    whitened: Float[Array, "segments length outputs"]
    defects: Float[Array, "links states"]
    outputs: Float[Array, "segments length outputs"]
    change: Float[Array, ""]
    gradient: Float[Array, " unknowns"] | None = None


def first_iterate(layout, z0, r0, cost0, broken0, outputs0, nx, p) -> Iterate:
    """The [`Iterate`][] before the first iteration: the linearisation and the
    defects zero, `outputs0` `(S, length, outputs)`."""
    n, shape = z0.shape[0], layout.measured.shape
    k = layout.local_columns(nx, p).shape[1]
    return Iterate(
        z=z0,
        r=r0,
        cost=cost0,
        iterations=jnp.array(0),
        done=jnp.array(False),
        broken=broken0,
        information=jnp.zeros((n, n)),
        jacobian=jnp.zeros((*shape, k)),
        whitened=jnp.zeros(shape),
        defects=jnp.zeros((layout.n_segments - 1, nx)),
        outputs=outputs0,
        change=jnp.array(jnp.inf),
    )


def channel_variance(layout, e):
    """Diagonal of R: mean square residual per output over the valid samples."""
    return jnp.sum(e**2, axis=(0, 1)) / jnp.sum(layout.valid)


class Linearisation(eqx.Module):
    """The R-weighted least squares linearised at the point a fit stopped at: the
    normal matrix `normal` `(unknowns, unknowns)` and `gradient` `(unknowns,)` over
    every unknown (held ones too), the whitened output Jacobian `jacobian` `(S,
    length, outputs, local)`, the whitened output residuals `whitened` `(S, length,
    outputs)` and the continuity `defects` `(S - 1, states)`: what a score test of
    held parameters at the fit needs, without evaluating the model again."""

    normal: Float[Array, "unknowns unknowns"]
    gradient: Float[Array, " unknowns"]
    jacobian: Float[Array, "segments length outputs local"]
    whitened: Float[Array, "segments length outputs"]
    defects: Float[Array, "links states"]


class Solution(eqx.Module):
    """The raw result of [`solve`][] (the front end [`fit`][] wraps it).

    **Fields:** `z` the unknowns; `R` `(outputs,)`; `cost` det(R); `iterations`;
    `result` a [`RESULTS`][] code; `covariance` of `z` (the inverse Fisher
    information, zero rows and columns for held unknowns); `corrected` the same with
    the Morelli-Klein correction for coloured residuals (over `theta` and biases
    only, 0 elsewhere); `outputs` `(S, length, outputs)`; `defect` the largest
    continuity defect relative to the state scale; `linearisation` the
    `Linearisation` at `z` (from `solve`; `None` from a loop whose last
    linearisation is at the start of its last step).
    """

    z: Float[Array, " unknowns"]
    R: Float[Array, " outputs"]
    cost: Float[Array, ""]
    iterations: Int[Array, ""]
    result: RESULTS
    covariance: Float[Array, "unknowns unknowns"]
    corrected: Float[Array, "unknowns unknowns"]
    outputs: Float[Array, "segments length outputs"]
    defect: Float[Array, ""]
    jacobian: Float[Array, "segments length outputs local"]
    whitened: Float[Array, "segments length outputs"]
    information: Float[Array, "unknowns unknowns"]
    change: Float[Array, ""]
    linearisation: Linearisation | None = None


def _print_progress(it, cost, change, damping, defect):
    import sys

    print(
        f"iteration {int(it):4d}: det(R) {float(cost):.6e}, relative change "
        f"{float(change):.2e}, damping {float(damping):.1e}, largest defect "
        f"{float(defect):.3g}",
        file=sys.stderr,
        flush=True,
    )


# geodesic acceleration: the finite-difference step (a share of the step) for the
# residuals' second directional derivative, and the largest 2 |a| / |v| accepted
# (Transtrum and Sethna's values)
ACCELERATION_STEP = 0.1
ACCELERATION_RATIO = 0.75


def accelerated(model, layout, ev, z, h, free, r, nx, p):
    """`correct(v, damping) -> (v + a/2, ok)` for [`damped_step`][]: Levenberg-
    Marquardt with geodesic acceleration (Transtrum and Sethna 2012). At a trial
    step `v` the residuals' (outputs' and defects') second directional derivative
    `r_vv` comes from one more evaluation at `z + h v` (`h` =
    `ACCELERATION_STEP`), `(2/h) ((r(z + h v) - r(z)) / h - J v)`; the acceleration
    `a` solves the step's damped normal equations with `J' W r_vv` for the
    gradient. The trial is `z + v + a/2`, `ok` where `2 |a| / |v|` (scaled as the
    step) is at most `ACCELERATION_RATIO`. It follows a valley that bends (a
    parameter combination the data pin down moving with one they barely do) in
    steps the straight one could not take: there the straight step's cost rises
    and the damping cuts it to a sliver of the way."""
    n = z.shape[0]
    local = layout.local_columns(nx, p)
    nodes = layout.node_columns(nx, p)
    m = free.astype(h.dtype)
    scale = jnp.sqrt(jnp.clip(jnp.diag(h * m[:, None] * m[None, :]) + 1.0 - m, 1e-300))
    step = ACCELERATION_STEP

    def correct(v, damping):
        e_h, d_h, _ = residuals_at(model, layout, z + step * v, nx, p)
        vl = v[local]  # (S, local)
        # e = measured - model: its derivative along v is minus the model's
        jv = -jnp.einsum("slok,sk->slo", ev.jy, vl)
        rvv = 2.0 / step * ((e_h - ev.e) / step - jv)
        rvv = jnp.where(layout.valid[..., None], rvv, 0.0)
        jd = (jnp.einsum("sik,sk->si", ev.jx[:-1], vl[:-1]) - v[nodes[1:]]) / (
            layout.scale[None, :]
        )
        dvv = 2.0 / step * ((d_h - ev.d) / step - jd)
        dvv = jnp.where(layout.link[:, None], dvv, 0.0)
        curved = dataclasses.replace(ev, e=rvv, d=dvv)
        _, gvv, _, _ = assemble(layout, curved, n, nx, p, r)
        a = lm_step(h, gvv, free, damping)
        ratio = 2.0 * jnp.linalg.norm(a * scale) / jnp.linalg.norm(v * scale)
        return v + 0.5 * a, ratio <= ACCELERATION_RATIO

    return correct


@functools.partial(
    jax.jit,
    static_argnames=("model", "nx", "p", "coloured", "progress", "acceleration"),
)
def solve(
    model,
    layout,
    z0,
    free_params,
    *,
    nx,
    p,
    rtol,
    max_iter,
    coloured=True,
    progress=False,
    acceleration=False,
) -> Solution:
    """Minimise det(R) over the free unknowns from `z0`. Pure and jitted; vmap
    batches it over layouts of one shape. `coloured=False` skips the coloured-
    residual covariance of the unknowns after the first `S nx` (`corrected` is then
    0; a layout whose unknowns are ordered otherwise corrects its own, from
    `jacobian` and `whitened`).

    The program holds the model twice: once with its Jacobian ([`evaluate`][], at
    the point an iteration starts from) and once without (`weighted_cost`, the
    damping's trials, the cheap evaluation a rejected trial costs). The start's R
    comes from the first Jacobian pass's residuals rather than from a third copy.
    After the last accepted step one more pass linearises at the point the fit
    stopped at (`Solution.linearisation`): the covariances are the optimum's, and
    a score test of held parameters reuses it instead of compiling the model's
    Jacobian again.

    `progress` prints one line per iteration to standard error (a host callback:
    that program does not enter JAX's persistent cache, so it is off by default);
    `Solution.change` is the last iteration's relative change of det(R), which says
    whether a fit that ran out of iterations was still making progress.

    `acceleration` takes each step with geodesic acceleration ([`accelerated`][]):
    the same optimum where a valley bends, in a fraction of the steps. Off, the
    program is the plain Levenberg-Marquardt's, unchanged."""
    free = layout.free_columns(free_params, nx, p)
    n, n_out = z0.shape[0], layout.measured.shape[-1]

    def body(carry):
        state, damping, first, _ = carry
        z, r, cost_prev, it = state.z, state.r, state.cost, state.iterations
        ev = evaluate(model, layout, z, nx, p)
        r = jnp.where(first, channel_variance(layout, ev.e), r)
        cost_prev = jnp.where(first, jnp.prod(r), cost_prev)
        h, g, jyw, ew = assemble(layout, ev, n, nx, p, r)
        j0 = _cost(ev.e, ev.d, r)
        # a converged (or exhausted) iteration ends with one more pass that only
        # linearises, at the point it stopped at; max_iter = 0: the start is
        # evaluated (R, outputs, statistics), not moved
        active = (it < max_iter) & ~state.done
        damping, new, _, (e1, d1, ys1), accepted = damped_step(
            h,
            g,
            free,
            z,
            damping,
            j0,
            lambda new: weighted_cost(model, layout, new, nx, p, r),
            (ev.e, ev.d, ev.ys),
            active,
            **(
                {"correct": accelerated(model, layout, ev, z, h, free, r, nx, p)}
                if acceleration
                else {}
            ),
        )
        r_new = jnp.where(accepted, channel_variance(layout, e1), r)
        cost = jnp.prod(r_new)
        # det(R) = 0: a channel reproduced to the last bit (noise-free data), nothing
        # left to fit, and its weight would be infinite in the next linearisation
        small = (jnp.abs(cost_prev - cost) <= rtol * jnp.abs(cost)) | (cost == 0)
        # no decrease at any damping: the minimum if the normal equations are
        # finite, a failure (e.g. a diverged segment) if not
        broken = ~(jnp.all(jnp.isfinite(h)) & jnp.all(jnp.isfinite(g)))
        broken = broken | ~jnp.all(jnp.isfinite(r))
        stepped = active | first
        # the pass that only linearises cannot break a fit that stopped well: where
        # it is not finite (R reproduced to the last bit on noise-free data gives
        # infinite weights) the linearisation the last step started from is kept
        kept = ~stepped & broken
        broken = jnp.where(stepped, broken, state.broken)
        h, g = jnp.where(kept, state.information, h), jnp.where(kept, state.gradient, g)
        jyw = jnp.where(kept, state.jacobian, jyw)
        ew = jnp.where(kept, state.whitened, ew)
        done = jnp.where(stepped, small | ~accepted | broken, state.done)
        change = jnp.where(
            stepped, jnp.abs(cost_prev - cost) / jnp.abs(cost), state.change
        )
        if progress:
            defect = jnp.max(jnp.abs(jnp.where(accepted, d1, ev.d)), initial=0.0)
            jax.lax.cond(
                active,
                lambda: jax.debug.callback(
                    _print_progress, it + 1, cost, change, damping, defect
                ),
                lambda: None,
            )
        # the loop carries the linearisation at the point it stopped at (the
        # statistics and the score test need no other copy of the Jacobian
        # program): a pass without a step, or a step no damping made, leaves it
        # there; an accepted step is followed by another pass
        linearised = ~active | ~accepted | broken
        state = Iterate(
            z=new,
            r=r_new,
            cost=cost,
            iterations=it + active,
            done=done,
            broken=broken,
            information=h,
            jacobian=jyw,
            whitened=ew,
            defects=jnp.where(accepted, d1, ev.d),
            outputs=jnp.where(accepted, ys1, ev.ys),
            change=change,
            gradient=g,
        )
        return state, damping / 10.0, jnp.array(False), linearised

    start = first_iterate(
        layout,
        z0,
        jnp.ones(n_out),
        jnp.array(jnp.inf),
        jnp.array(False),
        jnp.zeros(layout.measured.shape),
        nx,
        p,
    )
    start = dataclasses.replace(start, gradient=jnp.zeros(n))
    state, _, _, _ = jax.lax.while_loop(
        lambda c: ~c[3],
        body,
        (start, jnp.array(0.0), jnp.array(True), jnp.array(False)),
    )
    return finish(layout, state, free, nx=nx, p=p, coloured=coloured)


def finish(layout, state: Iterate, free, *, nx, p, coloured) -> Solution:
    """The [`Solution`][] of a finished iteration ([`Iterate`][]): the covariances
    from its last normal matrix and whitened Jacobian and residuals, the largest
    defect, the result code (shared by [`solve`][] and the optimistix solver's
    loop)."""
    h, jyw, ew = state.information, state.jacobian, state.whitened
    m = free.astype(h.dtype)
    hm = h * m[:, None] * m[None, :] + jnp.diag(1.0 - m)
    cov = jnp.linalg.inv(hm) * m[:, None] * m[None, :]
    ns = layout.n_segments * nx
    corrected = jnp.zeros_like(cov)
    if coloured:
        tail = coloured_covariance(layout, jyw, ew, cov[:, ns:], nx, p)
        corrected = corrected.at[ns:, ns:].set(tail)
    defect = jnp.max(jnp.abs(state.defects), initial=0.0) * 1.0
    finite = jnp.isfinite(state.cost) & jnp.all(jnp.isfinite(state.z)) & ~state.broken
    result = RESULTS.where(
        finite,
        RESULTS.where(state.done, RESULTS.successful, RESULTS.max_iterations),
        RESULTS.nonfinite,
    )
    return Solution(
        z=state.z,
        R=state.r,
        cost=state.cost,
        iterations=state.iterations,
        result=result,
        covariance=cov,
        corrected=corrected,
        outputs=state.outputs,
        defect=defect,
        jacobian=jyw,
        whitened=ew,
        information=hm * m[:, None] * m[None, :],
        change=state.change,
        linearisation=None
        if state.gradient is None
        else Linearisation(
            normal=h,
            gradient=state.gradient,
            jacobian=jyw,
            whitened=ew,
            defects=state.defects,
        ),
    )


def explain(
    code,
    *,
    information,
    free,
    names,
    iterations: int,
    change: float,
    defect: float | None = None,
) -> tuple[RESULTS, str]:
    """Why a fit stopped, on the host: the [`RESULTS`][] item and a sentence that
    names what went wrong and what to try ("" when it converged).

    **Arguments:** `code` the solve's result; `information` `(unknowns,
    unknowns)` the outputs' information about the unknowns that can be named
    (parameters, biases, intensities: `A^T A` of the whitened residuals'
    Jacobian in those columns); `free` `(unknowns,)`; `names` a name per
    unknown (`None` for one not worth naming); `iterations`; `change` the last
    relative change of the cost; `defect` the largest continuity defect relative
    to its tolerance (`None` without multiple shooting).

    A fit whose information is numerically singular (an eigenvalue of the
    unit-diagonal information below the rounding of its largest, numpy's rank
    rule) is reported as `no_excitation`, naming the parameters of the null
    direction: their estimates are not unique.
    """
    code = int(np.asarray(code._value))
    if code == int(np.asarray(RESULTS.nonfinite._value)):
        return RESULTS.nonfinite, (
            f"{RESULTS[RESULTS.nonfinite]} (at iteration {iterations})"
        )
    singular = _unexcited(np.asarray(information), np.asarray(free), names)
    if singular:
        return RESULTS.no_excitation, (
            f"the information matrix is singular for {', '.join(singular)}: the "
            "records do not excite them, so their estimates are not unique (hold "
            "some of them, or fit records whose inputs move them)"
        )
    if code == int(np.asarray(RESULTS.successful._value)):
        return RESULTS.successful, ""
    if defect is not None and defect > 1.0:
        return RESULTS.defects, (
            f"after {iterations} iterations the largest continuity defect is "
            f"{defect:.3g} times its tolerance: {RESULTS[RESULTS.defects]}"
        )
    return RESULTS.slow_progress, (
        f"after {iterations} iterations det(R) still changed by {change:.2g} "
        f"(relatively) per iteration: {RESULTS[RESULTS.slow_progress]}"
    )


def _unexcited(information, free, names) -> list[str]:
    """Names of the free unknowns in the numerically null directions of the
    information (an unknown with no information at all is named alone)."""
    idx = np.flatnonzero(free)
    if idx.size == 0 or not np.all(np.isfinite(information)):
        return []
    h = information[np.ix_(idx, idx)]
    diag = np.diag(h)
    out = [
        names[i]
        for i, d in zip(idx, diag, strict=True)
        if d <= 0 and names[i] is not None
    ]
    live = diag > 0
    if np.sum(live) > 1:
        d = np.sqrt(diag[live])
        hs = h[np.ix_(live, live)] / np.outer(d, d)
        w, v = np.linalg.eigh(hs)
        tol = w.max() * hs.shape[0] * np.finfo(float).eps
        cols = idx[live]
        for k in np.flatnonzero(w <= tol):
            vec = np.abs(v[:, k])
            for j in np.flatnonzero(vec >= 0.25 * vec.max()):
                name = names[cols[j]]
                if name is not None and name not in out:
                    out.append(name)
    return out


def row_jacobian(layout, jyw, cols, nx, p):
    """Whitened output Jacobian rows times `cols` `(unknowns, k)`: `(rows, outputs,
    k)`, segments in order."""
    picked = cols[layout.local_columns(nx, p)]  # (S, local, k)
    out = jnp.einsum("snoa,sak->snok", jyw, picked)
    return out.reshape(-1, out.shape[2], out.shape[3])


def coloured_information(jw, vw, samples=None):
    """Sum over lags of residual autocorrelation times Jacobian cross-correlation,
    per output channel (Morelli and Klein's correction), by FFT.

    `jw`: `(rows, outputs, k)` whitened Jacobian rows; `vw`: `(rows, outputs)`
    whitened residuals, both zero on padding rows. `samples`: how many rows are
    samples (the residuals' autocovariance is their sum of lagged products over
    this count); default every row. Returns `(k, k)`.
    """
    n = jw.shape[0]
    m = 2 * n
    a = jnp.fft.fft(jw, n=m, axis=0)
    v = jnp.fft.fft(vw, n=m, axis=0)
    power = jnp.abs(v) ** 2 / (n if samples is None else samples)
    total = jnp.einsum("fo,fop,foq->pq", power, jnp.conj(a), a) / m
    return jnp.real(total)


def coloured_covariance(layout, jyw, ew, cov_cols, nx, p):
    """`K^T Sigma K` with `K = J cov[:, cols]` and Sigma the residuals'
    autocovariance per output: the covariance corrected for coloured residuals."""
    k = row_jacobian(layout, jyw, cov_cols, nx, p)
    # the padding rows (zero) are no samples: the autocovariance is over the valid ones
    samples = jnp.sum(layout.valid)
    return coloured_information(k, ew.reshape(-1, ew.shape[-1]), samples)
