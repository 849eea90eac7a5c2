"""The filter-error method: maximum likelihood on the innovations of a Kalman filter.

Model (Jategaonkar ch. 5; Maine and Iliff): `x' = f(t, x, u, p) + F w` with `w` unit
white noise and `F` diagonal on the states listed in `process_noise`, sampled outputs
`z_k = g(t_k, x_k, u_k, p) + v_k`. A steady-state filter runs through each record:

    predicted output   y_k  = g(t_k, x~_k, u_k)
    innovation         nu_k = z_k - y_k
    correction         x^_k = x~_k + K nu_k
    prediction         x~_k+1 = RK4 step of f from x^_k (the engine's integrator)

The gain `K = P C^T R^-1` comes from the model linearised by JAX (`A = df/dx`,
`C = dg/dx`) at the record's initial state and first input (as FVSysID does,
[`SteadyStateGain`][]), or at a few points along the filter's predicted
trajectory with the gains interpolated in time between them ([`ScheduledGain`][],
for a vehicle whose flight condition changes through the record), discretised
exactly at the sample step (`Phi = expm(A dt)`, `Q` by Van Loan) and the discrete
Riccati equation written with the innovation covariance `R`
([`solve_filter_riccati`][]). The cost is det(R); as in output error, `R` (diagonal by default, full
on request) is relaxed: estimated in closed form from the innovations, then held while a
Gauss-Newton (Levenberg-Marquardt) step on `sum nu^T R^-1 nu` moves the model
parameters and the process-noise intensities `F` together. Each step's Jacobian of
every innovation is exact: forward mode through the filter, the gain and the Riccati
solution (implicit derivative). After `R` changes, `F` is rescaled to keep the gain
(Jategaonkar eq. 5.41's heuristic), which saves iterations. The gain is kept
physical, `diag(K C) <= 1` (else the implied measurement noise `R - C P C^T` would be
negative), by an equality-constrained step on the linearised constraint for the rows
the free step would violate; the result says when the constraint is active.

Why not an extended Kalman filter with a gain per sample: it propagates a
covariance and solves a gain inside the scan, so every tangent of the Jacobian
differentiates both at every sample, and its innovation covariance changes per
sample, so `R` can no longer be relaxed in closed form. A schedule solves a
handful of Riccati equations outside the scan (each differentiated by one
implicit linear solve per tangent) and keeps the method's structure; measured
against an EKF in `benchmarks/filter_gain.py` (see the filter-error guide). Around
a trim point the steady-state gain is the schedule's first point, and it is what
FVSysID does, so its published HFB-320 estimates are a check we can reproduce.
"""

import functools
from collections.abc import Mapping, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .._model import Model, Record
from .._rk4 import rk4_step
from ._engine import (
    _input_at,
    coloured_information,
    explain,
    iteration_bound,
    Layout,
    RESULTS,
)
from ._estimator import AbstractFit
from ._filter_gain import AbstractFilterGain, SteadyStateGain
from ._fit import layout as _layout, output_error, simulate, SingleShooting
from ._gust import Gust, with_gust
from ._riccati import discretise, solve_filter_riccati


class FilterProblem(eqx.Module):
    """What [`solve_filter_error`][] needs besides the model: the records cut as one
    segment each ([`Layout`][]), their initial states `x0` `(records, states)`, the
    sample indices where the gain is solved `schedule` `(records, points)` (see
    [`AbstractFilterGain`][]), the states measured there `reference` `(records,
    points, states)` (NaN where no output measures a state; the first point is
    `x0`) and the state index of each process-noise intensity `noise_states`
    (static)."""

    layout: Layout
    x0: Float[Array, "records states"]
    schedule: Int[Array, "records points"]
    reference: Float[Array, "records points states"]
    noise_states: tuple[int, ...] = eqx.field(static=True)


def _noise_matrix(nx, noise_states, f):
    """`F` `(states, noise)`: intensity `f[j]` on state `noise_states[j]`."""
    m = jnp.zeros((nx, len(noise_states)))
    return m.at[jnp.asarray(noise_states), jnp.arange(len(noise_states))].set(f)


def gain(model: Model, prob: FilterProblem, r, theta, f, rmat, ref):
    """Steady-state gains `K` `(points, states, outputs)` of record `r` at its
    schedule points, the model linearised at the states `ref` `(points, states)`
    there, for innovation covariance `rmat` `(outputs, outputs)`; with the
    linearised `C` `(points, outputs, states)` and the a-priori covariances `P`
    `(points, states, states)`."""
    lay = prob.layout
    delay = model.input_delays(theta)
    fm = _noise_matrix(prob.x0.shape[1], prob.noise_states, f)

    def at(j, x):
        t = lay.t0[r] + lay.dt[r] * j
        u = _input_at(lay, r, t, delay)
        a = jax.jacfwd(model.f, argnums=1)(t, x, u, theta)
        c = jax.jacfwd(model.g, argnums=1)(t, x, u, theta)
        phi, q = discretise(a, fm, lay.dt[r])
        p = solve_filter_riccati(phi, c, q, rmat)
        return jnp.linalg.solve(rmat, c @ p).T, c, p

    return jax.vmap(at)(prob.schedule[r], ref)


def _gain_at(schedule, ks, i):
    """The gain at sample `i`: `ks` `(points, states, outputs)` interpolated
    linearly between the schedule's samples (constant with one point)."""
    m = ks.shape[0]
    if m == 1:
        return ks[0]
    j = jnp.clip(jnp.searchsorted(schedule, i, side="right") - 1, 0, m - 2)
    s0, s1 = schedule[j], schedule[j + 1]
    w = jnp.clip(jnp.where(s1 > s0, (i - s0) / jnp.maximum(s1 - s0, 1), 0.0), 0, 1)
    return ks[j] * (1 - w) + ks[j + 1] * w


