"""Gradient-optimal input design through the differentiable output-error model.

The Fisher information of the output-error parameters is `M = sum_t S_t^T R^-1 S_t`
with `S_t = d y(t) / d theta` the output sensitivities: the exact Jacobians the OEM
uses (forward mode through the model's diffrax RK4 solve). The model's input column
`column` is a base schedule plus an excitation, an [`AbstractInput`][] PyTree; so `M`
is a differentiable function of the excitation's parameters (forward over forward
mode), and an optax optimiser can minimise a design criterion of the Cramér-Rao
covariance `M^-1` — D (log det) or A (trace), on parameters made relative to their
a-priori values (so the criterion is scale-free) — subject to an amplitude limit, a
rate limit and a bound on one output's excursion (e.g. alpha), enforced by a
quadratic penalty while optimising and by scaling the excitation to its binding limit
at the end (as every input compared with it is scaled).
"""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from jaxtyping import Array, Float

from .._estimate._oem import _input_at, _window_solve, OEMProblem
from .._inputs import AbstractInput


class Scaled(AbstractInput):
    """An input multiplied by `scale`."""

    inner: AbstractInput
    scale: Float[Array, ""]

    def __call__(self, t):
        return self.scale * self.inner(t)


class DesignProblem(eqx.Module):
    """What the design needs to know.

    **Fields:**

    - `problem`: an [`OEMProblem`][] over the design segment (one parameter set, single
      shooting); column `column` of its inputs holds the base schedule (rad).
    - `theta`: a-priori parameters `(params,)` at which the information is evaluated.
    - `x0`: the initial state `(states,)`.
    - `noise`: output noise variances `(outputs,)` per sample.
    - `column`: the excited input column (static).
    - `transform`: optional `theta -> reported parameters` (e.g. body axes to
      lift/drag); the covariance is mapped through its Jacobian (static).
    - `excursion_output`: the output whose excursion from the unexcited response is
      bounded (e.g. alpha), or None (static).
    """

    problem: OEMProblem
    theta: Float[Array, " params"]
    x0: Float[Array, " states"]
    noise: Float[Array, " outputs"]
    column: int = eqx.field(static=True)
    transform: Callable | None = eqx.field(static=True, default=None)
    excursion_output: int | None = eqx.field(static=True, default=None)

    @property
    def times(self) -> Float[Array, " samples"]:
        return self.problem.t0 + self.problem.dt * jnp.arange(self.problem.n_samples)


class Limits(eqx.Module):
    """Limits on the excitation: peak deflection (rad), peak rate (rad/s) and the
    peak excursion of `DesignProblem.excursion_output` (its units)."""

    max_deflection: float
    max_rate: float = float("inf")
    max_excursion: float = float("inf")


# Every quantity below depends on an excitation only through its values and its
# exact time derivative on the design's sample grid ([`samples`][]): the compiled
# programs take those arrays, so inputs of different kinds (pulse, 3211, multisine,
# a scaled one...) share one program each instead of compiling their own.


def samples(
    design: DesignProblem, excitation: AbstractInput
) -> tuple[Float[Array, " samples"], Float[Array, " samples"]]:
    """The excitation and its exact time derivative on the design's sample grid."""
    t = design.times
    e = jax.vmap(excitation)(t)
    rate = jax.vmap(jax.grad(lambda s: excitation(s)))(t)
    # strongly typed, so that every kind of input meets the same compiled program
    return e.astype(t.dtype), rate.astype(t.dtype)


_samples_jit = eqx.filter_jit(samples)


def _values(design: DesignProblem, excitation: AbstractInput):
    t = design.times
    return jax.vmap(excitation)(t).astype(t.dtype)


_values_jit = eqx.filter_jit(_values)


@eqx.filter_jit
def _outputs_of(design: DesignProblem, e, theta) -> Float[Array, "samples outputs"]:
    problem = design.problem
    if e is not None:
        inputs = problem.inputs.at[:, design.column].add(e)
        problem = eqx.tree_at(lambda p: p.inputs, problem, inputs)
    xs, ts = _window_solve(problem, design.x0, theta, problem.t0)
    u = jax.vmap(lambda t: _input_at(problem, t, theta))(ts[:-1])
    return jax.vmap(lambda t, x, uu: problem.outputs(t, x, uu, theta))(
        ts[:-1], xs[:-1], u
    )


