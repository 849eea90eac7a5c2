"""The output-error engine's step as an optimistix least-squares solver.

[`BlockLevenbergMarquardt`][] is an `optimistix.AbstractLeastSquaresSolver`: run by
`optx.least_squares(output_error_residuals, solver, z0, args=problem)` it minimises
the R-weighted output-error cost `sum e^2 / R + sum d^2` of an
[`OutputErrorProblem`][] (R fixed) with the engine's structured Levenberg-Marquardt
step: each shooting segment's Jacobian in its own `nodes + theta + biases` unknowns
(forward mode), the normal equations assembled from those blocks, a damped Cholesky
solve, damping raised tenfold until the cost falls. The residual function `fn` is
what optimistix sees (trial costs, its adjoints: `optx.ImplicitAdjoint`
differentiates the estimate through `fn`); the block Jacobian comes from the
problem in `args`, which must be the one `fn` evaluates.

The maximum-likelihood cost det(R) relaxes R between steps;
[`solve_with_optimistix`][] is that outer loop around `optx.least_squares` (one
solver step per R, as the engine's own loop in [`solve`][] does), returning the
engine's [`Solution`][], so `dp.OutputError(solver=dp.BlockLevenbergMarquardt())`
fits through optimistix.
"""

import functools
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx
from jaxtyping import Array, Bool, Float, Int, PyTree, Scalar

from .._model import Model
from ._engine import (
    _cost,
    assemble,
    channel_variance,
    damped_step,
    evaluate,
    finish,
    first_iterate,
    Iterate,
    residuals_at,
    Solution,
)


class OutputErrorProblem(eqx.Module):
    """The `args` of [`output_error_residuals`][] and [`BlockLevenbergMarquardt`][]:
    the model (static), the records cut into segments (`layout`), the diagonal of
    R `(outputs,)` the output residuals are whitened by, which unknowns are `free`
    `(unknowns,)`, and the numbers of states `nx` and parameters `p`."""

    model: Model = eqx.field(static=True)
    layout: Any
    r: Float[Array, " outputs"]
    free: Bool[Array, " unknowns"]
    nx: int = eqx.field(static=True)
    p: int = eqx.field(static=True)


def output_error_residuals(z, problem: OutputErrorProblem):
    """Whitened output residuals `(segments, length, outputs)` (0 at padding) and
    continuity defects `(segments - 1, states)` at the unknowns `z` `(unknowns,)`:
    `sum` of their squares is the R-weighted output-error cost."""
    e, d, _ = residuals_at(problem.model, problem.layout, z, problem.nx, problem.p)
    return e / jnp.sqrt(problem.r)[None, None, :], d


class _BlockState(eqx.Module):
    damping: Scalar
    change: Scalar
    done: Bool[Array, ""]
    broken: Bool[Array, ""]
    # the last linearisation (at the point the last step started from) and the
    # accepted point's residuals: what the statistics and R's update need
    information: Float[Array, "unknowns unknowns"]
    jacobian: Float[Array, "segments length outputs local"]
    whitened: Float[Array, "segments length outputs"]
    residual: PyTree[Array]
    steps: Int[Array, ""]


