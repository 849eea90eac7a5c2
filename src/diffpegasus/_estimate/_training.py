"""Levenberg-Marquardt training of any equinox model, in the manner of MATLAB's
`trainlm`.

Each epoch forms the exact Jacobian of the training residuals with respect to the
flattened trainable (inexact-array) leaves, accumulates `J^T J` and `J^T r` over
chunks of the training set (so memory is bounded by the chunk, not the data), and
solves the damped normal equations `(J^T J + mu I) dw = -J^T r`. A step that lowers
the training cost is taken and `mu` is divided by `mu_decrease`; a step that does not
is rejected and `mu` multiplied by `mu_increase`, up to `max_tries` times per epoch.
Training stops after `max_epochs`, when `mu` exceeds `mu_max`, or when the validation
error has not improved for `patience` epochs (the best-validation weights are
returned).
"""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.flatten_util
import jax.numpy as jnp
from jaxtyping import Array, Float, PyTree


class TrainingHistory(eqx.Module):
    """Per-epoch mean-squared errors (`train`, `validation`, `test`; NaN after the
    last epoch), damping `mu`, and `epochs` run."""

    train: Float[Array, " epochs"]
    validation: Float[Array, " epochs"]
    test: Float[Array, " epochs"]
    mu: Float[Array, " epochs"]
    epochs: Array


def _mse(model, x, y):
    pred = jax.vmap(model)(x)
    return jnp.mean((pred - y) ** 2)


def train_levenberg_marquardt(
    model: PyTree,
    train: tuple[Float[Array, "n in"], Float[Array, "n out"]],
    validation: tuple[Float[Array, "m in"], Float[Array, "m out"]] | None = None,
    test: tuple[Float[Array, "k in"], Float[Array, "k out"]] | None = None,
    *,
    max_epochs: int = 1000,
    patience: int = 6,
    mu: float = 1e-3,
    mu_increase: float = 10.0,
    mu_decrease: float = 10.0,
    mu_max: float = 1e10,
    max_tries: int = 10,
    chunk: int = 4096,
    loss_fn: Callable | None = None,
) -> tuple[PyTree, TrainingHistory]:
    """Train `model` (any equinox Module mapping one input to one output) by LM.

    **Arguments:** the model; `(inputs, targets)` for training, validation and test
    (validation drives early stopping; test is only reported); the damping schedule;
    `chunk`, samples per Jacobian block.

    **Returns:** the best model (lowest validation error, or the last one without a
    validation set) and a [`TrainingHistory`][].
    """
    params, static = eqx.partition(model, eqx.is_inexact_array)
    flat0, unravel = jax.flatten_util.ravel_pytree(params)
    x_tr, y_tr = train
    n = x_tr.shape[0]
    n_chunks = -(-n // chunk)
    pad = n_chunks * chunk - n
    xc = jnp.concatenate([x_tr, jnp.zeros((pad, *x_tr.shape[1:]))]).reshape(
        n_chunks, chunk, -1
    )
    yc = jnp.concatenate([y_tr, jnp.zeros((pad, *y_tr.shape[1:]))]).reshape(
        n_chunks, chunk, -1
    )
    mc = (jnp.arange(n_chunks * chunk) < n).reshape(n_chunks, chunk).astype(flat0.dtype)

    def residuals(flat, x, y, m):
        m_ = eqx.combine(unravel(flat), static)
        return ((jax.vmap(m_)(x) - y) * m[:, None]).reshape(-1)

    def normal_equations(flat):
        def body(carry, c):
            jtj, jtr, sse = carry
            x, y, m = c
            r = residuals(flat, x, y, m)
            j = jax.jacfwd(residuals)(flat, x, y, m)
            return (jtj + j.T @ j, jtr + j.T @ r, sse + r @ r), None

        p = flat.shape[0]
        init = (jnp.zeros((p, p)), jnp.zeros(p), jnp.zeros(()))
        (jtj, jtr, sse), _ = jax.lax.scan(body, init, (xc, yc, mc))
        return jtj, jtr, sse

    def cost(flat):
        def body(s, c):
            x, y, m = c
            r = residuals(flat, x, y, m)
            return s + r @ r, None

        return jax.lax.scan(body, jnp.zeros(()), (xc, yc, mc))[0]

    n_out = y_tr.shape[-1]

    def mse_of(flat, data):
        if data is None:
            return jnp.nan
        return _mse(eqx.combine(unravel(flat), static), *data)

    @jax.jit
    def epoch(state):
        flat, mu_, best_flat, best_val, since_best, k, hist, stop = state
        jtj, jtr, sse = normal_equations(flat)
        eye = jnp.eye(jtj.shape[0])

        def try_step(c):
            mu_t, _, _, tries = c
            dw = jnp.linalg.solve(jtj + mu_t * eye, -jtr)
            new = flat + dw
            ok = cost(new) < sse
            return jnp.where(ok, mu_t, mu_t * mu_increase), new, ok, tries + 1

        mu_new, new_flat, ok, _ = jax.lax.while_loop(
            lambda c: (~c[2]) & (c[3] < max_tries) & (c[0] < mu_max),
            try_step,
            (mu_, flat, jnp.array(False), jnp.array(0)),
        )
        flat = jnp.where(ok, new_flat, flat)
        mu_new = jnp.where(ok, mu_new / mu_decrease, mu_new)
        tr = cost(flat) / (n * n_out)
        va = mse_of(flat, validation)
        te = mse_of(flat, test)
        improved = (va < best_val) if validation is not None else jnp.array(True)
        best_flat = jnp.where(improved, flat, best_flat)
        best_val = jnp.where(improved, va, best_val)
        since_best = jnp.where(improved, 0, since_best + 1)
        hist = jax.tree_util.tree_map(
            lambda h, v: h.at[k].set(v), hist, (tr, va, te, mu_new)
        )
        stop = (~ok) | (mu_new >= mu_max) | (since_best >= patience)
        return flat, mu_new, best_flat, best_val, since_best, k + 1, hist, stop

    hist0 = tuple(jnp.full(max_epochs, jnp.nan) for _ in range(4))
    state = (
        flat0,
        jnp.asarray(mu),
        flat0,
        jnp.asarray(jnp.inf),
        jnp.array(0),
        jnp.array(0),
        hist0,
        jnp.array(False),
    )
    state = jax.lax.while_loop(lambda s: (s[5] < max_epochs) & ~s[7], epoch, state)
    best = state[2] if validation is not None else state[0]
    tr, va, te, mus = state[6]
    history = TrainingHistory(train=tr, validation=va, test=te, mu=mus, epochs=state[5])
    return eqx.combine(unravel(best), static), history