def run_filter(model: Model, prob: FilterProblem, r, theta, k):
    """Innovations `(length, outputs)` (0 at padding), predicted outputs and
    predicted (a-priori) states `(length, states)` of record `r` through the
    filter with gains `k` `(points, states, outputs)` at its schedule points (or
    one gain `(states, outputs)`)."""
    lay = prob.layout
    dt = lay.dt[r]
    delay = model.input_delays(theta)
    ts = lay.t0[r] + dt * jnp.arange(lay.length)
    ks = k if k.ndim == 3 else k[None]
    sched = prob.schedule[r]

    def field(t, x):
        return model.f(t, x, _input_at(lay, r, t, delay), theta)

    def step(x, inp):
        i, t, z, valid = inp
        y = model.g(t, x, _input_at(lay, r, t, delay), theta)
        nu = jnp.where(valid, z - y, 0.0)
        xc = x + _gain_at(sched, ks, i) @ nu
        # padding holds the state: propagating it could overflow into the tangents
        x1 = jnp.where(valid, rk4_step(field, t, xc, dt), x)
        return x1, (nu, y, x)

    idx = jnp.arange(lay.length)
    _, (nu, y, xs) = jax.lax.scan(
        step, prob.x0[r], (idx, ts, lay.measured[r], lay.valid[r])
    )
    return nu, y, xs


def innovations(model: Model, prob: FilterProblem, z, rmat, ref=None):
    """Innovations `(records, length, outputs)`, predicted outputs, `diag(K C)`
    `(records, points, states)`, gains `(records, points, states, outputs)`,
    linearised `C`s `(records, points, outputs, states)` and predicted states
    `(records, length, states)` at unknowns `z = [theta, f]`, the gains
    linearised at the states `ref` `(records, points, states)` (default
    `prob.reference`)."""
    p = len(model.parameters)
    theta, f = z[:p], z[p:]
    ref = prob.reference if ref is None else ref

    def one(r):
        k, c, _ = gain(model, prob, r, theta, f, rmat, ref[r])
        nu, y, xs = run_filter(model, prob, r, theta, k)
        return nu, y, jnp.einsum("pij,pji->pi", k, c), k, c, xs

    return jax.vmap(one)(jnp.arange(prob.layout.n_records))


class FilterSolution(eqx.Module):
    """The raw result of [`solve_filter_error`][].

    **Fields:** `z` `[theta, f]`; `R` `(outputs, outputs)` innovation covariance; `cost`
    det(R); `iterations`; `result`; `covariance` of `z` (inverse Fisher information
    of the innovations, zero for held unknowns); `innovations` and `outputs`
    `(records, length, outputs)`; `kc` `(records, points, states)` the diagonal of
    `K C` at the schedule points; `gain` `(records, points, states, outputs)`;
    `reference` `(records, points, states)` the states the gains were linearised
    at; `active` whether `diag(K C) <= 1` bound a
    step at the end; `jacobian` `(records, length, outputs, unknowns)` the whitened
    innovations' Jacobian in every unknown (held ones too: a score test of a held
    parameter needs its column) and `whitened` `(records, length, outputs)` the
    whitened innovations, both at `z` (zero at padding).
    """

    z: Float[Array, " unknowns"]
    R: Float[Array, "outputs outputs"]
    cost: Float[Array, ""]
    iterations: Int[Array, ""]
    result: RESULTS
    covariance: Float[Array, "unknowns unknowns"]
    innovations: Float[Array, "records length outputs"]
    outputs: Float[Array, "records length outputs"]
    kc: Float[Array, "records points states"]
    gain: Float[Array, "records points states outputs"]
    reference: Float[Array, "records points states"]
    active: Bool[Array, ""]
    jacobian: Float[Array, "records length outputs unknowns"]
    whitened: Float[Array, "records length outputs"]
    information: Float[Array, "unknowns unknowns"]
    change: Float[Array, ""]


def _whiten(rmat):
    """`W` with `W^T W = R^-1` (the inverse Cholesky factor)."""
    chol = jnp.linalg.cholesky(rmat)
    return jax.scipy.linalg.solve_triangular(chol, jnp.eye(rmat.shape[0]), lower=True)


def _linearise(model, prob, z, rmat, ref, rows=False):
    """Normal matrix `(n, n)` and gradient of `sum nu^T R^-1 nu` with the gains
    linearised at `ref`, with the innovations, `diag(K C)` and its Jacobian
    `(records, points, states, n)`, `C`s and predicted states;
    with `rows`, also the whitened innovation Jacobian `(records, length,
    outputs, n)` and whitened innovations `(records, length, outputs)`."""

    def fn(v):
        nu, y, kc, k, c, xs = innovations(model, prob, v, rmat, ref)
        return (nu, kc), (nu, y, kc, k, c, xs)

    (jnu, jkc), aux = jax.jacfwd(fn, has_aux=True)(z)
    nu = aux[0]
    w = _whiten(rmat)
    valid = prob.layout.valid[..., None, None]
    jw4 = jnp.where(valid, jnp.einsum("ij,rtjk->rtik", w, jnu), 0.0)
    ew3 = jnp.einsum("ij,rtj->rti", w, nu)
    jw, ew = jw4.reshape(-1, z.shape[0]), ew3.reshape(-1)
    if rows:
        return jw.T @ jw, jw.T @ ew, jkc, aux, jw4, ew3
    return jw.T @ jw, jw.T @ ew, jkc, aux


