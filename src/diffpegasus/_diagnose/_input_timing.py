"""What the sampled input leaves unknown: where, inside a sample interval, it moved.

A log knows an input only at its samples; the model interpolates it linearly. When
the input steps (a doublet, a 3-2-1-1) at an instant inside a sample interval, the
true input's mean over that interval lies anywhere between the two samples around
it, and the interpolation puts it half way: the model's response after the step is
off by an impulse the log cannot resolve. A filter absorbs such an error as process
noise, and its innovations around the steps stay predictable. So the process-noise
decision treats the input's mean over each such interval as unknown, in the null
and in the alternative alike: a nuisance amplitude per interval, whose direction
is the residuals' sensitivity to that interval's input ([`timing_directions`][]).

Which intervals: those whose unknown could move the weighted sum of squares of the
fit by at least one unit, `(du^2 / 12) |W h|^2 >= 1`, with `du` the input's change
across the interval (the interval's mean uniform within it: variance `du^2 / 12`)
and `W h` the whitened residuals' sensitivity to it ([`timing_intervals`][]). A
smooth input changes little from sample to sample and gives none; nothing here is
tuned on a simulator.
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._estimate._filter_error import problem, run_filter
from .._model import Model, Record


# intervals whose directions are computed in one batch (one compiled program)
BATCH = 16


@functools.lru_cache(maxsize=8)
def _with_timing(model: Model, t0: float, dt: float) -> Model:
    """`model` with one more input per input, `"<input> timing"`, added to that
    input in the state equations at the middle of each sample interval only (the
    RK4 stages between samples; never at a sample, never in the outputs): a
    change of the input inside an interval that leaves its samples as logged."""
    n = len(model.inputs)

    def gate(t):
        s = (t - t0) / dt
        return jnp.abs(s - jnp.floor(s) - 0.5) < 0.25

    def rates(t, x, u, p):
        return model.rates(t, x, u[:n] + jnp.where(gate(t), u[n:], 0.0), p)

    def observe(t, x, u, p):
        return model.observe(t, x, u[:n], p)

    delays = None
    if model.delays is not None:

        def delays(p):
            d = jnp.asarray(model.delays(p))
            return jnp.concatenate([d, jnp.zeros_like(d)])

    return Model(
        model.states,
        (*model.inputs, *(f"{u} timing" for u in model.inputs)),
        model.outputs,
        model.parameters,
        rates,
        observe,
        start=model.start,
        fixed=model.fixed,
        delays=delays,
        state_scale=model.state_scale,
    )


def _directions(model, record, theta, gain, schedule, x0, intervals, delta_u):
    """The innovations' sensitivity `(samples, outputs, k)` of one record's filter
    (gains `gain` `(points, states, outputs)` at sample indices `schedule`; zero
    gain: the simulation) to an impulse of `delta_u` times the sample step in the
    input inside each interval `(input, sample)` of `intervals` (the input
    changed at the RK4 stages in the middle of that interval only, by 3/2
    `delta_u`: RK4 weighs them 2/3), so that the unknown is how far from half way
    inside the interval the input moved, as a fraction of the interval."""
    t = np.asarray(record.t, float)
    n, m = len(t), len(model.inputs)
    dt = float(t[1] - t[0])
    wide = _with_timing(model, float(t[0]), dt)
    inputs = np.asarray(record.inputs, float)
    rec = Record(
        t,
        np.column_stack([inputs, np.zeros_like(inputs)]),
        record.measured,
        x0=np.asarray(x0, float),
        name=record.name,
    )
    prob = problem(wide, [rec], (), x0=np.asarray(x0, float)[None])
    prob = eqx.tree_at(lambda p: p.schedule, prob, jnp.asarray(schedule)[None])
    theta = jnp.asarray(theta, float)
    k = jnp.asarray(gain, float)

    base = prob.layout.inputs
    # samples alternating in sign about the interval: every other interval's
    # middle (the mean of its two samples) stays 0
    rows = np.arange(base.shape[1])
    tangents = np.zeros((len(intervals), *base.shape))
    for j, (col, i) in enumerate(intervals):
        sign = np.where(rows <= i, (-1.0) ** (i - rows), (-1.0) ** (rows - i - 1))
        tangents[j, 0, :, m + col] = 1.5 * delta_u[j] * sign

    out = []
    for s in range(0, len(intervals), BATCH):
        chunk = tangents[s : s + BATCH]
        pad = BATCH - len(chunk)
        if pad:
            chunk = np.concatenate([chunk, np.zeros((pad, *base.shape))])
        out.append(
            np.asarray(_jvps(wide, prob, theta, k, jnp.asarray(chunk)))[
                : BATCH - pad, :n
            ]
        )
    if not out:
        return np.zeros((n, len(model.outputs), 0))
    return np.moveaxis(np.concatenate(out), 0, -1)


@eqx.filter_jit
def _jvps(wide, prob, theta, k, tangents):
    """The innovations' tangents `(batch, length, outputs)` along each of
    `tangents` `(batch, records, samples, inputs)` of the layout's inputs: one
    compiled program per model and shape, shared by every call."""

    def innov(inputs):
        p = eqx.tree_at(lambda q: q.layout.inputs, prob, inputs)
        return run_filter(wide, p, 0, theta, k)[0]

    base = prob.layout.inputs
    return jax.vmap(lambda tt: jax.jvp(innov, (base,), (tt,))[1])(tangents)


def timing_intervals(record, unit) -> list[tuple[int, int]]:
    """The intervals `(input, sample)` whose unknown mean could move the fit's
    weighted sum of squares by one unit or more: `(du^2 / 12) |W h|^2 >= 1`,
    largest first.

    **Arguments:** `record`; `unit` `(inputs,)`: `|W h|^2` for a unit change of
    each input's mean over one interval (measured by the caller in the middle of
    the record).
    """
    u = np.asarray(record.inputs, float)
    du = np.diff(u, axis=0)
    expected = du**2 / 12.0 * np.asarray(unit)[None, :]
    i, col = np.nonzero(expected >= 1.0)
    order = np.argsort(-expected[i, col], kind="stable")
    return [(int(col[j]), int(i[j])) for j in order]


def timing_directions(
    model, record, theta, gain, schedule, x0, residuals, intervals=None
) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """The nuisance directions of the input's unknown sub-sample motion for one
    record's residuals `residuals` `(samples, outputs)` (innovations of the filter
    with gains `gain` `(points, states, outputs)` at sample indices `schedule`, or
    output-error residuals with a zero gain), see the module; `intervals` given
    (another fit's), those, else chosen from this fit ([`timing_intervals`][]).

    **Returns:** `(directions (samples, outputs, k), intervals)`, one column per
    interval `(input, sample)` chosen, scaled to the interval's input change."""
    e = np.asarray(residuals, float)
    n, m = e.shape
    u = np.asarray(record.inputs, float)
    if n < 4 or u.shape[1] == 0:
        return np.zeros((n, m, 0)), []
    if intervals is None:
        w = 1.0 / np.maximum(np.sqrt(np.mean(e**2, axis=0)), np.finfo(float).tiny)
        mid = n // 2
        unit_cols = _directions(
            model,
            record,
            theta,
            gain,
            schedule,
            x0,
            [(c, mid) for c in range(u.shape[1])],
            np.ones(u.shape[1]),
        )
        unit = np.einsum("nok,o->k", unit_cols**2, w**2)
        # a simulation that diverges from the middle of the record resolves nothing
        unit = np.where(np.isfinite(unit), unit, 0.0)
        intervals = timing_intervals(record, unit)
    if not intervals:
        return np.zeros((n, m, 0)), []
    du = np.array([u[i + 1, c] - u[i, c] for c, i in intervals])
    cols = _directions(model, record, theta, gain, schedule, x0, intervals, du)
    return cols, intervals


def project_out(residuals, directions, rmat_diag):
    """Residuals `(samples, outputs)` less their weighted least-squares fit on the
    nuisance `directions` `(samples, outputs, k)` (weights `1 / rmat_diag`): what a
    fit that also adjusts the input's unknown sub-sample motion leaves."""
    e = np.asarray(residuals, float)
    h = np.asarray(directions, float)
    if h.shape[-1] == 0:
        return e
    w = 1.0 / np.sqrt(np.asarray(rmat_diag, float))
    a = (h * w[None, :, None]).reshape(-1, h.shape[-1])
    b = (e * w[None, :]).reshape(-1)
    coef = np.linalg.lstsq(a, b, rcond=None)[0]
    return e - h @ coef
