"""The output-error method: maximum likelihood by Gauss-Newton with exact Jacobians.

A model is two pure functions of time, state, known inputs and parameters:
`rates(t, x, u, theta) -> x'` and `outputs(t, x, u, theta) -> y`. The record is cut
into parameter windows (the parameters are constant in each, or over the whole record)
and shooting segments (groups of windows, each integrated from its own node state).
Inside a window the model is integrated by RK4 at the sample step in one diffrax solve,
with the known inputs interpolated linearly between samples.

Cost: det(R), R the covariance of the output residuals (full or diagonal), relaxed in
the standard way: with R fixed, the R^-1-weighted least-squares problem is solved by
Gauss-Newton (optimistix, Newton descent with a backtracking search that halves the
step until the cost falls), then R is re-estimated from the residuals; this repeats
until det(R) changes by less than `rtol` (1e-5) relatively, or `max_outer` times.
Jacobians are exact, by forward-mode differentiation through the diffrax solves.

Multiple shooting: the node states are unknowns (initial guesses from the
measurements) and continuity is enforced by defect residuals
`(x_end(segment j) - node(j + 1)) / (state_scale * continuity_tol)` in the same least
squares, a quadratic penalty that keeps the defects at `continuity_tol` times the state
scale or below; the final defects are reported.
"""

import functools
from collections.abc import Callable

import diffrax
import equinox as eqx
import jax
import jax.flatten_util
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx
from jaxtyping import Array, Bool, Float, Int

from ._rk4 import RK4


def _silent(**kwargs):
    del kwargs


class HalvingGaussNewton(optx.AbstractGaussNewton):
    """Gauss-Newton whose step is halved until the cost decreases (Armijo
    backtracking with factor 1/2), as flight-test output-error codes do."""

    rtol: float
    atol: float
    norm: Callable = eqx.field(static=True, default=optx.rms_norm)
    descent: optx.NewtonDescent = optx.NewtonDescent(
        linear_solver=lx.AutoLinearSolver(well_posed=None)
    )
    search: optx.BacktrackingArmijo = optx.BacktrackingArmijo(
        decrease_factor=0.5, slope=1e-4
    )
    verbose: Callable = eqx.field(static=True, default=_silent)