def _constrained_step(h, g, free, damping, kc, jkc):
    """Levenberg-Marquardt step on the free unknowns, with rows of
    `kc + jkc step <= 1` that the free step would break held at equality (one
    active-set pass: the KKT system of the equality-constrained quadratic)."""
    m = free.astype(h.dtype)
    hm = h * m[:, None] * m[None, :] + jnp.diag(1.0 - m)
    scale = jnp.sqrt(jnp.clip(jnp.diag(hm), 1e-300))
    hs = hm / scale[:, None] / scale[None, :] + (damping + 1e-12) * jnp.eye(h.shape[0])
    cf = jax.scipy.linalg.cho_factor(hs)
    step = jax.scipy.linalg.cho_solve(cf, -g * m / scale)
    a = jkc.reshape(-1, h.shape[0]) * m[None, :] / scale[None, :]
    b = 1.0 - kc.reshape(-1)
    active = (a @ step > b) & jnp.any(a != 0.0, axis=1)
    a_act = jnp.where(active[:, None], a, 0.0)
    hia = jax.scipy.linalg.cho_solve(cf, a_act.T)
    schur = a_act @ hia + jnp.diag(jnp.where(active, 0.0, 1.0))
    lam = jnp.linalg.solve(schur, jnp.where(active, a_act @ step - b, 0.0))
    step = step - hia @ lam
    return step / scale * m, jnp.any(active)


def _print_progress(it, cost, change, damping):
    import sys

    print(
        f"iteration {int(it):4d}: det(R) {float(cost):.6e}, relative change "
        f"{float(change):.2e}, damping {float(damping):.1e}",
        file=sys.stderr,
        flush=True,
    )


@functools.partial(jax.jit, static_argnames=("model", "full", "progress"))
def solve_filter_error(
    model: Model,
    prob: FilterProblem,
    z0,
    free,
    *,
    rtol,
    max_iter,
    full=False,
    progress=False,
) -> FilterSolution:
    """Minimise det(R) of the innovations over the free unknowns `z = [theta, f]`
    from `z0` (pure and jitted; vmap batches it over problems of one shape); `R`
    full (`full=True`) or diagonal; `progress` prints one line per iteration."""
    p = len(model.parameters)
    lay = prob.layout
    nvalid = jnp.sum(lay.valid)

    def weighted(nu, rmat):
        return jnp.sum(jnp.einsum("ij,rtj->rti", _whiten(rmat), nu) ** 2)

    def cost_at(z, rmat, ref):
        nu, _, _, _, _, xs = innovations(model, prob, z, rmat, ref)
        return weighted(nu, rmat), nu, xs

    def reference(xs):
        """The predicted states at the schedule points."""
        return jax.vmap(lambda x, i: x[i])(xs, prob.schedule)

    def sample(nu):
        r = jnp.einsum("rti,rtj->ij", nu, nu) / nvalid
        return r if full else jnp.diag(jnp.diag(r))

    def relax(z, rmat, nu, c):
        """New R from the innovations and `f` rescaled to keep the gain."""
        r_new = sample(nu)
        c0 = c[0, 0]
        info_old = jnp.diag(c0.T @ jnp.linalg.solve(rmat, c0))
        info_new = jnp.diag(c0.T @ jnp.linalg.solve(r_new, c0))
        ratio = jnp.sqrt(info_old / jnp.where(info_new > 0, info_new, info_old))
        ratio = jnp.where(jnp.isfinite(ratio) & (info_old > 0), ratio, 1.0)
        f = z[p:] * ratio[jnp.asarray(prob.noise_states, int)]
        return r_new, z.at[p:].set(f)

    def step(carry, lin):
        z, rmat, ref, cost_prev, it, _, damping, _, _, _ = carry
        h, g, jkc, (nu, _, kc, _, c, xs), _, _ = lin
        j0 = weighted(nu, rmat)

        def trial(lam):
            step, act = _constrained_step(h, g, free, lam, kc, jkc)
            new = z + step
            j1, nu1, xs1 = cost_at(new, rmat, ref)
            return new, jnp.where(jnp.isfinite(j1), j1, jnp.inf), nu1, xs1, act

        def increase(carry):
            # the first pass tries the carried damping, later ones raise it; one
            # copy of the trial (and of the filter in it) in the compiled program
            lam = jnp.where(carry[0], carry[1], jnp.maximum(10.0 * carry[1], 1e-8))
            return (jnp.array(False), lam, *trial(lam))

        _, damping, new, j1, nu1, xs1, act = jax.lax.while_loop(
            lambda c_: c_[0] | (~(c_[3] < j0) & (c_[1] < 1e8)),
            increase,
            (
                jnp.array(True),
                damping,
                z,
                jnp.full((), jnp.inf, j0.dtype),
                nu,
                xs,
                jnp.array(False),
            ),
        )
        accepted = j1 < j0
        new = jnp.where(accepted, new, z)
        nu_used = jnp.where(accepted, nu1, nu)
        # the linearisation points follow the filter's predicted trajectory,
        # relaxed with R (the first point stays the held initial state)
        ref_new = reference(jnp.where(accepted, xs1, xs))
        ref_new = jnp.where(jnp.all(jnp.isfinite(ref_new)), ref_new, ref)
        r_new, new = relax(new, rmat, nu_used, c)
        cost = jnp.linalg.det(r_new)
        small = jnp.abs(cost_prev - cost) <= rtol * jnp.abs(cost)
        broken = ~(jnp.all(jnp.isfinite(h)) & jnp.all(jnp.isfinite(g)))
        done = (small & accepted) | ~accepted | broken
        change = jnp.abs(cost_prev - cost) / jnp.abs(cost)
        if progress:
            jax.debug.callback(_print_progress, it + 1, cost, change, damping)
        return (
            new,
            r_new,
            ref_new,
            cost,
            it + 1,
            done,
            damping / 10.0,
            broken,
            act & accepted,
            change,
        )

    # start as FVSysID does: R from the output errors of the start model (zero
    # gain); the first gain is the one the start intensities imply with that R
    nx = prob.x0.shape[1]
    k0 = jnp.zeros((nx, lay.measured.shape[-1]))
    e0, _, x_sim = jax.vmap(lambda r: run_filter(model, prob, r, z0[:p], k0))(
        jnp.arange(lay.n_records)
    )
    r0 = jnp.diag(jnp.sum(e0**2, axis=(0, 1)) / nvalid)
    # the first linearisation points: measured states, else the start simulation
    ref0 = prob.reference
    ref0 = jnp.where(jnp.isnan(ref0), jnp.nan_to_num(reference(x_sim)), ref0)
    init = (z0, r0, ref0, jnp.linalg.det(r0), jnp.array(0), jnp.array(False))
    init = (*init, jnp.array(0.0), ~jnp.all(jnp.isfinite(r0)), jnp.array(False))
    init = (*init, jnp.array(jnp.inf))

    def going(c_):
        return (c_[4] < max_iter) & ~c_[5] & ~c_[7]

    def linearise(c_):
        return _linearise(model, prob, c_[0], c_[1], c_[2], rows=True)

    def body(carry):
        # every pass linearises where it stands; the pass after the last step
        # only does that, for the statistics at the solution: one copy of the
        # filter's Jacobian in the compiled program, not one in the loop and
        # another after it
        state, _, _ = carry
        lin = linearise(state)
        go = going(state)
        state = jax.lax.cond(go, lambda s_: step(s_, lin), lambda s_: s_, state)
        return state, lin, ~go

    lin0 = jax.tree.map(
        lambda a: jnp.zeros(a.shape, a.dtype), jax.eval_shape(linearise, init)
    )
    state, lin, _ = jax.lax.while_loop(
        lambda c_: ~c_[2], body, (init, lin0, jnp.array(False))
    )
    z, rmat, ref, cost, iterations, done, _, broken, active, change = state
    h, _, _, (nu, y, kc, k, _, _), jw, ew = lin
    m = free.astype(h.dtype)
    hm = h * m[:, None] * m[None, :] + jnp.diag(1.0 - m)
    cov = jnp.linalg.inv(hm) * m[:, None] * m[None, :]
    finite = jnp.isfinite(cost) & jnp.all(jnp.isfinite(z)) & ~broken
    result = RESULTS.where(
        finite,
        RESULTS.where(done, RESULTS.successful, RESULTS.max_iterations),
        RESULTS.nonfinite,
    )
    return FilterSolution(
        z=z,
        R=rmat,
        cost=cost,
        iterations=iterations,
        result=result,
        covariance=cov,
        innovations=nu,
        outputs=y,
        kc=kc,
        gain=k,
        reference=ref,
        active=active | jnp.any(kc > 1.0 - 1e-3),
        jacobian=jw,
        whitened=jnp.where(lay.valid[..., None], ew, 0.0),
        information=hm * m[:, None] * m[None, :],
        change=change,
    )


