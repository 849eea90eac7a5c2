"""Fitting the global model to a log by output error.

The fit is [`fit_global_oem`][]: one parameter set for the record, multiple shooting
(nodes every `node_interval` s, all free, since the first is measured with noise
too). Starting values come from one global equation-error regression of the
reconstructed coefficients on the spline basis, so no a-priori database is needed
and logs from any source work.

The model runs at about 50 Hz whatever the log's rate. Picking every n-th sample
would move each elevator step by up to a model sample (the model interpolates its
inputs linearly between samples), an artefact the diagnosis reported as an
actuator delay on logs with true steps. Instead every channel, inputs and outputs
alike, is reduced by a centred block mean: the model sample at `t_i` is the mean of
the log over `[t_i - T/2, t_i + T/2]` (`T` the model interval; each log sample
stands for its own interval, half weights where a block edge falls on a sample).
The linear interpolant of block means has the same integral as the log, so a step
keeps its timing on average over where it falls between samples; and the model's
outputs, computed from the block-mean input, match block means of the outputs to
first order.
"""

import dataclasses

import jax.numpy as jnp
import numpy as np

from .._estimate._coefficients import reconstruct_coefficients
from .._estimate._global_oem import fit_global_oem, GlobalFit
from .._estimate._oem import node_times, OEMProblem
from .._log._format import FlightLog
from .._vehicle._effects import make_effect
from ._model import (
    aero_columns,
    KNOWN,
    make_model,
    measured_states,
    ModelSpec,
    OUTPUTS,
    scheduling_basis,
    STATE_SCALE,
)


@dataclasses.dataclass
class ModelFit:
    """A fit of the global model to one log.

    **Fields:** `spec` (model structure), `problem` (the [`OEMProblem`][]),
    `result` (the [`GlobalFit`][]), `index` (log sample at the centre of every
    model sample), `log` (the log), `channels` (the log's channels as block means
    at the model samples), `step` (log samples per model sample).
    """

    spec: ModelSpec
    problem: OEMProblem
    result: GlobalFit
    index: np.ndarray
    log: FlightLog
    channels: dict = dataclasses.field(default_factory=dict)
    step: int = 1

    @property
    def cost(self) -> float:
        """The output-error cost det(R) of the fit."""
        return float(self.result.cost)

    @property
    def t(self) -> np.ndarray:
        return self.log.t[self.index]

    @property
    def measured(self) -> np.ndarray:
        return np.asarray(self.problem.measured)

    @property
    def model(self) -> np.ndarray:
        return np.asarray(self.result.outputs)

    @property
    def residuals(self) -> np.ndarray:
        """Measured minus model outputs, `(samples, outputs)`, SI units."""
        return self.measured - self.model

    @property
    def added(self) -> tuple[str, ...]:
        free = np.asarray(self.result.free)
        return tuple(
            e for i, e in enumerate(self.spec.effects) if free[self.spec.n_aero + i]
        )

    def effect_estimates(self) -> dict[str, dict[str, float | str]]:
        """Each estimated effect: its parameter's estimate and standard error
        (corrected for coloured residuals; the plain Cramér-Rao bound beside it)."""
        out = {}
        for name in self.added:
            k = self.spec.effect_index(name)
            out[name] = {
                "parameter": make_effect(name).parameter,
                "estimate": float(self.result.params[k]),
                "stderr": float(self.result.stderr_corrected[k]),
                "stderr_crb": float(self.result.stderr[k]),
            }
        return out


def block_weights(step: int) -> np.ndarray:
    """Weights of a centred block mean over `step` log samples, offsets
    `-h..h`: 1 inside, 1/2 where the block edge falls on a sample (even `step`);
    they sum to `step`."""
    h = step // 2
    return np.clip(step / 2 + 0.5 - np.abs(np.arange(-h, h + 1)), 0.0, 1.0)


def block_means(x: np.ndarray, step: int) -> tuple[np.ndarray, np.ndarray]:
    """Centred block means of `x` `(n,)` or `(n, k)` at samples `0, step, 2 step, ...`;
    blocks cut by the ends of the record shrink symmetrically (so every mean stays
    centred on its sample). Returns `(means, index)`."""
    x = np.asarray(x, float)
    n = x.shape[0]
    index = np.arange(0, n, step)
    if step == 1:
        return x.copy(), index
    w = block_weights(step)
    h = len(w) // 2
    radius = np.minimum(index, n - 1 - index)
    num = np.zeros((len(index),) + x.shape[1:])
    den = np.zeros(len(index))
    for d, wd in zip(range(-h, h + 1), w, strict=True):
        ok = np.abs(d) <= radius
        j = np.clip(index + d, 0, n - 1)
        num += (wd * ok).reshape((-1,) + (1,) * (x.ndim - 1)) * x[j]
        den += wd * ok
    return num / den.reshape((-1,) + (1,) * (x.ndim - 1)), index


