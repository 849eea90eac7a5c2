"""Neural model plus least squares (thesis chapter 4).

An equinox MLP maps measured quantities to `[CL, CD, CM]` (one hidden layer of 10
tanh units by default): by default the measured aerodynamic loads over the measured
dynamic pressure (the thesis's accelerations `ax, az, qdot` times the log's mass and
inertia, less its thrust, the moment moved to the cp station with the log's CG) and
`[q, V, alpha, de, qbar]`; the
thesis's `[ax, az, qdot, q, V, alpha, de]` with `inputs=NN_INPUTS`. Min-max
normalisation of inputs
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
from ._coefficients import aerodynamic_loads, reconstruct_coefficients
from ._lse import window_truth, windowed_least_squares
from ._result import Estimates
from ._training import train_levenberg_marquardt, TrainingHistory
from ._windows import WindowLayout


NN_INPUTS = ("ax", "az", "qdot", "q", "V", "alpha", "de")  # thesis eq 4.1
# Inputs computed from a log's channels rather than read from it: the measured
# aerodynamic loads (N, N, N m; see `aerodynamic_loads`), the thesis's accelerations
# times the flight's own mass and inertia, less its thrust, the moment moved from its
# own CG to the cp station.
LOAD_INPUTS = ("X_aero", "Z_aero", "M_cp")
# The same loads over the measured dynamic pressure (m^2, m^2, m^3): the targets up
# to the constant S (and c), so the network is left with the rotation through alpha.
PER_QBAR_INPUTS = ("X_per_qbar", "Z_per_qbar", "M_per_qbar")
# The thesis's set with its accelerations replaced by the loads over the measured
# dynamic pressure, plus qbar: the targets are these inputs over S (and c), rotated
# through alpha. Mass, thrust, inertia and CG differ from flight to flight but are
# functions of time on every training flight, so a network given accelerations can
# only apply the training flights' values to them; and a network given the loads
# and qbar apart has to learn their ratio, whose error it passes to the derivatives
# (CMa 3.6x LSE's over 100 flights; see docs/validation/thesis.md).
DEFAULT_INPUTS = (
    "X_per_qbar",
    "Z_per_qbar",
    "M_per_qbar",
    "q",
    "V",
    "alpha",
    "de",
    "qbar",
)
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
    """MLP from measured channels (`names`, in that order) to `[CL, CD, CM]`,
    normalisation included.

    With `moment_about_cg` (the default) the network's third output is the pitching
    moment about the CG, `(Iyy qdot + Iyy_dot q) / (qbar S c)` (thesis eq 4.4), and
    [`coefficients`][] moves it to the cp station of the database with the log's
    known CG and cp stations, as the equation-error reconstruction does.
    """

    mlp: eqx.nn.MLP
    inputs: MinMax
    outputs: MinMax
    names: tuple[str, ...] = eqx.field(static=True, default=NN_INPUTS)
    moment_about_cg: bool = eqx.field(static=True, default=False)
    c_ref: float = eqx.field(static=True, default=1.0)

    def __call__(self, x: Float[Array, " k"]) -> Float[Array, " 3"]:
        return self.outputs.inverse(self.mlp(self.inputs.forward(x)))

    def features(self, channels: dict[str, Array]) -> Float[Array, "n k"]:
        """The network's input matrix from a log's channels."""
        return network_inputs(channels, self.names)

    def coefficients(self, channels: dict[str, Array]) -> Float[Array, "n 3"]:
        """`[CL, CD, CM]` per sample, CM about the cp station (the truth's
        convention), from a log's channels."""
        out = jax.vmap(self)(self.features(channels))
        if not self.moment_about_cg:
            return out
        return jnp.stack(
            [out[:, 0], out[:, 1], _moment_to_cp(out, channels, self.c_ref)], axis=-1
        )


def _moment_to_cp(out, channels, c_ref):
    """`CM_cp = CM_cg - (xcp - xcg) CZ / c`, `CZ = -CL cos(alpha) - CD sin(alpha)`."""
    a = jnp.asarray(channels["alpha"])
    cz = -out[:, 0] * jnp.cos(a) - out[:, 1] * jnp.sin(a)
    lever = jnp.asarray(channels["xcp"]) - jnp.asarray(channels["xcg"])
    return out[:, 2] - lever * cz / c_ref


def network_inputs(
    channels: dict[str, Array], names: tuple[str, ...] = NN_INPUTS
) -> Float[Array, "n k"]:
    """The input matrix `(n, len(names))`: each name a channel of the log or one of
    `LOAD_INPUTS`."""
    loads = {}
    if any(n in LOAD_INPUTS + PER_QBAR_INPUTS for n in names):
        ch = {k: jnp.asarray(v) for k, v in channels.items()}
        loads = dict(zip(LOAD_INPUTS, aerodynamic_loads(ch), strict=True))
        for name, load in zip(PER_QBAR_INPUTS, aerodynamic_loads(ch), strict=True):
            loads[name] = load / ch["qbar"]
    return jnp.stack(
        [loads[c] if c in loads else jnp.asarray(channels[c]) for c in names], axis=-1
    )