class FilterErrorFit(AbstractFit):
    """A filter-error fit of a [`Model`][] to one or several [`Record`][]s.

    **Fields:**

    - `model`, `records`: what was fitted.
    - `params` `(params,)`, `free`, `stderr` (Cramér-Rao, from the Fisher information
      of the innovations; 0 for held parameters), `stderr_corrected` (the same
      corrected for whatever colour the innovations keep, Morelli-Klein),
      `correlation` `(params, params)`.
    - `process_noise` names of the states with process noise; `F` `(noise,)` their
      intensities (state units / sqrt(s): `x' = f + F w`, `w` unit white noise) and
      `F_stderr`.
    - `covariance` `(params + noise, params + noise)` of `[params, F]`.
    - `cost` det(R); `R` `(outputs, outputs)` the innovation covariance (diagonal
      unless fitted with `full_R=True`).
    - `innovations`, `outputs`: per record `(samples, outputs)`, the filter's
      innovations (residuals) and predicted outputs.
    - `gain` `(records, points, states, outputs)` the gains at the schedule
      points (one point for [`SteadyStateGain`][]) at times `gain_times`
      `(records, points)` s; `kc` per record `(states,)` the largest diagonal of
      `K C` over the points; `constraint_active` whether `diag(K C) <= 1` binds.
    - `jacobian` `(records, length, outputs, params + noise)`: the whitened
      innovations' Jacobian in every parameter (held ones too) and intensity, and
      `whitened` `(records, length, outputs)` the whitened innovations `W nu`
      (`W^T W = R^-1`), records padded to the longest with zeros: what a score test
      of a held parameter at this fit needs.
    - `iterations`; `result` a [`RESULTS`][] code (`converged`), `reason` why it
      stopped and what to try (`message`).
    """

    model: Model
    records: tuple[Record, ...]
    params: np.ndarray
    free: np.ndarray
    stderr: np.ndarray
    stderr_corrected: np.ndarray
    correlation: np.ndarray
    process_noise: tuple[str, ...] = eqx.field(static=True)
    F: np.ndarray
    F_stderr: np.ndarray
    covariance: np.ndarray
    cost: float
    R: np.ndarray
    innovations: tuple[np.ndarray, ...]
    outputs: tuple[np.ndarray, ...]
    gain: np.ndarray
    gain_times: np.ndarray
    kc: np.ndarray
    constraint_active: bool
    jacobian: np.ndarray
    whitened: np.ndarray
    iterations: int
    result: RESULTS
    reason: str

    @property
    def residuals(self) -> tuple[np.ndarray, ...]:
        """The innovations (the filter-error method's residuals)."""
        return self.innovations

    def table(self) -> list[dict]:
        """One row per parameter and per process-noise intensity `F[state]`."""
        from ._oem import parameter_table

        names = [*self.model.parameters, *(f"F[{s}]" for s in self.process_noise)]
        est = [*self.params.tolist(), *np.abs(self.F).tolist()]
        sd = [*self.stderr.tolist(), *self.F_stderr.tolist()]
        free = [*self.free.tolist(), *([True] * len(self.F))]
        rows = parameter_table(names, est, sd, free)
        for row, f in zip(rows, free, strict=True):
            row["fixed"] = not f
        return rows