class BlockLevenbergMarquardt(optx.AbstractLeastSquaresSolver):
    """Levenberg-Marquardt on the block-bordered normal equations of output error.

    **Fields:**

    - `rtol`: converged when the cost changes by less than this, relatively.
    - `atol`, `norm`: optimistix's solver contract (`atol` is unused: the cost's
      scale is the data's).

    **Options** (`options=` of `optx.least_squares`): `"damping"`, the start value
    of the damping (default 0: a Gauss-Newton step first).

    `args` must be the [`OutputErrorProblem`][] that `fn` evaluates
    ([`output_error_residuals`][]); unknowns not `free` in it are held.
    """

    rtol: float = 1e-10
    atol: float = 0.0
    norm: Callable[[PyTree], Scalar] = optx.max_norm

    def init(self, fn, y, args, options, f_struct, aux_struct, tags):
        del fn, aux_struct, tags
        n = y.shape[0]
        lay = args.layout
        k = lay.local_columns(args.nx, args.p).shape[1]
        shape = lay.measured.shape
        return _BlockState(
            damping=jnp.asarray(options.get("damping", 0.0), float),
            change=jnp.array(jnp.inf),
            done=jnp.array(False),
            broken=jnp.array(False),
            information=jnp.zeros((n, n)),
            jacobian=jnp.zeros((*shape, k)),
            whitened=jnp.zeros(shape),
            residual=jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), f_struct),
            steps=jnp.array(0),
        )

    def step(self, fn, y, args, options, state, tags):
        del options, tags
        prob = args
        nx, p = prob.nx, prob.p
        ev = evaluate(prob.model, prob.layout, y, nx, p)
        h, g, jyw, ew = assemble(prob.layout, ev, y.shape[0], nx, p, prob.r)
        j0 = _cost(ev.e, ev.d, prob.r)

        def sum_squares(res):
            return sum(jnp.sum(x**2) for x in jax.tree.leaves(res))

        def cost_at(new):
            res, aux = fn(new, args)
            return sum_squares(res), res, aux

        struct = jax.eval_shape(lambda: fn(y, args))
        zeros = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), struct)
        damping, new, j1, (res1, aux1), accepted = damped_step(
            h, g, prob.free, y, state.damping, j0, cost_at, zeros
        )
        broken = ~(jnp.all(jnp.isfinite(h)) & jnp.all(jnp.isfinite(g)))
        change = jnp.abs(j0 - j1) / jnp.abs(j1)
        done = ~accepted | broken | (change <= self.rtol)
        whitened_now = (ev.e / jnp.sqrt(prob.r)[None, None, :], ev.d)
        residual = jax.tree.map(
            lambda a, b: jnp.where(accepted, a, b), res1, whitened_now
        )
        new_state = _BlockState(
            damping=damping / 10.0,
            change=jnp.where(accepted, change, 0.0),
            done=done,
            broken=broken,
            information=h,
            jacobian=jyw,
            whitened=ew,
            residual=residual,
            steps=state.steps + 1,
        )
        return new, new_state, aux1

    def terminate(self, fn, y, args, options, state, tags):
        del fn, y, args, options, tags
        result = optx.RESULTS.where(
            state.broken, optx.RESULTS.nonlinear_divergence, optx.RESULTS.successful
        )
        return state.done, result

    def postprocess(self, fn, y, aux, args, options, state, tags, result):
        del fn, args, options, state, tags, result
        return y, aux, {}


@functools.partial(jax.jit, static_argnames=("model", "nx", "p", "coloured", "solver"))
def solve_with_optimistix(
    model,
    layout,
    z0,
    free_params,
    *,
    nx,
    p,
    rtol,
    max_iter,
    solver: BlockLevenbergMarquardt,
    coloured=True,
) -> Solution:
    """Minimise det(R) over the free unknowns from `z0` as [`solve`][] does, each
    step one `optx.least_squares(output_error_residuals, solver, ...)` step at the
    current R (the relaxation of det(R)), the damping carried between them.
    Returns the engine's [`Solution`][]."""
    free = layout.free_columns(free_params, nx, p)
    e0, _, _ = residuals_at(model, layout, z0, nx, p)
    r0 = channel_variance(layout, e0)

    def body(c):
        state, damping = c
        z, r = state.z, state.r
        prob = OutputErrorProblem(
            model=model, layout=layout, r=r, free=free, nx=nx, p=p
        )
        sol = optx.least_squares(
            output_error_residuals,
            solver,
            z,
            args=prob,
            options={"damping": damping},
            max_steps=1,
            throw=False,
        )
        st = sol.state
        ew, d = st.residual
        e = ew * jnp.sqrt(r)[None, None, :]
        r_new = channel_variance(layout, e)
        cost = jnp.prod(r_new)
        cost_prev = state.cost
        small = (jnp.abs(cost_prev - cost) <= rtol * jnp.abs(cost)) | (cost == 0)
        accepted = jnp.any(sol.value != z)
        r_new = jnp.where(accepted, r_new, r)
        cost = jnp.where(accepted, cost, cost_prev)
        broken = st.broken | ~jnp.all(jnp.isfinite(r_new))
        state = Iterate(
            z=sol.value,
            r=r_new,
            cost=cost,
            iterations=state.iterations + 1,
            done=small | ~accepted | broken,
            broken=broken,
            information=st.information,
            jacobian=st.jacobian,
            whitened=st.whitened,
            defects=d,
            # the accepted point's outputs from its residuals (whitened by the R
            # before it)
            outputs=jnp.where(layout.valid[..., None], layout.measured - e, 0.0),
            change=jnp.abs(cost_prev - cost) / jnp.abs(cost),
        )
        return state, st.damping

    start = first_iterate(
        layout,
        z0,
        r0,
        jnp.prod(r0),
        ~jnp.all(jnp.isfinite(r0)),
        jnp.where(layout.valid[..., None], layout.measured, 0.0),
        nx,
        p,
    )
    state, _ = jax.lax.while_loop(
        lambda c: (c[0].iterations < max_iter) & ~c[0].done & ~c[0].broken,
        body,
        (start, jnp.array(0.0)),
    )
    return finish(layout, state, free, nx=nx, p=p, coloured=coloured)
