"""Output error with parameters global over a record, on the one engine, and a score
test for parameters held at zero.

[`fit_global_oem`][] takes the [`OEMProblem`][] form (vector parameters, one record,
single shooting, or multiple shooting every `node_interval` samples with all nodes
estimated) and solves it with the engine of `diffpegasus._estimate`: a structured Levenberg-Marquardt over
exact per-segment Jacobian blocks. Which parameters are estimated is a traced mask,
so fits with different free sets (the baseline, the baseline plus an effect) reuse
one compiled program, and the score test of the held parameters at the optimum
comes from the same blocks.
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .._cache import kept_call
from ._engine import iteration_bound, Layout, RESULTS, solve
from ._oem import OEMProblem, theil_inequality
from ._score import score, ScoreTest


class VectorModel(eqx.Module):
    """An [`OEMProblem`][]'s model functions, which take the parameters as a
    vector, in the engine's model interface."""

    rates: object = eqx.field(static=True)
    outputs: object = eqx.field(static=True)
    delay: object = eqx.field(static=True)

    def f(self, t, x, u, theta):
        return self.rates(t, x, u, theta)

    def g(self, t, x, u, theta):
        return self.outputs(t, x, u, theta)

    def input_delays(self, theta):
        return None if self.delay is None else self.delay(theta)