def problem(
    model: Model,
    records: Sequence[Record],
    noise_states: tuple[int, ...],
    gain: AbstractFilterGain = SteadyStateGain(),
    x0=None,
) -> FilterProblem:
    """Records as a [`FilterProblem`][] (one padded segment each), the gain solved
    at `gain`'s schedule; initial states `x0` `(records, states)` (default each
    record's `x0`, else its first measured sample)."""
    starts, schedule, reference = [], [], []
    for i, rec in enumerate(records):
        rec.check(model)
        if x0 is not None:
            x = np.asarray(x0[i], float)
        else:
            x = rec.x0 if rec.x0 is not None else rec.measured_states(model, [0])[0]
        if np.any(np.isnan(x)):
            missing = [model.states[j] for j in np.flatnonzero(np.isnan(x))]
            raise ValueError(
                f"{rec.name}: states {missing} are not measured outputs; give the "
                "record's initial state x0"
            )
        starts.append(x)
        idx = gain.schedule(len(rec.t))
        ref = rec.measured_states(model, idx)
        ref[idx == 0] = x
        schedule.append(idx)
        reference.append(ref)
    lay = _layout(
        model, records, SingleShooting(), "fixed", (), np.ones(len(model.states))
    )
    return FilterProblem(
        layout=lay,
        x0=jnp.asarray(np.array(starts)),
        schedule=jnp.asarray(np.array(schedule)),
        reference=jnp.asarray(np.array(reference)),
        noise_states=noise_states,
    )


def fit_filter_error(
    model: Model,
    records: Record | Sequence[Record],
    *,
    process_noise: Sequence[str] | Mapping[str, float],
    start=None,
    full_R: bool = False,
    rtol: float = 1e-6,
    max_iter: int | None = None,
    throw: bool = True,
    gain: AbstractFilterGain = SteadyStateGain(),
    start_fit: Mapping | None = None,
    residuals=None,
    x0=None,
    gust: Gust | None = None,
) -> FilterErrorFit:
    """Maximum-likelihood filter-error estimate of `model`'s parameters and the
    process-noise intensities from one or several records (e.g. flown in
    turbulence). Kept for one release: prefer `dp.estimate(model, records,
    dp.FilterError(...))`, the one entry for every method.

    **Arguments:**

    - `model`: the [`Model`][] (its `fixed` parameters are held at `start`).
    - `records`: a [`Record`][] or a list of them; each record's initial state is
      its `x0` (default: its first measured sample), held (the filter corrects it).
    - `process_noise`: the states whose equations get process noise: names, or a
      dict name -> start intensity (state units / sqrt(s)). Names alone start
      from an output-error fit (see [`FilterError`][]): its estimates are the
      parameters' start, and each intensity is scaled to its residuals. Every
      intensity is estimated.
    - `start`: start values of the model parameters `(params,)` (default: the
      output-error estimates when the intensities are not given, else
      `model.start`); given, it is the start, the output-error fit from it only
      scales the intensities.
    - `full_R`: estimate the full innovation covariance instead of its diagonal
      (the default, as output error and FVSysID do). Process noise correlates the
      innovations of outputs driven by the same state (alpha and az): in the
      simulated Monte Carlo the diagonal R left F[alpha] 25% low (the derivatives
      unbiased either way) and the full R found it; on the real HFB-320 record
      the diagonal R reproduces FVSysID and gives the whiter innovations.
    - `rtol`: stop when det(R) changes by less than this, relatively.
    - `max_iter`: iteration bound (default: the adaptive budget).
    - `throw`: raise a `RuntimeError` with the reason when the fit fails; with
      `throw=False` the result carries the code and `message` instead.
    - `gain`: [`SteadyStateGain`][] (default, one gain from the linearisation at
      the initial state), [`ScheduledGain`][] (a gain following the flight
      condition), or `None`: chosen from the record by `choose_gain` at the
      start values (what `fit --method fem` does).
    - `start_fit`: keywords of the output-error fit that gives the start
      (`shooting`, `initial_state`; default single shooting from the held initial
      state); with `initial_state="estimated"` its initial states are the
      filter's too, unless a record has its own `x0`.
    - `residuals`: per record `(samples, outputs)`, residuals of a fit made
      already to scale the start intensities (then no output-error fit is made:
      the parameters start at `start`, default `model.start`); `x0` `(records,
      states)` the initial states that fit found.
    - `gust`: a [`Gust`][] (default `None`: white process noise only): first-order
      gust states on the airflow states it names, driven by process noise too,
      with their correlation time estimated; the fit's model is then the
      augmented one ([`with_gust`][]: states `gust[state]`, parameter
      `gust_ln_tau`, the natural log of the correlation time in s, or
      `gust_ln_length`, of the length scale in m, when the gust names the
      airspeed).

    **Returns:** a [`FilterErrorFit`][].
    """
    return filter_error(
        model,
        records,
        process_noise=process_noise,
        start=start,
        full_R=full_R,
        rtol=rtol,
        max_iter=max_iter,
        throw=throw,
        gain=gain,
        start_fit=start_fit,
        residuals=residuals,
        x0=x0,
        gust=gust,
    )


