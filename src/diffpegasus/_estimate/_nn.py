"""Neural model plus least squares (thesis chapter 4).

An equinox MLP maps the measured `[ax, az, qdot, q, V, alpha, de]` to `[CL, CD, CM]`
(one hidden layer of 10 tanh units by default), with min-max normalisation of inputs
and outputs to [0, 1] kept inside the model. It is trained by Levenberg-Marquardt
([`train_levenberg_marquardt`][]) on flights whose coefficients are reconstructed from
the measurements (what a user has), split 70/15/15 at random into training,
validation (early stopping) and test sets. Derivatives come two ways: central
differences of the network in alpha and de, averaged per window (the thesis's first
attempt, kept as the documented poor baseline), and windowed least squares of the
network's outputs on `[alpha, de]` (the method the thesis compares).
"""

import json
import os
import pathlib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._log._format import FlightLog
from ._coefficients import reconstruct_coefficients
from ._lse import window_truth, windowed_least_squares
from ._result import Estimates
from ._training import train_levenberg_marquardt, TrainingHistory
from ._windows import WindowLayout


NN_INPUTS = ("ax", "az", "qdot", "q", "V", "alpha", "de")
NN_OUTPUTS = ("CL", "CD", "CM")


class MinMax(eqx.Module):
    """Affine map of each column from [lo, hi] to [0, 1]."""

    lo: Float[Array, " k"]
    hi: Float[Array, " k"]

    @classmethod
    def fit(cls, data: Float[Array, "n k"]) -> "MinMax":
        lo, hi = jnp.min(data, axis=0), jnp.max(data, axis=0)
        return cls(lo, jnp.where(hi > lo, hi, lo + 1.0))

    def forward(self, x):
        return (x - self.lo) / (self.hi - self.lo)

    def inverse(self, z):
        return self.lo + z * (self.hi - self.lo)


class CoefficientNetwork(eqx.Module):
    """MLP from the seven measured inputs to `[CL, CD, CM]`, normalisation included."""

    mlp: eqx.nn.MLP
    inputs: MinMax
    outputs: MinMax

    def __call__(self, x: Float[Array, " 7"]) -> Float[Array, " 3"]:
        return self.outputs.inverse(self.mlp(self.inputs.forward(x)))


def network_inputs(channels: dict[str, Array]) -> Float[Array, "n 7"]:
    return jnp.stack([jnp.asarray(channels[c]) for c in NN_INPUTS], axis=-1)


def network_targets(log: FlightLog) -> Float[Array, "n 3"]:
    c = reconstruct_coefficients(
        {k: jnp.asarray(v) for k, v in log.channels.items()}, log.s_ref, log.c_ref
    )
    return jnp.stack([c.CL, c.CD, c.CM], axis=-1)


def train_network(
    logs: list[FlightLog],
    key,
    *,
    width: int = 10,
    depth: int = 1,
    max_epochs: int = 1000,
    patience: int = 6,
    subsample: int = 10,
    t_min: float = 5.0,
) -> tuple[CoefficientNetwork, TrainingHistory]:
    """Train the coefficient network on flight logs.

    Uses every `subsample`-th sample from `t_min` s on (the unpowered fall has no
    excitation), a random 70/15/15 split, and LM up to `max_epochs` with early stopping
    after `patience` epochs without a better validation error.
    """
    xs, ys = [], []
    for log in logs:
        keep = np.flatnonzero(log.t >= t_min)[::subsample]
        xs.append(network_inputs(log.channels)[keep])
        ys.append(network_targets(log)[keep])
    x, y = jnp.concatenate(xs), jnp.concatenate(ys)
    k_perm, k_init = jax.random.split(key)
    perm = jax.random.permutation(k_perm, x.shape[0])
    n_tr, n_va = int(0.7 * len(perm)), int(0.15 * len(perm))
    parts = [perm[:n_tr], perm[n_tr : n_tr + n_va], perm[n_tr + n_va :]]
    x_scale, y_scale = MinMax.fit(x[parts[0]]), MinMax.fit(y[parts[0]])
    mlp = eqx.nn.MLP(
        len(NN_INPUTS), len(NN_OUTPUTS), width, depth, activation=jnp.tanh, key=k_init
    )
    xn, yn = jax.vmap(x_scale.forward)(x), jax.vmap(y_scale.forward)(y)
    trained, history = train_levenberg_marquardt(
        mlp,
        (xn[parts[0]], yn[parts[0]]),
        (xn[parts[1]], yn[parts[1]]),
        (xn[parts[2]], yn[parts[2]]),
        max_epochs=max_epochs,
        patience=patience,
    )
    return CoefficientNetwork(trained, x_scale, y_scale), history


