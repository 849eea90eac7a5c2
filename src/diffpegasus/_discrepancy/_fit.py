"""Fitting the global model to a log by output error.

The fit is [`fit_global_oem`][]: one parameter set for the record, multiple shooting
(nodes every `node_interval` s, all free, since the first is measured with noise
too). Starting values come from one global equation-error regression of the
reconstructed coefficients on the spline basis, so no a-priori database is needed
and logs from any source work.
"""

import dataclasses

import jax.numpy as jnp
import numpy as np

from .._effects import make_effect
from .._estimators._coefficients import reconstruct_coefficients
from .._estimators._global_oem import fit_global_oem, GlobalFit
from .._estimators._oem import node_times, OEMProblem
from .._log import FlightLog
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
    `result` (the [`GlobalFit`][]), `index` (log sample of every model sample),
    `log` (the log).
    """

    spec: ModelSpec
    problem: OEMProblem
    result: GlobalFit
    index: np.ndarray
    log: FlightLog

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


def global_problem(
    log: FlightLog,
    spec: ModelSpec,
    *,
    rate: float = 50.0,
    node_interval: float = 2.0,
) -> tuple[OEMProblem, np.ndarray]:
    """The output-error problem of `spec` on `log`, resampled to about `rate` Hz
    (every n-th sample); returns it with the log sample indices."""
    step = max(1, int(round(log.sample_rate / rate)))
    per_node = max(1, int(round(node_interval * log.sample_rate / step)))
    index = np.arange(0, len(log), step)
    if len(index) < 2 * per_node:
        raise ValueError(
            f"{len(index) / (log.sample_rate / step):.1f} s of log; the global fit "
            f"needs at least two shooting segments of {node_interval} s"
        )
    basis = scheduling_basis(log, index, spec)
    rates, outputs, delay = make_model(spec)
    problem = OEMProblem(
        rates=rates,
        outputs=outputs,
        t0=float(log.t[0]),
        dt=float(step / log.sample_rate),
        inputs=jnp.asarray(np.column_stack([log[c][index] for c in KNOWN] + [basis])),
        measured=jnp.asarray(np.column_stack([log[c][index] for c in OUTPUTS])),
        free=(True,) * spec.n_params,
        window=None,
        node_interval=per_node,
        free_initial_state=True,
        state_scale=jnp.asarray(STATE_SCALE),
        continuity_tol=1e-2,
        input_delay=delay,
    )
    return problem, index


def equation_error_start(log: FlightLog, spec: ModelSpec, index) -> np.ndarray:
    """Aerodynamic parameters from one least-squares regression of the reconstructed
    CL, CD, CM on the model's regressors; effects start at zero."""
    c = reconstruct_coefficients(
        {k: jnp.asarray(v[index]) for k, v in log.channels.items()},
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
    problem, index = global_problem(log, spec, rate=rate, node_interval=node_interval)
    free = np.zeros(spec.n_params, bool)
    free[: spec.n_aero] = True
    for a in add:
        free[spec.effect_index(a)] = True
    if start is None:
        theta0 = equation_error_start(log, spec, index)
        nodes0 = measured_states(log, index[node_times(problem)])
    else:
        theta0 = np.asarray(start.result.params)
        nodes0 = start.result.nodes
    result = fit_global_oem(
        problem, jnp.asarray(theta0), nodes0, jnp.asarray(free), max_iter=max_iter
    )
    return ModelFit(spec, problem, result, index, log)