class GlobalFit(eqx.Module):
    """Result of [`fit_global_oem`][].

    **Fields:** `params` `(params,)` (fixed ones at their given values); `free`;
    `stderr` (Cramér-Rao) and `stderr_corrected` (Morelli-Klein correction for
    coloured residuals, never below `stderr`), 0 for fixed parameters;
    `correlation` `(params, params)` (fixed rows 0); `nodes` `(segments, states)`;
    `cost` det(R); `R` `(outputs,)` diagonal; `outputs` `(samples, outputs)`;
    `defect` largest continuity defect relative to the state scale; `iterations`;
    `converged`; `result` the engine's [`RESULTS`][] code; `tic` `(outputs,)`
    Theil's inequality coefficient.
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
    result: RESULTS
    tic: Float[Array, " outputs"]


def _layout(problem: OEMProblem, n_seg: int, nx: int) -> Layout:
    per = problem.window_samples
    index = np.arange(n_seg)[:, None] * per + np.arange(per)[None, :]
    valid = index < problem.n_samples
    measured = problem.measured[jnp.minimum(jnp.asarray(index), problem.n_samples - 1)]
    node_free = np.ones((n_seg, nx), bool)
    node_free[0] = problem.free_initial_state or problem.node_interval is not None
    scale = problem.state_scale
    if scale is None:
        scale = jnp.ones(nx)
    return Layout(
        inputs=problem.inputs[None],
        t0=jnp.asarray(problem.t0, float)[None],
        dt=jnp.asarray([problem.dt], float),
        n=jnp.asarray([problem.inputs.shape[0]]),
        record=jnp.zeros(n_seg, int),
        first=jnp.asarray(np.arange(n_seg) * per),
        measured=jnp.where(jnp.asarray(valid)[..., None], measured, 0.0),
        valid=jnp.asarray(valid),
        link=jnp.ones(n_seg - 1, bool),
        scale=scale * problem.continuity_tol,
        node_free=jnp.asarray(node_free),
        length=per,
        bias_channels=(),
    )


@functools.partial(jax.jit, static_argnames=("max_iter",))
def _fit(problem, theta0, nodes0, free, rtol, max_iter):
    n_seg, nx = nodes0.shape
    p = theta0.shape[0]
    model = VectorModel(problem.rates, problem.outputs, problem.input_delay)
    layout = _layout(problem, n_seg, nx)
    z0 = jnp.concatenate([nodes0.reshape(-1), theta0])
    sol = solve(model, layout, z0, free, nx=nx, p=p, rtol=rtol, max_iter=max_iter)
    ns = n_seg * nx
    cov = sol.covariance[ns:, ns:]
    sd = jnp.sqrt(jnp.clip(jnp.diag(cov), 0.0))
    sd_c = jnp.sqrt(jnp.clip(jnp.diag(sol.corrected[ns:, ns:]), 0.0))
    dd = jnp.sqrt(jnp.clip(jnp.diag(cov), 1e-300))
    outputs = sol.outputs.reshape(-1, sol.outputs.shape[-1])[: problem.n_samples]
    return GlobalFit(
        params=sol.z[ns:],
        free=free,
        stderr=sd,
        stderr_corrected=jnp.maximum(sd_c, sd),
        correlation=cov / (dd[:, None] * dd[None, :]),
        nodes=sol.z[:ns].reshape(n_seg, nx),
        cost=sol.cost,
        R=sol.R,
        outputs=outputs,
        defect=sol.defect * problem.continuity_tol,
        iterations=sol.iterations,
        converged=sol.result == RESULTS.successful,
        result=sol.result,
        tic=theil_inequality(problem.measured, outputs),
    )


def _as_array(x, dtype):
    """A traced value as a jax array, a concrete one as numpy (`jnp.asarray` of a
    concrete value compiles a small program per shape in JAX 0.10)."""
    if isinstance(x, jax.core.Tracer):
        return jnp.asarray(x, dtype)
    return np.asarray(x, dtype)


def fit_global_oem(
    problem: OEMProblem,
    theta0: Float[Array, " params"],
    nodes0: Float[Array, "segments states"],
    free: Bool[Array, " params"] | None = None,
    *,
    rtol: float = 1e-5,
    max_iter: int | None = None,
) -> GlobalFit:
    """Output error with one parameter set for the record: multiple shooting (all
    node states estimated) when `problem.node_interval` is set, else single
    shooting from `nodes0[0]` (held unless `problem.free_initial_state`).

    **Arguments:** `problem` with `window=None` (and `state_scale` for multiple
    shooting); `theta0` `(params,)` starting (and fixed) values; `nodes0`
    `(segments, states)` starting node states; `free` which parameters to estimate
    (an array: changing it does not recompile; default `problem.free`); `rtol` the
    relative change of det(R) that ends the iteration; `max_iter` an iteration bound
    (default `None`: to convergence, within the engine's adaptive budget).

    **Returns:** a [`GlobalFit`][]. Pure and jitted; `jax.vmap` batches it.
    """
    if problem.window is not None:
        raise ValueError("fit_global_oem needs window=None (one parameter set)")
    if problem.node_interval is not None and problem.state_scale is None:
        raise ValueError("multiple shooting needs the problem's state_scale")
    theta0 = _as_array(theta0, float)
    free = _as_array(problem.free if free is None else free, bool)
    nodes0 = _as_array(nodes0, float)
    if nodes0.shape[0] != problem.n_segments:
        raise ValueError(
            f"nodes0 has {nodes0.shape[0]} rows but the problem has "
            f"{problem.n_segments} shooting segments"
        )
    # through the cache's kept programs: a later process skips tracing (when the
    # model functions are values of the package, e.g. the discrepancy model's)
    return kept_call(
        _fit,
        {"max_iter": iteration_bound(max_iter)},
        {
            "problem": problem,
            "theta0": theta0,
            "nodes0": nodes0,
            "free": free,
            "rtol": np.asarray(rtol, float),
        },
    )


@jax.jit
def _score(problem, fit, candidates):
    n_seg, nx = fit.nodes.shape
    model = VectorModel(problem.rates, problem.outputs, problem.input_delay)
    z = jnp.concatenate([fit.nodes.reshape(-1), fit.params])
    return score(
        model,
        _layout(problem, n_seg, nx),
        z,
        fit.R,
        fit.free,
        candidates,
        nx=nx,
        p=fit.params.shape[0],
    )


def score_test(problem: OEMProblem, fit: GlobalFit, candidates) -> ScoreTest:
    """Score test of the parameters `candidates` (indices, held fixed in `fit`)."""
    return kept_call(
        _score,
        {},
        {"problem": problem, "fit": fit, "candidates": np.asarray(candidates, int)},
    )