def residual_intensities(model: Model, records, residuals, theta, noise_states):
    """Start intensities (state units / sqrt(s)) scaled to a fit's residuals.

    Each output's residual rms `sigma_i` (over all records) is carried to the
    states through the linearised observation `C = dg/dx` at the first record's
    start: a state's residual level is the smallest `sigma_i / |C_ij|` over the
    outputs that see it. A random walk of intensity `F` wanders by `F sqrt(T)` in
    the record's duration `T`, so `F = sigma_x / sqrt(T)` is the intensity whose
    drift over the record is the size of what the fit left unexplained: small when
    the model already fits (the residuals are the sensors' noise), large when
    turbulence moved the states. The steps of the fit then move it by factors.
    """
    e = np.concatenate([np.asarray(r) for r in residuals])
    sigma = np.sqrt(np.mean(e**2, axis=0))
    rec = records[0]
    x0 = rec.x0 if rec.x0 is not None else rec.measured_states(model, [0])[0]
    c = np.asarray(
        jax.jacfwd(model.g, argnums=1)(
            float(rec.t[0]),
            jnp.asarray(x0),
            jnp.asarray(rec.inputs[0]),
            jnp.asarray(theta),
        )
    )
    duration = max(float(r.t[-1] - r.t[0]) for r in records)
    f0 = []
    for j in noise_states:
        seen = np.abs(c[:, j]) > 0
        if not np.any(seen):
            raise ValueError(
                f"process noise on {model.states[j]!r}: no output sees this state at "
                "the start (give its start intensity)"
            )
        level = np.min(sigma[seen] / np.abs(c[seen, j]))
        f0.append(level / np.sqrt(duration))
    f0 = np.asarray(f0)
    # a model that reproduces a channel to the last bit leaves no residual: a
    # floor of the rounding of the states' size keeps the intensity non-zero
    floor = np.finfo(float).eps * np.maximum(
        np.abs(np.asarray(x0))[list(noise_states)], 1.0
    )
    return np.maximum(f0, floor)