def simulate_outputs(
    design: DesignProblem, excitation: AbstractInput | None, theta=None
) -> Float[Array, "samples outputs"]:
    """Model outputs over the segment with the excitation added (None: without)."""
    e = None if excitation is None else _values_jit(design, excitation)
    return _outputs_of(design, e, design.theta if theta is None else theta)


@eqx.filter_jit
def _fisher_of(design: DesignProblem, e) -> Float[Array, "params params"]:
    free = jnp.asarray(design.problem.free)
    sens = jax.jacfwd(lambda th: _outputs_of(design, e, th))(design.theta)
    sens = jnp.where(free[None, None, :], sens, 0.0)
    m = jnp.einsum("toa,o,tob->ab", sens, 1.0 / design.noise, sens)
    return m + jnp.diag(jnp.where(free, 0.0, 1.0))


def fisher_information(
    design: DesignProblem, excitation: AbstractInput | None
) -> Float[Array, "params params"]:
    """`sum_t S_t^T R^-1 S_t` with exact sensitivities `S_t = dy(t)/dtheta`, free
    parameters only (fixed ones get a unit diagonal)."""
    e = None if excitation is None else _values_jit(design, excitation)
    return _fisher_of(design, e)


@eqx.filter_jit
def _covariance_of(design: DesignProblem, e) -> Float[Array, "k k"]:
    free = jnp.asarray(design.problem.free)
    cov = jnp.linalg.inv(_fisher_of(design, e))
    cov = jnp.where(free[:, None] & free[None, :], cov, 0.0)
    if design.transform is None:
        return cov
    jac = jax.jacfwd(design.transform)(design.theta)
    return jac @ cov @ jac.T


def predicted_covariance(design: DesignProblem, excitation) -> Float[Array, "k k"]:
    """The Cramér-Rao covariance of the (transformed) parameters."""
    e = None if excitation is None else _values_jit(design, excitation)
    return _covariance_of(design, e)


@eqx.filter_jit
def _stderr_of(design: DesignProblem, e) -> Float[Array, " k"]:
    return jnp.sqrt(jnp.diag(_covariance_of(design, e)))


def predicted_stderr(design: DesignProblem, excitation) -> Float[Array, " k"]:
    """Cramér-Rao standard errors of the (transformed) parameters."""
    e = None if excitation is None else _values_jit(design, excitation)
    return _stderr_of(design, e)


def _criterion_of(design: DesignProblem, e, kind: str = "D") -> Float[Array, ""]:
    cov = _covariance_of(design, e)
    ref = design.theta if design.transform is None else design.transform(design.theta)
    free = np.asarray(design.problem.free)
    if design.transform is None:
        keep = np.flatnonzero(free)
    else:
        keep = np.arange(cov.shape[0])
    rel = cov[keep[:, None], keep[None, :]] / jnp.outer(ref[keep], ref[keep])
    if kind == "D":
        return jnp.linalg.slogdet(rel)[1]
    if kind == "A":
        return jnp.trace(rel)
    raise ValueError(f"criterion must be D or A, got {kind!r}")


_criterion_jit = eqx.filter_jit(_criterion_of)


def criterion(design: DesignProblem, excitation, kind: str = "D") -> Float[Array, ""]:
    """D: `log det` of the covariance of the parameters relative to their a-priori
    values; A: the sum of their squared relative standard errors. Lower is better."""
    return _criterion_of(design, _values(design, excitation), kind)


def _compiled_criterion(design: DesignProblem, excitation, kind: str) -> float:
    """`criterion`, through the one program every kind of excitation shares."""
    return float(_criterion_jit(design, _values_jit(design, excitation), kind))


