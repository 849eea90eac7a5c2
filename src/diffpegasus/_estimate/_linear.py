"""A model file read as a linear system: `x' = A x + B u + c`, `y = C x + D u + d`.

The frequency-domain estimators need a [`Model`][] whose `rates` and `observe` are
linear (affine) in the states and inputs. That holds iff their Jacobians with respect
to `x` and `u` are constant, so [`linear_system`][] takes `A, B, C, D` by forward-mode
differentiation (`jax.jacfwd`) at one point and [`check_linear`][] verifies them at
another: a model that is not linear gets one clear error naming the function and the
entry that changed. The constant parts `c, d` (trim values, biases) have no transform
on the frequency grid, so they never enter.

The matrices are functions of the parameters (any smooth dependence: `U0 + Zq` is
fine); equation error also needs them linear in the parameters, which
[`check_linear_in_parameters`][] verifies the same way.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._model import Model, Record


def linear_system(model: Model, theta, t=0.0):
    """`A (nx, nx), B (nx, nu), C (ny, nx), D (ny, nu)` of `model` at the parameter
    vector `theta` `(params,)`: the Jacobians of `rates` and `observe` at `x = 0`,
    `u = 0` (any point: the model is linear in them)."""
    nx, nu = len(model.states), len(model.inputs)
    x = jnp.zeros(nx)
    u = jnp.zeros(nu)

    def jac(fn):
        return jax.jacfwd(lambda xu: fn(t, xu[:nx], xu[nx:], theta))(
            jnp.concatenate([x, u])
        )

    jf, jg = jac(model.f), jac(model.g)
    return jf[:, :nx], jf[:, nx:], jg[:, :nx], jg[:, nx:]


@eqx.filter_jit
def system_jacobian(model: Model, theta):
    """`(A, B, C, D)` at `theta` and their Jacobians with respect to it, each
    `(..., params)`: one compiled program per model."""
    return linear_system(model, theta), jax.jacfwd(lambda th: linear_system(model, th))(
        theta
    )


@eqx.filter_jit
def _state_input_jacobians(model: Model, theta, t, x, u):
    nx = len(model.states)

    def jac(fn):
        return jax.jacfwd(lambda xu: fn(t, xu[:nx], xu[nx:], theta))(
            jnp.concatenate([x, u])
        )

    return jac(model.f), jac(model.g)


def _points(model: Model, record: Record | None):
    """Two (t, x, u) points to compare the Jacobians at: the record's first and a
    middle sample (unmeasured states 0 and 1), or two fixed points."""
    nx, nu = len(model.states), len(model.inputs)
    if record is None:
        return (
            (0.0, np.full(nx, 0.3), np.full(nu, 0.2)),
            (1.0, np.linspace(-1.1, 0.7, nx), np.linspace(0.9, -0.4, nu)),
        )
    i = len(record.t) // 2
    x = record.measured_states(model, [0, i])
    x[0] = np.where(np.isnan(x[0]), 0.0, x[0])
    x[1] = np.where(np.isnan(x[1]), 1.0, x[1])
    u = record.inputs[[0, i]]
    # distinct points even on a record that starts at rest
    x[1] = x[1] + 0.1 * np.maximum(np.abs(x[1]), 1.0)
    u = u.copy()
    u[1] = u[1] + 0.1 * np.maximum(np.abs(u[1]), 1.0)
    return (record.t[0], x[0], u[0]), (record.t[i], x[1], u[1])


def check_linear(model: Model, theta, record: Record | None = None) -> None:
    """Raise a `ValueError` unless `rates` and `observe` are linear (affine) in the
    states and inputs, with coefficients constant in time: their Jacobians at two
    points (from `record` when given) must agree."""
    names = (*model.states, *model.inputs)
    theta = jnp.asarray(theta, float)
    (ta, xa, ua), (tb, xb, ub) = _points(model, record)
    model = model.structure()
    at_a = _state_input_jacobians(model, theta, ta, jnp.asarray(xa), jnp.asarray(ua))
    at_b = _state_input_jacobians(model, theta, tb, jnp.asarray(xb), jnp.asarray(ub))
    for what, ja, jb, rows in (
        ("rates", at_a[0], at_b[0], model.states),
        ("observe", at_a[1], at_b[1], model.outputs),
    ):
        ja, jb = np.asarray(ja), np.asarray(jb)
        if not (np.all(np.isfinite(ja)) and np.all(np.isfinite(jb))):
            raise ValueError(
                f"{what}(t, x, u, p) has a non-finite derivative with respect to the "
                "states or inputs: frequency-domain estimation needs a model linear "
                "in them"
            )
        scale = np.maximum(np.abs(ja), np.abs(jb)).max(axis=1, keepdims=True)
        bad = np.abs(ja - jb) > 1e-7 * np.maximum(scale, 1e-12)
        if bad.any():
            i, j = np.argwhere(bad)[0]
            raise ValueError(
                f"{what}(t, x, u, p) is not linear in the states and inputs: "
                f"d {rows[i]} / d {names[j]} is {ja[i, j]:.6g} at t = {ta:g} s and "
                f"{jb[i, j]:.6g} at t = {tb:g} s; frequency-domain estimation needs "
                "x' = A x + B u + c, y = C x + D u + d with constant A, B, C, D "
                "(linearise the model about the trim of the manoeuvre)"
            )


def parameter_sensitivity(model: Model, theta) -> np.ndarray:
    """`(params,)` bool: which parameters change `A, B, C, D` at `theta` (the others,
    such as biases and trim constants, have no effect on the frequency grid)."""
    theta = jnp.asarray(theta, float)
    _, jac = system_jacobian(model.structure(), theta)
    total = sum(np.abs(np.asarray(j)).reshape(-1, len(theta)).sum(0) for j in jac)
    return total > 0


def check_linear_in_parameters(model: Model, theta, which) -> None:
    """Raise a `ValueError` unless `A, B, C, D` are linear (affine) in the
    parameters flagged in `which` `(params,)` bool: equation error solves for them
    by least squares."""
    theta = np.asarray(theta, float)
    which = np.asarray(which, bool)
    step = 0.3 * np.maximum(np.abs(theta), 1.0) * which
    _, ja = system_jacobian(model.structure(), jnp.asarray(theta))
    _, jb = system_jacobian(model.structure(), jnp.asarray(theta + step))
    for a, b, label in zip(ja, jb, "ABCD", strict=True):
        a, b = np.asarray(a)[..., which], np.asarray(b)[..., which]
        scale = max(np.abs(a).max(initial=0.0), np.abs(b).max(initial=0.0), 1e-300)
        if np.max(np.abs(a - b), initial=0.0) > 1e-7 * scale:
            k = int(np.argwhere(np.abs(a - b) > 1e-7 * scale)[0][-1])
            name = np.asarray(model.parameters)[which][k]
            raise ValueError(
                f"the model's {label} matrix is not linear in the parameter {name!r}: "
                "frequency-domain equation error solves a least-squares problem; use "
                "output error (method 'fdoe') or write the model with that parameter "
                "entering linearly"
            )