def filter_error(
    model: Model,
    records: Record | Sequence[Record],
    *,
    process_noise: Sequence[str] | Mapping[str, float],
    start=None,
    full_R: bool = False,
    rtol: float = 1e-6,
    max_iter: int | None = None,
    throw: bool = True,
    progress: bool = False,
    gain: AbstractFilterGain = SteadyStateGain(),
    start_fit: Mapping | None = None,
    residuals=None,
    x0=None,
    gust: Gust | None = None,
) -> FilterErrorFit:
    """The filter-error fit behind [`FilterError`][] and [`fit_filter_error`][]
    (arguments as [`fit_filter_error`][]'s; `progress` prints one line per
    iteration)."""
    records = (records,) if isinstance(records, Record) else tuple(records)
    if not records:
        raise ValueError("no records to fit")
    if gust is not None:
        return _gust_filter_error(
            model,
            records,
            gust,
            process_noise=process_noise,
            start=start,
            start_fit=start_fit,
            residuals=residuals,
            x0=x0,
            full_R=full_R,
            rtol=rtol,
            max_iter=max_iter,
            throw=throw,
            progress=progress,
            gain=gain,
        )
    names = tuple(process_noise)
    if not names:
        raise ValueError(
            "process_noise names no state; without process noise use `fit` (output error)"
        )
    unknown = [s for s in names if s not in model.states]
    if unknown:
        raise ValueError(
            f"process_noise on {unknown}: not model states ({', '.join(model.states)})"
        )
    if len(set(names)) != len(names):
        raise ValueError(f"process_noise names a state twice: {names}")
    noise_states = tuple(model.states.index(s) for s in names)
    first = SteadyStateGain() if gain is None else gain
    if isinstance(process_noise, Mapping):
        prob = problem(model, records, noise_states, first, x0)
        theta0 = np.asarray(model.start if start is None else start, float)
        f0 = np.array([float(process_noise[s]) for s in names])
    elif residuals is not None:
        prob = problem(model, records, noise_states, first, x0)
        theta0 = np.asarray(model.start if start is None else start, float)
        f0 = residual_intensities(model, records, residuals, theta0, noise_states)
    else:
        theta0, residuals, x_oe = _output_error_start(
            model, records, start, dict(start_fit or {})
        )
        x_start = x0 if x0 is not None else x_oe
        prob = problem(model, records, noise_states, first, x_start)
        f0 = residual_intensities(model, records, residuals, theta0, noise_states)
    if np.any(f0 == 0):
        raise ValueError("process-noise start intensities must be non-zero")
    if gain is None and residuals is None:
        # start intensities given, no residuals to weigh a schedule by
        gain = first
    elif gain is None:
        gain = choose_gain(
            model, records, noise_states, np.asarray(prob.x0), theta0, f0, residuals
        )
        if gain != first:
            prob = problem(model, records, noise_states, gain, np.asarray(prob.x0))
    if (
        residuals is not None
        and not isinstance(process_noise, Mapping)
        and prob.schedule.shape[1] > 1
    ):
        # a scheduled gain: the program choose_gain compiled for these shapes
        f0 = _solvable_start(model, prob, theta0, f0, residuals)
    z0 = np.concatenate([theta0, f0])
    free = np.concatenate([model.free, np.ones(len(names), bool)])
    sol = solve_filter_error(
        model,
        prob,
        jnp.asarray(z0),
        jnp.asarray(free),
        rtol=rtol,
        max_iter=jnp.asarray(iteration_bound(max_iter)),
        full=bool(full_R),
        progress=bool(progress),
    )
    sol = jax.tree.map(np.asarray, sol)
    # a steady gain solved at several (identical) points reports one
    kept = 1 if isinstance(gain, SteadyStateGain) else prob.schedule.shape[1]
    p = len(model.parameters)
    sd = np.sqrt(np.clip(np.diag(sol.covariance), 0.0, None))
    block = sol.covariance[:p, :p]
    d = np.sqrt(np.clip(np.diag(block), 1e-300, None))
    lengths = [len(rec.t) for rec in records]
    result, reason = explain(
        sol.result,
        information=_gram(sol.jacobian),
        free=free,
        names=[*model.parameters, *(f"F[{s}]" for s in names)],
        iterations=int(sol.iterations),
        change=float(sol.change),
    )
    out = FilterErrorFit(
        model=model,
        records=records,
        params=sol.z[:p],
        free=np.asarray(model.free),
        stderr=sd[:p],
        stderr_corrected=np.maximum(
            _corrected_stderr(sol.jacobian, sol.whitened, sol.covariance, lengths)[:p],
            sd[:p],
        ),
        correlation=block / (d[:, None] * d[None, :]),
        process_noise=names,
        F=np.abs(sol.z[p:]),
        F_stderr=sd[p:],
        covariance=sol.covariance,
        cost=float(sol.cost),
        R=sol.R,
        innovations=tuple(sol.innovations[i, :n] for i, n in enumerate(lengths)),
        outputs=tuple(sol.outputs[i, :n] for i, n in enumerate(lengths)),
        gain=sol.gain[:, :kept],
        gain_times=np.asarray(
            [
                rec.t[0] + (rec.t[1] - rec.t[0]) * np.asarray(idx)[:kept]
                for rec, idx in zip(records, np.asarray(prob.schedule), strict=True)
            ]
        ),
        kc=np.max(sol.kc, axis=1),
        constraint_active=bool(sol.active),
        jacobian=sol.jacobian,
        whitened=sol.whitened,
        iterations=int(sol.iterations),
        result=result,
        reason=reason,
    )
    if throw and not out.converged:
        raise RuntimeError(f"filter-error fit failed: {out.message}")
    return out


def _gust_filter_error(
    model, records, gust, *, process_noise, start, start_fit, residuals, x0, **options
):
    """[`filter_error`][] of `model` with the [`Gust`][] states appended
    ([`with_gust`][]): white process noise on `process_noise` as without it, and
    the gust states driven by noise too; the gust states start at 0 (the filter
    corrects them) and their start intensities are scaled like the white ones
    (given intensities: the gust on a state starts with that state's)."""
    if isinstance(process_noise, Mapping):
        theta0 = np.asarray(model.start if start is None else start, float)
    elif residuals is None:
        theta0, residuals, x_oe = _output_error_start(
            model, records, start, dict(start_fit or {})
        )
        x0 = x0 if x0 is not None else x_oe
    else:
        theta0 = np.asarray(model.start if start is None else start, float)
    base = [
        np.asarray(x0[i], float)
        if x0 is not None
        else (rec.x0 if rec.x0 is not None else rec.measured_states(model, [0])[0])
        for i, rec in enumerate(records)
    ]
    x_aug = np.array([np.concatenate([x, np.zeros(len(gust.states))]) for x in base])
    # each record's initial state, gust states included, for the augmented model
    records = tuple(
        Record(rec.t, rec.inputs, rec.measured, x0=x, name=rec.name)
        for rec, x in zip(records, x_aug, strict=True)
    )
    aug = with_gust(model, gust)
    if isinstance(process_noise, Mapping):
        noise = dict(process_noise)
        for s, g in zip(gust.states, gust.names, strict=True):
            noise[g] = float(process_noise.get(s, next(iter(process_noise.values()))))
    else:
        noise = (*process_noise, *gust.names)
    return filter_error(
        aug,
        records,
        process_noise=noise,
        start=np.concatenate([theta0, aug.start[-1:]]),
        residuals=residuals,
        x0=x_aug,
        **options,
    )


# the steady-state gain serves a record while the weight the filter gives the
# measurements of each state, diag(K C) (0: none, 1: all), stays within this of
# its value at the start, wherever the gain is solved along the record
GAIN_VARIATION = 0.1


@functools.partial(jax.jit, static_argnames=("model",))
def _kc_at_points(model, prob, theta, f, rmat, ref):
    """`diag(K C)` `(records, points, states)` at the schedule points of `prob`
    (one compiled program per model and shape, shared by every call)."""

    def one(r):
        k, c, _ = gain(model, prob, r, theta, f, rmat, ref[r])
        return jnp.einsum("pij,pji->pi", k, c)

    return jax.vmap(one)(jnp.arange(prob.layout.n_records))


