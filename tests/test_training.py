"""Levenberg-Marquardt training of equinox models."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from diffpegasus._estimate._training import train_levenberg_marquardt


def _mlp(key):
    return eqx.nn.MLP(2, 1, width_size=6, depth=1, activation=jnp.tanh, key=key)


def _data(n, key):
    teacher = _mlp(jax.random.key(42))
    x = jax.random.uniform(key, (n, 2), minval=-1.0, maxval=1.0)
    return x, jax.vmap(teacher)(x)


def test_lm_fits_a_representable_function_far_faster_than_adam():
    train = _data(200, jax.random.key(0))
    val = _data(50, jax.random.key(1))
    student = _mlp(jax.random.key(7))
    trained, hist = train_levenberg_marquardt(
        student, train, val, max_epochs=300, patience=50, chunk=64
    )
    epochs = int(hist.epochs)
    lm_mse = float(jnp.mean((jax.vmap(trained)(val[0]) - val[1]) ** 2))
    assert lm_mse < 1e-8, lm_mse
    # plain gradient descent (Adam) with ten times as many steps stays far worse
    opt = optax.adam(1e-2)
    params, static = eqx.partition(student, eqx.is_inexact_array)
    state = opt.init(params)

    @jax.jit
    def step(params, state):
        loss, g = jax.value_and_grad(
            lambda p: jnp.mean(
                (jax.vmap(eqx.combine(p, static))(train[0]) - train[1]) ** 2
            )
        )(params)
        updates, state = opt.update(g, state)
        return optax.apply_updates(params, updates), state, loss

    for _ in range(10 * epochs):
        params, state, _ = step(params, state)
    adam_mse = float(
        jnp.mean((jax.vmap(eqx.combine(params, static))(val[0]) - val[1]) ** 2)
    )
    assert adam_mse > 100 * lm_mse, (adam_mse, lm_mse, epochs)
    # the history is recorded epoch by epoch and falls
    tr = np.asarray(hist.train)[:epochs]
    assert np.all(np.isfinite(tr)) and tr[-1] < 1e-6 * tr[0]


def test_chunking_does_not_change_the_result():
    train = _data(100, jax.random.key(3))
    a, _ = train_levenberg_marquardt(
        _mlp(jax.random.key(5)), train, max_epochs=5, chunk=16
    )
    b, _ = train_levenberg_marquardt(
        _mlp(jax.random.key(5)), train, max_epochs=5, chunk=100
    )
    x = train[0][:10]
    np.testing.assert_allclose(
        np.asarray(jax.vmap(a)(x)), np.asarray(jax.vmap(b)(x)), rtol=1e-9
    )


def test_early_stopping_returns_the_best_validation_model():
    train = _data(30, jax.random.key(4))
    noisy_val = (train[0][:10], train[1][:10] + 0.3)
    model, hist = train_levenberg_marquardt(
        _mlp(jax.random.key(6)), train, noisy_val, max_epochs=200, patience=3, chunk=30
    )
    va = np.asarray(hist.validation)[: int(hist.epochs)]
    best = float(jnp.mean((jax.vmap(model)(noisy_val[0]) - noisy_val[1]) ** 2))
    assert best == np.nanmin(va) or abs(best - np.nanmin(va)) < 1e-12
    assert int(hist.epochs) < 200