def network_targets(
    log: FlightLog, moment_about_cg: bool = False
) -> Float[Array, "n 3"]:
    """`[CL, CD, CM]` reconstructed from the measurements; CM about the CG with
    `moment_about_cg`, else about the cp station."""
    ch = {k: jnp.asarray(v) for k, v in log.channels.items()}
    c = reconstruct_coefficients(ch, log.s_ref, log.c_ref)
    cm = c.CM
    if moment_about_cg:
        cm = cm + (ch["xcp"] - ch["xcg"]) * c.CZ / log.c_ref
    return jnp.stack([c.CL, c.CD, cm], axis=-1)


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
    inputs: tuple[str, ...] = DEFAULT_INPUTS,
    moment_about_cg: bool = False,
) -> tuple[CoefficientNetwork, TrainingHistory]:
    """Train the coefficient network on flight logs.

    Uses every `subsample`-th sample from `t_min` s on (the unpowered fall has no
    excitation), a random 70/15/15 split, and LM up to `max_epochs` with early stopping
    after `patience` epochs without a better validation error.
    """
    xs, ys = [], []
    for log in logs:
        keep = np.flatnonzero(log.t >= t_min)[::subsample]
        xs.append(network_inputs(log.channels, inputs)[keep])
        ys.append(network_targets(log, moment_about_cg)[keep])
    x, y = jnp.concatenate(xs), jnp.concatenate(ys)
    k_perm, k_init = jax.random.split(key)
    perm = jax.random.permutation(k_perm, x.shape[0])
    n_tr, n_va = int(0.7 * len(perm)), int(0.15 * len(perm))
    parts = [perm[:n_tr], perm[n_tr : n_tr + n_va], perm[n_tr + n_va :]]
    x_scale, y_scale = MinMax.fit(x[parts[0]]), MinMax.fit(y[parts[0]])
    mlp = eqx.nn.MLP(
        len(inputs), len(NN_OUTPUTS), width, depth, activation=jnp.tanh, key=k_init
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
    net = CoefficientNetwork(
        trained, x_scale, y_scale, tuple(inputs), moment_about_cg, float(logs[0].c_ref)
    )
    return net, history


def save_network(path: str | os.PathLike, net: CoefficientNetwork) -> None:
    """Equinox serialisation of the leaves plus a JSON file of the architecture."""
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {
        "width": net.mlp.width_size,
        "depth": net.mlp.depth,
        "inputs": list(net.names),
        "moment_about_cg": net.moment_about_cg,
        "c_ref": net.c_ref,
    }
    path.with_suffix(".json").write_text(json.dumps(meta))
    eqx.tree_serialise_leaves(path, net)


def load_network(path: str | os.PathLike) -> CoefficientNetwork:
    """Load a network saved by [`save_network`][]."""
    path = pathlib.Path(path)
    meta = json.loads(path.with_suffix(".json").read_text())
    names = tuple(meta.get("inputs", NN_INPUTS))
    like = CoefficientNetwork(
        eqx.nn.MLP(
            len(names),
            len(NN_OUTPUTS),
            meta["width"],
            meta["depth"],
            activation=jnp.tanh,
            key=jax.random.key(0),
        ),
        MinMax(jnp.zeros(len(names)), jnp.ones(len(names))),
        MinMax(jnp.zeros(3), jnp.ones(3)),
        names,
        bool(meta.get("moment_about_cg", False)),
        float(meta.get("c_ref", 1.0)),
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
    if isinstance(model, CoefficientNetwork):
        x = model.features(channels)
        coeffs = model.coefficients(channels)
    else:
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
        names = model.names if isinstance(model, CoefficientNetwork) else NN_INPUTS
        ia, ide = names.index("alpha"), names.index("de")
        if isinstance(model, CoefficientNetwork) and model.moment_about_cg:
            lever = jnp.asarray(channels["xcp"]) - jnp.asarray(channels["xcg"])

            def at_cp(xi, li):
                out = model(xi)
                ch = {"alpha": xi[ia], "xcp": li, "xcg": 0.0}
                return out.at[2].set(_moment_to_cp(out[None], ch, model.c_ref)[0])
        else:
            lever = jnp.zeros(x.shape[0])

            def at_cp(xi, li):
                del li
                return model(xi)

        def slopes(xi, li):
            d = []
            for j in (ia, ide):
                e = jnp.zeros(xi.shape[0]).at[j].set(step)
                d.append((at_cp(xi + e, li) - at_cp(xi - e, li)) / (2 * step))
            return jnp.stack(d, axis=-1)  # (3 coefficients, 2 inputs)

        s = jax.vmap(slopes)(x, lever).reshape(-1, 6)
        values = jnp.stack([layout.window_mean(s[:, j]) for j in range(6)], axis=-1)
        ok = jnp.ones(layout.count, bool)
        return Estimates(
            "nn", jnp.asarray(start), jnp.asarray(end), values, None, ok, {}, truth
        )
    raise ValueError(f"derivatives must be lse or central, got {derivatives!r}")