def save_network(path: str | os.PathLike, net: CoefficientNetwork) -> None:
    """Equinox serialisation of the leaves plus a JSON file of the architecture."""
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {"width": net.mlp.width_size, "depth": net.mlp.depth}
    path.with_suffix(".json").write_text(json.dumps(meta))
    eqx.tree_serialise_leaves(path, net)


def load_network(path: str | os.PathLike) -> CoefficientNetwork:
    """Load a network saved by [`save_network`][]."""
    path = pathlib.Path(path)
    meta = json.loads(path.with_suffix(".json").read_text())
    like = CoefficientNetwork(
        eqx.nn.MLP(
            len(NN_INPUTS),
            len(NN_OUTPUTS),
            meta["width"],
            meta["depth"],
            activation=jnp.tanh,
            key=jax.random.key(0),
        ),
        MinMax(jnp.zeros(7), jnp.ones(7)),
        MinMax(jnp.zeros(3), jnp.ones(3)),
    )
    return eqx.tree_deserialise_leaves(path, like)


def estimate_nn(
    log: FlightLog,
    model,
    *,
    window: float = 0.5,
    derivatives: str = "lse",
    step: float = float(np.deg2rad(0.5)),
    tol: float = 1e-2,
) -> Estimates:
    """Per-window derivatives from a coefficient model (the trained network, or any
    function of the seven inputs returning `[CL, CD, CM]`).

    `derivatives="lse"` regresses the model's outputs on `[alpha, de]` per window
    with the LSE rank rule; `"central"` averages central differences (step `step`
    rad) of the model in alpha and de over each window.
    """
    layout = WindowLayout.make(len(log), log.sample_rate, window)
    channels = {k: jnp.asarray(v) for k, v in log.channels.items()}
    x = network_inputs(channels)
    coeffs = jax.vmap(model)(x)
    start, end = layout.times(float(log.t[0]))
    truth = window_truth(channels, layout)
    if derivatives == "lse":
        a = layout.split(jnp.stack([channels["alpha"], channels["de"]], axis=-1))
        deg = 180.0 / jnp.pi
        theta, stderr, rank_a, rank_ata, ok = windowed_least_squares(
            a,
            layout.split(coeffs),
            layout.mask(),
            tol=tol,
            column_scale=jnp.array([deg, deg]),
        )
        values = jnp.swapaxes(theta, 1, 2).reshape(layout.count, 6)
        sd = jnp.swapaxes(stderr, 1, 2).reshape(layout.count, 6)
        flags = {"rank_deficient": ~ok, "rank_A": rank_a, "rank_ATA": rank_ata}
        return Estimates(
            "nn", jnp.asarray(start), jnp.asarray(end), values, sd, ok, flags, truth
        )
    if derivatives == "central":
        ia, ide = NN_INPUTS.index("alpha"), NN_INPUTS.index("de")

        def slopes(xi):
            d = []
            for j in (ia, ide):
                e = jnp.zeros(7).at[j].set(step)
                d.append((model(xi + e) - model(xi - e)) / (2 * step))
            return jnp.stack(d, axis=-1)  # (3 coefficients, 2 inputs)

        s = jax.vmap(slopes)(x).reshape(-1, 6)
        values = jnp.stack([layout.window_mean(s[:, j]) for j in range(6)], axis=-1)
        ok = jnp.ones(layout.count, bool)
        return Estimates(
            "nn", jnp.asarray(start), jnp.asarray(end), values, None, ok, {}, truth
        )
    raise ValueError(f"derivatives must be lse or central, got {derivatives!r}")