class OEMProblem(eqx.Module):
    """An output-error problem: the model, the data and the unknowns.

    **Fields:**

    - `rates`, `outputs`: the model, `f(t, x, u, theta)` and `g(t, x, u, theta)` with
      `x` shape `(states,)`, `u` shape `(inputs,)`, `theta` shape `(params,)`.
    - `t0`, `dt`: time of the first sample and the sample interval, s.
    - `inputs`: shape `(samples, inputs)`, known inputs.
    - `measured`: shape `(samples, outputs)`, measured outputs.
    - `free`: which parameters are estimated (static tuple of bools).
    - `window`: samples per parameter window, or `None` for one parameter set over the
      record.
    - `node_interval`: samples per shooting segment (a multiple of `window`), or
      `None` for single shooting.
    - `free_initial_state`: whether the first node state is estimated (always true for
      later nodes under multiple shooting).
    - `full_covariance`: full or diagonal R.
    - `state_scale`: shape `(states,)`, typical state magnitudes for the continuity
      defects.
    - `continuity_tol`: allowed defect relative to `state_scale`.
    - `input_delay`: optional `theta -> (inputs,)` time delays, s: input `i` enters the
      model as recorded at `t - delay[i]` (an estimated actuator or sensor lag; linear
      interpolation between samples, so the delay is differentiable).
    """

    rates: Callable = eqx.field(static=True)
    outputs: Callable = eqx.field(static=True)
    t0: float | Float[Array, ""]
    dt: float = eqx.field(static=True)
    inputs: Float[Array, "samples inputs"]
    measured: Float[Array, "samples outputs"]
    free: tuple[bool, ...] = eqx.field(static=True)
    window: int | None = eqx.field(static=True, default=None)
    node_interval: int | None = eqx.field(static=True, default=None)
    free_initial_state: bool = eqx.field(static=True, default=False)
    full_covariance: bool = eqx.field(static=True, default=False)
    state_scale: Float[Array, " states"] | None = None
    continuity_tol: float = eqx.field(static=True, default=1e-4)
    input_delay: Callable | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        if self.node_interval is not None and self.window is not None:
            if self.node_interval % self.window:
                raise ValueError(
                    f"node_interval ({self.node_interval} samples) must be a multiple "
                    f"of the parameter window ({self.window} samples)"
                )

    @property
    def n_samples(self) -> int:
        return self.measured.shape[0]

    @property
    def window_samples(self) -> int:
        """Samples integrated by one diffrax solve."""
        if self.window is not None:
            return self.window
        if self.node_interval is not None:
            return self.node_interval
        return self.n_samples

    @property
    def n_windows(self) -> int:
        return -(-self.n_samples // self.window_samples)

    @property
    def windows_per_segment(self) -> int:
        if self.node_interval is None:
            return self.n_windows
        return self.node_interval // self.window_samples

    @property
    def n_segments(self) -> int:
        return -(-self.n_windows // self.windows_per_segment)

    @property
    def n_param_sets(self) -> int:
        return self.n_windows if self.window is not None else 1

    @property
    def free_index(self) -> np.ndarray:
        return np.flatnonzero(np.asarray(self.free))


class Unknowns(eqx.Module):
    """What Gauss-Newton solves for: free parameters per window and node states."""

    params: Float[Array, "sets free"]
    nodes: Float[Array, "segments states"]


def _input_at(problem: OEMProblem, t, theta=None):
    n = problem.inputs.shape[0]
    if problem.input_delay is None or theta is None:
        x = (t - problem.t0) / problem.dt
        i = jnp.clip(jnp.floor(x), 0, n - 2).astype(int)
        frac = jnp.clip(x - i, 0.0, 1.0)
        return problem.inputs[i] * (1 - frac) + problem.inputs[i + 1] * frac
    x = (t - problem.input_delay(theta) - problem.t0) / problem.dt
    i = jnp.clip(jnp.floor(x), 0, n - 2).astype(int)
    frac = jnp.clip(x - i, 0.0, 1.0)
    cols = jnp.arange(problem.inputs.shape[1])
    return problem.inputs[i, cols] * (1 - frac) + problem.inputs[i + 1, cols] * frac


def _window_solve(problem: OEMProblem, x0, theta, t_start, theta_end=None):
    """States at the window's samples and one step beyond, shape `(L + 1, states)`.

    With `theta_end` the parameters vary linearly in time from `theta` at `t_start`
    to `theta_end` one window later."""
    length = problem.window_samples
    span = length * problem.dt

    def field(t, x, args):
        th = _theta_at(args, t, span)
        return problem.rates(t, x, _input_at(problem, t, th), th)

    ts = t_start + problem.dt * jnp.arange(length + 1)
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(field),
        RK4(),
        t0=t_start,
        t1=ts[-1],
        dt0=problem.dt,
        y0=x0,
        args=(theta, theta_end, t_start),
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.ConstantStepSize(),
        adjoint=diffrax.ForwardMode(),
        max_steps=length + 2,
        throw=False,
    )
    return sol.ys, ts


def _theta_at(args, t, span):
    theta, theta_end, t_start = args
    if theta_end is None:
        return theta
    return theta + (theta_end - theta) * ((t - t_start) / span)


def full_parameters(problem, base, unknowns):
    """All parameters per set, shape `(sets, params)`: free ones from the unknowns."""
    return base.at[:, problem.free_index].set(unknowns.params)


def simulate_segments(problem, base, unknowns):
    """Model outputs for every padded sample and each segment's end state.

    **Returns:** `(outputs (segments, per_segment, outputs), end_states (segments,
    states), sample_index (segments, per_segment))`.
    """
    theta_all = full_parameters(problem, base, unknowns)
    k, length = problem.windows_per_segment, problem.window_samples

    def segment(s, x0):
        def step(x, j):
            w = s * k + j
            theta = theta_all[jnp.minimum(w, problem.n_param_sets - 1)]
            t_start = problem.t0 + w * length * problem.dt
            xs, ts = _window_solve(problem, x, theta, t_start)
            u = jax.vmap(lambda t: _input_at(problem, t, theta))(ts[:-1])
            y = jax.vmap(lambda t, x_, u_: problem.outputs(t, x_, u_, theta))(
                ts[:-1], xs[:-1], u
            )
            return xs[-1], y

        x_end, ys = jax.lax.scan(step, x0, jnp.arange(k))
        return ys.reshape(k * length, -1), x_end

    seg = jnp.arange(problem.n_segments)
    ys, ends = jax.vmap(segment)(seg, unknowns.nodes)
    index = seg[:, None] * (k * length) + jnp.arange(k * length)[None, :]
    return ys, ends, index


def _output_residuals(problem, base, unknowns):
    ys, ends, index = simulate_segments(problem, base, unknowns)
    valid = index < problem.n_samples
    measured = problem.measured[jnp.minimum(index, problem.n_samples - 1)]
    e = jnp.where(valid[..., None], measured - ys, 0.0)
    return e, valid, ends


def _defects(problem, unknowns, ends):
    if problem.n_segments == 1:
        return jnp.zeros((0, unknowns.nodes.shape[1]))
    scale = problem.state_scale
    if scale is None:
        scale = jnp.ones(unknowns.nodes.shape[1])
    return (ends[:-1] - unknowns.nodes[1:]) / (scale[None, :] * problem.continuity_tol)


def _whitening(r):
    """Lower-triangular W with W^T W = R^-1 (so W e has identity covariance)."""
    chol = jnp.linalg.cholesky(r)
    return jnp.linalg.inv(chol)


def _residual_vector(unknowns, args):
    problem, base, white, init_nodes = args
    e, _, ends = _output_residuals(problem, base, unknowns)
    ew = jnp.einsum("ij,snj->sni", white, e)
    parts = [ew.reshape(-1), _defects(problem, unknowns, ends).reshape(-1)]
    if not problem.free_initial_state:
        # the first node is known: pin it (its Jacobian column then stays regular)
        parts.append(1e6 * (unknowns.nodes[0] - init_nodes[0]))
    return jnp.concatenate(parts)


def _covariance(problem, e, valid):
    n = jnp.sum(valid)
    r = jnp.einsum("sni,snj->ij", e, e) / n
    if not problem.full_covariance:
        r = jnp.diag(jnp.diag(r))
    return r


class OEMResult(eqx.Module):
    """An output-error fit.

    **Fields:** `params` `(sets, params)` (all parameters, fixed ones at their given
    values); `stderr` `(sets, params)` Cramér-Rao standard errors (0 for fixed ones);
    `stderr_corrected` the same corrected for coloured residuals; `correlation`
    `(free, free)` for the first parameter set; `nodes` `(segments, states)`; `cost`
    det(R); `R` `(outputs, outputs)`; `outputs` `(samples, outputs)` the model
    outputs; `defect` the largest continuity defect relative to the state scale;
    `iterations` (outer R updates); `converged` (bool); `result` (optimistix result of
    the last inner solve); `tic` `(outputs,)` Theil's inequality coefficient per output
    (0 perfect, above about 0.3 a poor fit); `poor_fit` whether any output's TIC
    exceeds 0.3, which flags a fit that converged to a useless optimum (typical of
    single shooting on an unstable system).
    """

    params: Float[Array, "sets params"]
    stderr: Float[Array, "sets params"]
    stderr_corrected: Float[Array, "sets params"]
    correlation: Float[Array, "free free"]
    nodes: Float[Array, "segments states"]
    cost: Float[Array, ""]
    R: Float[Array, "outputs outputs"]
    outputs: Float[Array, "samples outputs"]
    defect: Float[Array, ""]
    iterations: Int[Array, ""]
    converged: Bool[Array, ""]
    result: optx.RESULTS
    tic: Float[Array, " outputs"]
    poor_fit: Bool[Array, ""]


def theil_inequality(measured, outputs):
    """Theil's inequality coefficient per output column, `(outputs,)`: 0 a perfect
    fit, above about 0.3 a poor one."""

    def rms(a):
        return jnp.sqrt(jnp.mean(a**2, axis=0))

    return rms(measured - outputs) / (rms(measured) + rms(outputs))


def _coloured_information(jw, vw):
    """Sum over lags of residual autocorrelation times Jacobian cross-correlation,
    per output channel (Morelli and Klein's correction), by FFT.

    `jw`: `(samples, outputs, unknowns)` whitened Jacobian rows; `vw`: `(samples,
    outputs)` whitened residuals. Returns `(unknowns, unknowns)`.
    """
    n = jw.shape[0]
    m = 2 * n
    a = jnp.fft.fft(jw, n=m, axis=0)  # (m, outputs, P)
    v = jnp.fft.fft(vw, n=m, axis=0)  # (m, outputs)
    power = jnp.abs(v) ** 2 / n  # spectrum of the autocorrelation estimate
    total = jnp.einsum("fo,fop,foq->pq", power, jnp.conj(a), a) / m
    return jnp.real(total)


@functools.partial(jax.jit, static_argnames=("max_outer", "max_inner"))
def _fit(problem, base, unknowns0, rtol, max_outer, max_inner):
    solver = HalvingGaussNewton(rtol=rtol, atol=1e-12)
    init_nodes = unknowns0.nodes

    def solve(unknowns, white):
        sol = optx.least_squares(
            _residual_vector,
            solver,
            unknowns,
            args=(problem, base, white, init_nodes),
            max_steps=max_inner,
            throw=False,
        )
        return sol.value, sol.result

    e0, valid0, _ = _output_residuals(problem, base, unknowns0)
    r0 = _covariance(problem, e0, valid0)
    r0 = r0 + 1e-12 * jnp.eye(r0.shape[0])

    def cond(carry):
        _, _, _, it, done, _ = carry
        return (it < max_outer) & ~done

    def body(carry):
        unknowns, r, cost_prev, it, _, _ = carry
        new, result = solve(unknowns, _whitening(r))
        e, valid, _ = _output_residuals(problem, base, new)
        r_new = _covariance(problem, e, valid) + 1e-300 * jnp.eye(r.shape[0])
        cost = jnp.linalg.det(r_new)
        done = jnp.abs(cost_prev - cost) <= rtol * jnp.abs(cost)
        return new, r_new, cost, it + 1, done, result

    init = (
        unknowns0,
        r0,
        jnp.linalg.det(r0),
        jnp.array(0),
        jnp.array(False),
        optx.RESULTS.successful,
    )
    unknowns, r, cost, iterations, done, result = jax.lax.while_loop(cond, body, init)

    # Uncertainty at the optimum: Fisher information of the whitened residuals.
    white = _whitening(r)
    args = (problem, base, white, init_nodes)
    flat, unflatten = jax.flatten_util.ravel_pytree(unknowns)
    jac = jax.jacfwd(lambda z: _residual_vector(unflatten(z), args))(flat)
    info = jac.T @ jac
    cov = jnp.linalg.pinv(info, hermitian=True)
    e, valid, ends = _output_residuals(problem, base, unknowns)
    n_out = e.shape[-1]
    n_rows = e.shape[0] * e.shape[1]
    jw = jac[: n_rows * n_out].reshape(n_rows, n_out, -1)
    vw = jnp.einsum("ij,snj->sni", white, e).reshape(n_rows, n_out)
    keep = valid.reshape(-1)
    jw = jnp.where(keep[:, None, None], jw, 0.0)
    vw = jnp.where(keep[:, None], vw, 0.0)
    # Chronological order of padded rows is already by segment then sample.
    coloured = cov @ _coloured_information(jw, vw) @ cov
    n_free = unknowns.params.size
    sd = jnp.sqrt(jnp.clip(jnp.diag(cov)[:n_free], 0.0))
    sd_c = jnp.sqrt(jnp.clip(jnp.diag(coloured)[:n_free], 0.0))
    sets, nf = unknowns.params.shape
    stderr = jnp.zeros_like(base).at[:, problem.free_index].set(sd.reshape(sets, nf))
    stderr_c = (
        jnp.zeros_like(base).at[:, problem.free_index].set(sd_c.reshape(sets, nf))
    )
    block = cov[:nf, :nf]
    d = jnp.sqrt(jnp.clip(jnp.diag(block), 1e-300))
    correlation = block / (d[:, None] * d[None, :])
    defects = _defects(problem, unknowns, ends)
    defect = (
        jnp.max(jnp.abs(defects)) * problem.continuity_tol
        if defects.size
        else jnp.zeros(())
    )
    ys, _, index = simulate_segments(problem, base, unknowns)
    outputs = ys.reshape(-1, ys.shape[-1])[: problem.n_samples]
    tic = theil_inequality(problem.measured, outputs)
    tic = jnp.where(jnp.isfinite(tic), tic, 1.0)
    finite = jnp.isfinite(cost) & jnp.all(jnp.isfinite(unknowns.params))
    converged = done & finite & (result == optx.RESULTS.successful)
    return OEMResult(
        params=full_parameters(problem, base, unknowns),
        stderr=stderr,
        stderr_corrected=stderr_c,
        correlation=correlation,
        nodes=unknowns.nodes,
        cost=cost,
        R=r,
        outputs=outputs,
        defect=defect,
        iterations=iterations,
        converged=converged,
        result=result,
        tic=tic,
        poor_fit=jnp.any(tic > 0.3),
    )


def fit_oem(
    problem: OEMProblem,
    theta0: Float[Array, " params"] | Float[Array, "sets params"],
    nodes0: Float[Array, "segments states"],
    *,
    rtol: float = 1e-5,
    max_outer: int = 30,
    max_inner: int = 50,
) -> OEMResult:
    """Maximum-likelihood output-error estimate.

    **Arguments:**

    - `problem`: the [`OEMProblem`][].
    - `theta0`: starting parameters, `(params,)` (the same for every window) or
      `(sets, params)`; fixed parameters keep these values.
    - `nodes0`: starting node states `(segments, states)`, usually the measured states
      at the node times; the first is kept fixed unless `free_initial_state`.
    - `rtol`: stop when det(R) changes by less than this, relatively.
    - `max_outer`, `max_inner`: caps on R updates and Gauss-Newton steps per update.

    **Returns:** an [`OEMResult`][]; a fit that did not converge or diverged has
    `converged = False` (it never raises inside a batch). `jax.vmap` over problems
    and starting values fits a batch in one call.
    """
    theta0 = jnp.asarray(theta0, float)
    if theta0.ndim == 1:
        theta0 = jnp.broadcast_to(theta0, (problem.n_param_sets, theta0.shape[0]))
    nodes0 = jnp.asarray(nodes0, float)
    if nodes0.shape[0] != problem.n_segments:
        raise ValueError(
            f"nodes0 has {nodes0.shape[0]} rows but the problem has "
            f"{problem.n_segments} shooting segments"
        )
    unknowns0 = Unknowns(params=theta0[:, problem.free_index], nodes=nodes0)
    return _fit(problem, theta0, unknowns0, rtol, max_outer, max_inner)


def node_times(problem: OEMProblem) -> np.ndarray:
    """Sample index of every shooting node."""
    per = problem.windows_per_segment * problem.window_samples
    return np.arange(problem.n_segments) * per


def parameter_table(
    names: list[str], estimate, stderr, free=None
) -> list[dict[str, float | str | None]]:
    """Rows of estimate, standard error, relative error (%) and 95% interval."""
    rows = []
    for i, name in enumerate(names):
        est, sd = float(estimate[i]), float(stderr[i])
        fixed = free is not None and not free[i]
        rows.append(
            {
                "parameter": name,
                "estimate": est,
                "stderr": None if fixed else sd,
                "relative_stderr_percent": None
                if fixed or est == 0
                else 100 * sd / abs(est),
                "ci95_low": None if fixed else est - 1.96 * sd,
                "ci95_high": None if fixed else est + 1.96 * sd,
            }
        )
    return rows


def format_parameter_table(rows) -> str:
    """A fixed-width table a flight-test engineer reads."""
    lines = [
        f"{'parameter':>10s} {'estimate':>13s} {'std. error':>12s} {'rel. %':>8s} "
        f"{'95% interval':>29s}"
    ]
    for r in rows:
        if r["stderr"] is None:
            lines.append(
                f"{r['parameter']:>10s} {r['estimate']:13.6g} {'(fixed)':>12s}"
            )
            continue
        rel = r["relative_stderr_percent"]
        lines.append(
            f"{r['parameter']:>10s} {r['estimate']:13.6g} {r['stderr']:12.4g} "
            f"{(rel if rel is not None else float('nan')):8.2f} "
            f"[{r['ci95_low']:12.6g}, {r['ci95_high']:12.6g}]"
        )
    return "\n".join(lines)