def gain_variation(model, prob, theta, f, residuals) -> float:
    """The largest change of `diag(K C)` (dimensionless, 0 to 1) between the
    steady-state gains solved at the schedule points of `prob` and its first,
    linearised at its reference states (measured; unmeasured states held at the
    initial state), for the intensities `f` and the innovation covariance of
    `residuals` (per record `(samples, outputs)`)."""
    e = np.concatenate([np.asarray(r) for r in residuals])
    rmat = jnp.diag(jnp.asarray(np.maximum(np.mean(e**2, axis=0), 1e-300)))
    ref = jnp.where(jnp.isnan(prob.reference), prob.x0[:, None, :], prob.reference)
    kc = np.asarray(
        _kc_at_points(model, prob, jnp.asarray(theta), jnp.asarray(f), rmat, ref)
    )
    change = np.abs(kc - kc[:, :1])
    return float(np.max(np.where(np.isfinite(change), change, np.inf)))


def _solvable_start(model, prob, theta, f, residuals, tries: int = 4):
    """Start intensities `f` scaled to residuals, divided by 10 (at most `tries`
    times) while the steady-state gain has no solution at some schedule point of
    `prob` (innovation covariance from `residuals`, as [`gain_variation`][]): a
    gain that does not exist there makes the filter's innovations, and so the
    start's det(R), non-finite, and the fit cannot take a step (measured: the
    launch vehicle's 10 s transonic flight with 6 Mach functions, no solution at
    Mach 1 from the output-error estimates). The intensities are estimated: only
    the start moves."""
    e = np.concatenate([np.asarray(r) for r in residuals])
    rmat = jnp.diag(jnp.asarray(np.maximum(np.mean(e**2, axis=0), 1e-300)))
    ref = jnp.where(jnp.isnan(prob.reference), prob.x0[:, None, :], prob.reference)
    f = np.asarray(f, float)
    for _ in range(tries):
        kc = _kc_at_points(model, prob, jnp.asarray(theta), jnp.asarray(f), rmat, ref)
        if np.all(np.isfinite(np.asarray(kc))):
            break
        f = f / 10.0
    return f


def choose_gain(model, records, noise_states, x0, theta, f, residuals, points=16):
    """[`SteadyStateGain`][] when the gains solved at `points` samples along the
    records (initial states `x0`) stay within [`GAIN_VARIATION`][] of the first
    (a record about one flight condition), else [`ScheduledGain`][]`(points)`."""
    from ._filter_gain import ScheduledGain

    sched = ScheduledGain(points=points)
    trial = problem(model, records, noise_states, sched, x0)
    if gain_variation(model, trial, theta, f, residuals) > GAIN_VARIATION:
        return sched
    return SteadyStateGain()


def _output_error_start(model, records, start, options):
    """Parameters, residuals and initial states (or None) to start the filter
    from. The residuals are those of an output-error fit (keywords `options`,
    e.g. multiple shooting) from `start` (default the model's) when it ends
    finite, else of `start`'s simulation; the parameters are that fit's estimates
    when no `start` is given, else `start` itself (a caller trying several starts
    keeps them apart); the initial states are the fit's when it estimated them."""
    theta0 = np.asarray(model.start if start is None else start, float)
    oe = output_error(
        model.replace(start=dict(zip(model.parameters, theta0.tolist(), strict=True))),
        records,
        throw=False,
        **options,
    )
    if np.isfinite(oe.cost) and np.all(np.isfinite(oe.params)):
        residuals = [
            rec.measured - y for rec, y in zip(records, oe.outputs, strict=True)
        ]
        x_oe = (
            np.asarray(oe.initial_states)
            if options.get("initial_state") == "estimated"
            and all(rec.x0 is None for rec in records)
            else None
        )
        return (
            (np.asarray(oe.params, float) if start is None else theta0),
            residuals,
            x_oe,
        )
    residuals = []
    for rec in records:
        x = rec.x0 if rec.x0 is not None else rec.measured_states(model, [0])[0]
        xs = simulate(model, rec, theta0, np.asarray(x))
        ys = jax.vmap(lambda t, x, u: model.g(t, x, u, jnp.asarray(theta0)))(
            jnp.asarray(rec.t), jnp.asarray(xs), jnp.asarray(rec.inputs)
        )
        residuals.append(
            np.nan_to_num(rec.measured - np.asarray(ys), posinf=0, neginf=0)
        )
    return theta0, residuals, None


def _gram(jacobian):
    """`A^T A` of the whitened innovations' Jacobian `(records, length, outputs,
    unknowns)`, held unknowns' columns included (the caller masks them)."""
    a = jacobian.reshape(-1, jacobian.shape[-1])
    return a.T @ a


def _corrected_stderr(jacobian, whitened, covariance, lengths):
    """Standard errors of all unknowns corrected for coloured innovations
    (Morelli-Klein, per record, summed). `lengths`: each record's samples; the
    rows beyond them are padding (zero), not samples of the autocovariance."""
    total = np.zeros_like(covariance)
    for r in range(jacobian.shape[0]):
        k = np.einsum("tok,kn->ton", jacobian[r], covariance)
        total += np.asarray(
            coloured_information(
                jnp.asarray(k), jnp.asarray(whitened[r]), samples=lengths[r]
            )
        )
    return np.sqrt(np.clip(np.diag(total), 0.0, None))