def _peaks_of(design: DesignProblem, e, rate) -> dict[str, Array]:
    out = {"deflection": jnp.max(jnp.abs(e)), "rate": jnp.max(jnp.abs(rate))}
    if design.excursion_output is not None:
        k = design.excursion_output
        y1 = _outputs_of(design, e, design.theta)[:, k]
        y0 = _outputs_of(design, None, design.theta)[:, k]
        out["excursion"] = jnp.max(jnp.abs(y1 - y0))
    else:
        out["excursion"] = jnp.zeros(())
    return out


_peaks_jit = eqx.filter_jit(_peaks_of)


def peaks(design: DesignProblem, excitation) -> dict[str, Array]:
    """Peak deflection (rad), rate (rad/s) and output excursion of an excitation on
    the design's sample grid (rate from the exact time derivative)."""
    return _peaks_jit(design, *_samples_jit(design, excitation))


def _violation_of(design, e, rate, limits):
    p = _peaks_of(design, e, rate)
    ratios = jnp.stack(
        [
            p["deflection"] / limits.max_deflection,
            p["rate"] / limits.max_rate,
            p["excursion"] / limits.max_excursion,
        ]
    )
    return jnp.max(ratios)


def _violation(design, excitation, limits):
    return _violation_of(design, *samples(design, excitation), limits)


@eqx.filter_jit
def _limit_scale(design: DesignProblem, e, rate, limits: Limits) -> Array:
    # the excitation scaled by s has samples s e and rate s rate
    scale = jnp.ones(())
    for _ in range(4):
        v = _violation_of(design, scale * e, scale * rate, limits)
        scale = scale * 0.999 / v
    v = _violation_of(design, scale * e, scale * rate, limits)
    return scale * jnp.minimum(1.0, 0.999 / v)


def within_limits(design: DesignProblem, excitation, limits: Limits) -> Scaled:
    """The excitation scaled (up or down) until its binding limit is just met, so
    inputs compared under the same limits each use their whole allowance (the
    output excursion is not exactly linear in the amplitude, so the scale is
    refined)."""
    e, rate = _samples_jit(design, excitation)
    return Scaled(excitation, _limit_scale(design, e, rate, limits))


def optimise_input(
    design: DesignProblem,
    excitation0: AbstractInput,
    limits: Limits,
    *,
    kind: str = "D",
    filter_spec=eqx.is_inexact_array,
    steps: int = 150,
    learning_rate: float = 0.05,
    penalty: float = 100.0,
) -> tuple[Scaled, dict[str, np.ndarray]]:
    """Minimise the design criterion over the excitation's parameters (those selected
    by `filter_spec`, e.g. a multisine's amplitudes and phases) with Adam, limits as a
    quadratic penalty on their excess; the result is scaled into the limits.

    **Returns:** the optimised excitation (within limits) and the history of the
    criterion and of the largest limit ratio per step.
    """
    params, static = eqx.partition(excitation0, filter_spec)

    def loss(p):
        exc = eqx.combine(p, static)
        excess = jax.nn.relu(_violation(design, exc, limits) - 1.0)
        return criterion(design, exc, kind) + penalty * excess**2

    # forward over forward mode: the information matrix is itself a forward-mode
    # Jacobian through the diffrax solve
    grad = jax.jit(lambda p: (loss(p), jax.jacfwd(loss)(p)))
    opt = optax.adam(learning_rate)
    state = opt.init(params)

    @jax.jit
    def step(p, s):
        value, g = grad(p)
        updates, s = opt.update(g, s, p)
        return optax.apply_updates(p, updates), s, value

    history = []
    for _ in range(steps):
        params, state, value = step(params, state)
        history.append(float(value))
    best = within_limits(design, eqx.combine(params, static), limits)
    return best, {
        "loss": np.asarray(history),
        "start": _compiled_criterion(
            design, within_limits(design, excitation0, limits), kind
        ),
        "end": _compiled_criterion(design, best, kind),
    }


HAND_PICKED = ("pulse", "sine", "3211", "multisine")