def model_step(log: FlightLog, rate: float) -> int:
    """Log samples per model sample for a model rate of about `rate` Hz."""
    return max(1, int(round(log.sample_rate / rate)))


def resample(log: FlightLog, rate: float) -> tuple[dict, np.ndarray, int]:
    """Every channel of `log` as centred block means at about `rate` Hz:
    `(channels, index, step)` with `index` the log sample at each block's centre."""
    step = model_step(log, rate)
    channels = {}
    index = np.arange(0, len(log), step)
    for name, values in log.channels.items():
        if name == "t":
            channels[name] = np.asarray(values, float)[index]
        else:
            channels[name], _ = block_means(values, step)
    return channels, index, step


def global_problem(
    log: FlightLog,
    spec: ModelSpec,
    *,
    rate: float = 50.0,
    node_interval: float = 2.0,
) -> tuple[OEMProblem, np.ndarray]:
    """The output-error problem of `spec` on `log`, reduced to about `rate` Hz by
    centred block means of every channel (see the module); returns it with the log
    sample index at the centre of each model sample."""
    problem, index, _ = _problem(log, spec, rate, node_interval)
    return problem, index


def _problem(log, spec, rate, node_interval):
    channels, index, step = resample(log, rate)
    per_node = max(1, int(round(node_interval * log.sample_rate / step)))
    if len(index) < 2 * per_node:
        raise ValueError(
            f"{len(index) / (log.sample_rate / step):.1f} s of log; the global fit "
            f"needs at least two shooting segments of {node_interval} s"
        )
    basis = scheduling_basis(channels, np.arange(len(index)), spec)
    rates, outputs, delay = make_model(spec)
    problem = OEMProblem(
        rates=rates,
        outputs=outputs,
        t0=float(log.t[0]),
        dt=float(step / log.sample_rate),
        inputs=jnp.asarray(np.column_stack([channels[c] for c in KNOWN] + [basis])),
        measured=jnp.asarray(np.column_stack([channels[c] for c in OUTPUTS])),
        free=(True,) * spec.n_params,
        window=None,
        node_interval=per_node,
        free_initial_state=True,
        state_scale=jnp.asarray(STATE_SCALE),
        continuity_tol=1e-2,
        input_delay=delay,
    )
    return problem, index, channels


def equation_error_start(log, spec: ModelSpec, index) -> np.ndarray:
    """Aerodynamic parameters from one least-squares regression of the reconstructed
    CL, CD, CM on the model's regressors at the samples `index` of `log` (a
    [`FlightLog`][] or a dict of channels); effects start at zero."""
    channels = log.channels if isinstance(log, FlightLog) else log
    c = reconstruct_coefficients(
        {k: jnp.asarray(v[index]) for k, v in channels.items()},
        spec.s_ref,
        spec.c_ref,
    )
    basis = scheduling_basis(log, index, spec)
    a = aero_columns(basis, log["alpha"][index], log["de"][index], spec)
    theta = np.zeros(spec.n_params)
    per = spec.n_aero // 3
    for j, y in enumerate((c.CL, c.CD, c.CM)):
        theta[j * per : (j + 1) * per] = np.linalg.lstsq(a, np.asarray(y), rcond=None)[
            0
        ]
    return theta


def fit_model(
    log: FlightLog,
    spec: ModelSpec,
    add: tuple[str, ...] = (),
    *,
    rate: float = 50.0,
    node_interval: float = 2.0,
    start: ModelFit | None = None,
    max_iter: int = 40,
) -> ModelFit:
    """Fit the global model `spec` to `log` with the effects `add` estimated and the
    other effects of `spec` held at zero.

    **Arguments:** `log`; `spec` (its `effects` must include `add`); `rate`: model
    sample rate, Hz (50); `node_interval`: shooting segment, s (2); `start`: a
    previous fit to start from (default: the equation-error regression).
    """
    missing = [a for a in add if a not in spec.effects]
    if missing:
        raise ValueError(f"effects {missing} are not in the model")
    problem, index, channels = _problem(log, spec, rate, node_interval)
    model_index = np.arange(len(index))
    free = np.zeros(spec.n_params, bool)
    free[: spec.n_aero] = True
    for a in add:
        free[spec.effect_index(a)] = True
    if start is None:
        theta0 = equation_error_start(channels, spec, model_index)
        nodes0 = measured_states(channels, model_index[node_times(problem)])
    else:
        theta0 = np.asarray(start.result.params)
        nodes0 = start.result.nodes
    result = fit_global_oem(
        problem, jnp.asarray(theta0), nodes0, jnp.asarray(free), max_iter=max_iter
    )
    return ModelFit(spec, problem, result, index, log, channels, model_step(log, rate))
