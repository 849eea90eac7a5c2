"""The vector form of an output-error problem (the input design's, and the engine's
adapter `_global_oem.py`; the windowed fit converts it to a `dp.Model`, deprecated),
and helpers to report a fit.

A model is two pure functions of time, state, known inputs and parameters:
`rates(t, x, u, theta) -> x'` and `outputs(t, x, u, theta) -> y`. The record is cut
into parameter windows (the parameters are constant in each, or over the whole record)
and shooting segments (groups of windows, each integrated from its own node state).
Inside a window the model is integrated by RK4 at the sample step, with the known
inputs interpolated linearly between samples (`_window_solve`, which the input design
uses); problems with one parameter set go to the engine through [`fit_global_oem`][].
"""

from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._rk4 import rk4_scan


class OEMProblem(eqx.Module):
    """An output-error problem: the model, the data and the unknowns.

    **Fields:**

    - `rates`, `outputs`: the model, `f(t, x, u, theta)` and `g(t, x, u, theta)` with
      `x` shape `(states,)`, `u` shape `(inputs,)`, `theta` shape `(params,)`.
    - `t0`, `dt`: time of the first sample and the sample interval, s.
    - `inputs`: shape `(samples, inputs)`, known inputs.
    - `measured`: shape `(samples, outputs)`, measured outputs.
    - `free`: which parameters are estimated (static tuple of bools).
    - `window`: samples per parameter window, or `None` for one parameter set over the
      record.
    - `node_interval`: samples per shooting segment (a multiple of `window`), or
      `None` for single shooting.
    - `free_initial_state`: whether the first node state is estimated (always true for
      later nodes under multiple shooting).
    - `full_covariance`: full or diagonal R.
    - `state_scale`: shape `(states,)`, typical state magnitudes for the continuity
      defects.
    - `continuity_tol`: allowed defect relative to `state_scale`.
    - `input_delay`: optional `theta -> (inputs,)` time delays, s: input `i` enters the
      model as recorded at `t - delay[i]` (an estimated actuator or sensor lag; linear
      interpolation between samples, so the delay is differentiable).
    """

    rates: Callable = eqx.field(static=True)
    outputs: Callable = eqx.field(static=True)
    t0: float | Float[Array, ""]
    dt: float = eqx.field(static=True)
    inputs: Float[Array, "samples inputs"]
    measured: Float[Array, "samples outputs"]
    free: tuple[bool, ...] = eqx.field(static=True)
    window: int | None = eqx.field(static=True, default=None)
    node_interval: int | None = eqx.field(static=True, default=None)
    free_initial_state: bool = eqx.field(static=True, default=False)
    full_covariance: bool = eqx.field(static=True, default=False)
    state_scale: Float[Array, " states"] | None = None
    continuity_tol: float = eqx.field(static=True, default=1e-4)
    input_delay: Callable | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        if self.node_interval is not None and self.window is not None:
            if self.node_interval % self.window:
                raise ValueError(
                    f"node_interval ({self.node_interval} samples) must be a multiple "
                    f"of the parameter window ({self.window} samples)"
                )

    @property
    def n_samples(self) -> int:
        return self.measured.shape[0]

    @property
    def window_samples(self) -> int:
        """Samples integrated by one diffrax solve."""
        if self.window is not None:
            return self.window
        if self.node_interval is not None:
            return self.node_interval
        return self.n_samples

    @property
    def n_windows(self) -> int:
        return -(-self.n_samples // self.window_samples)

    @property
    def windows_per_segment(self) -> int:
        if self.node_interval is None:
            return self.n_windows
        return self.node_interval // self.window_samples

    @property
    def n_segments(self) -> int:
        return -(-self.n_windows // self.windows_per_segment)

    @property
    def n_param_sets(self) -> int:
        return self.n_windows if self.window is not None else 1

    @property
    def free_index(self) -> np.ndarray:
        return np.flatnonzero(np.asarray(self.free))


def _input_at(problem: OEMProblem, t, theta=None):
    n = problem.inputs.shape[0]
    if problem.input_delay is None or theta is None:
        x = (t - problem.t0) / problem.dt
        i = jnp.clip(jnp.floor(x), 0, n - 2).astype(int)
        frac = jnp.clip(x - i, 0.0, 1.0)
        return problem.inputs[i] * (1 - frac) + problem.inputs[i + 1] * frac
    x = (t - problem.input_delay(theta) - problem.t0) / problem.dt
    i = jnp.clip(jnp.floor(x), 0, n - 2).astype(int)
    frac = jnp.clip(x - i, 0.0, 1.0)
    cols = jnp.arange(problem.inputs.shape[1])
    return problem.inputs[i, cols] * (1 - frac) + problem.inputs[i + 1, cols] * frac


def _window_solve(problem: OEMProblem, x0, theta, t_start, theta_end=None):
    """States at the window's samples and one step beyond, shape `(L + 1, states)`:
    RK4 at the sample step (the engine's `rk4_scan`).

    With `theta_end` the parameters vary linearly in time from `theta` at `t_start`
    to `theta_end` one window later."""
    length = problem.window_samples
    span = length * problem.dt

    def field(t, x, args):
        th = _theta_at(args, t, span)
        return problem.rates(t, x, _input_at(problem, t, th), th)

    ts = t_start + problem.dt * jnp.arange(length + 1)
    args = (theta, theta_end, t_start)
    return rk4_scan(lambda t, x: field(t, x, args), x0, ts, problem.dt), ts


def _theta_at(args, t, span):
    theta, theta_end, t_start = args
    if theta_end is None:
        return theta
    return theta + (theta_end - theta) * ((t - t_start) / span)


def theil_inequality(measured, outputs):
    """Theil's inequality coefficient per output column, `(outputs,)`: 0 a perfect
    fit, above about 0.3 a poor one."""

    def rms(a):
        return jnp.sqrt(jnp.mean(a**2, axis=0))

    return rms(measured - outputs) / (rms(measured) + rms(outputs))


def node_times(problem: OEMProblem) -> np.ndarray:
    """Sample index of every shooting node."""
    per = problem.windows_per_segment * problem.window_samples
    return np.arange(problem.n_segments) * per


def parameter_table(
    names: list[str], estimate, stderr, free=None
) -> list[dict[str, float | str | None]]:
    """Rows of estimate, standard error, relative error (%) and 95% interval."""
    rows = []
    for i, name in enumerate(names):
        est, sd = float(estimate[i]), float(stderr[i])
        fixed = free is not None and not free[i]
        rows.append(
            {
                "parameter": name,
                "estimate": est,
                "stderr": None if fixed else sd,
                "relative_stderr_percent": None
                if fixed or est == 0
                else 100 * sd / abs(est),
                "ci95_low": None if fixed else est - 1.96 * sd,
                "ci95_high": None if fixed else est + 1.96 * sd,
            }
        )
    return rows


def format_parameter_table(rows) -> str:
    """A fixed-width table a flight-test engineer reads."""
    lines = [
        f"{'parameter':>10s} {'estimate':>13s} {'std. error':>12s} {'rel. %':>8s} "
        f"{'95% interval':>29s}"
    ]
    for r in rows:
        if r["stderr"] is None:
            lines.append(
                f"{r['parameter']:>10s} {r['estimate']:13.6g} {'(fixed)':>12s}"
            )
            continue
        rel = r["relative_stderr_percent"]
        lines.append(
            f"{r['parameter']:>10s} {r['estimate']:13.6g} {r['stderr']:12.4g} "
            f"{(rel if rel is not None else float('nan')):8.2f} "
            f"[{r['ci95_low']:12.6g}, {r['ci95_high']:12.6g}]"
        )
    return "\n".join(lines)