def pegasus_design(
    segment: tuple[float, float] = (20.0, 25.0), rate: float = 100.0
) -> DesignProblem:
    """The Pegasus OEM model (body-axis derivatives, reported in lift/drag form)
    along the nominal flight without excitation over `segment` (s), sampled at `rate`
    Hz; a-priori derivatives from the database at the segment's mean alpha and Mach;
    noise the default sensor noise averaged over the 1 kHz samples in each design
    sample (as the OEM's block means); the alpha excursion bounded."""
    from .._estimate._pegasus_oem import (
        INPUTS,
        make_model,
        measured_states,
        OUTPUTS,
        to_body,
        to_lift_drag,
    )
    from .._simulate._sensors import DEFAULT_SIGMA, SensorModel
    from .._simulate._solve import (
        elevator_command,
        flight_to_log,
        PegasusConfig,
        simulate,
    )
    from .._vehicle._pegasus._aerodynamics import load_database

    config = PegasusConfig(
        elevator=elevator_command("none"),
        sensors=SensorModel.noise_free(),
        t_final=segment[1] + 0.5,
        sample_rate=rate,
    )
    log = flight_to_log(simulate(config, jax.random.key(0)))
    idx = np.flatnonzero((log.t >= segment[0] - 1e-9) & (log.t < segment[1] - 1e-9))
    alpha, mach = float(np.mean(log["alpha"][idx])), float(np.mean(log["mach"][idx]))
    prior = load_database().derivatives(alpha, mach).as_array()
    rates, outputs = make_model(log.s_ref, log.c_ref)
    problem = OEMProblem(
        rates=rates,
        outputs=outputs,
        t0=float(log.t[idx[0]]),
        dt=1.0 / rate,
        inputs=jnp.asarray(np.column_stack([log[c][idx] for c in INPUTS])),
        measured=jnp.zeros((len(idx), len(OUTPUTS))),
        free=(True,) * 6,
    )
    averaged = 1000.0 / rate
    noise = jnp.asarray([DEFAULT_SIGMA[c] ** 2 / averaged for c in OUTPUTS])

    def transform(body):
        return to_lift_drag(body, jnp.asarray(alpha))

    return DesignProblem(
        problem=problem,
        theta=to_body(prior, jnp.asarray(alpha)),
        x0=jnp.asarray(measured_states(log)[idx[0]]),
        noise=noise,
        column=INPUTS.index("de"),
        transform=transform,
        excursion_output=OUTPUTS.index("alpha"),
    )


def multisine_spec() -> AbstractInput:
    """A filter spec that frees a [`Multisine`][]'s amplitudes and phases."""
    from .._inputs import Multisine

    return Multisine(
        amplitudes=True, frequencies=False, phases=True, start=False, stop=False
    )


def run_design(
    design: DesignProblem,
    limits: Limits,
    *,
    kind: str = "D",
    steps: int = 150,
) -> dict:
    """Optimise a multisine (started from the Schroeder-phased one) and compare it
    with the hand-picked inputs, all scaled into the same limits.

    **Returns:** a dict with, per input, the excitation (within limits), its
    predicted standard errors (reported parameters), criterion and peaks; the
    optimiser history; and the name of the best hand-picked input.
    """
    from .._inputs import excitation

    start = float(design.problem.t0)
    inputs = {
        n: within_limits(design, excitation(n, start), limits) for n in HAND_PICKED
    }
    schroeder = excitation("multisine", start)
    best, history = optimise_input(
        design,
        schroeder,
        limits,
        kind=kind,
        filter_spec=multisine_spec(),
        steps=steps,
    )
    inputs["optimised"] = best
    rows = {}
    for name, exc in inputs.items():
        p = peaks(design, exc)
        rows[name] = {
            "stderr": np.asarray(predicted_stderr(design, exc)),
            "criterion": _compiled_criterion(design, exc, kind),
            "peaks": {k: float(v) for k, v in p.items()},
        }
    hand = min(HAND_PICKED, key=lambda n: rows[n]["criterion"])
    return {
        "inputs": inputs,
        "rows": rows,
        "history": history,
        "best_hand_picked": hand,
    }
