"""Frequency-domain equation error and output error for models linear in their
states and inputs (Klein & Morelli, *Aircraft System Identification*, chapter 7;
SIDPAC's `fdee` and `fdoe`).

Every record is transformed at its grid frequencies in a band ([`frequency_grid`][]):
biases and trim values have no transform there, so they are neither modelled nor
estimated. The finite transform of a state derivative is `j w X + x(T) - x(0)`, so the
state equations read, per record and frequency,

    j w X = A X + B U - dx,   Y = C X + D U,

with `dx = x(T) - x(0)` one real unknown per state and record (the end term; it
replaces the initial state of the time domain, and lets records start and end
anywhere).

- **Equation error** ([`frequency_equation_error`][]) puts the measured states in
  `X`: each state equation, and each output equation that has parameters, is a
  complex linear regression; they are solved together by weighted least squares
  (weights re-estimated from the residuals), so a parameter in several equations
  uses them all. The model must be linear in its estimated parameters.
- **Output error** ([`frequency_output_error`][]) solves `X = (j w I - A)^-1 (B U -
  dx)` and minimises `sum_k v_k^H S^-1 v_k`, `v = Z - Y`, with `S` the diagonal
  residual power, by Gauss-Newton with Levenberg-Marquardt damping. The parameters
  may enter nonlinearly; an unstable model is no harder than a stable one (no
  integration).

**Error bounds.** The Cramér-Rao bound is the inverse of `2 Re(J^H S^-1 J)` summed over
frequencies. It assumes the residual power is the same at every frequency (white
residuals). The corrected bound does not: the residual transforms at different grid
frequencies are nearly independent, so the covariance is the sandwich `M^-1 (sum_k
1/2 Re(s_k s_k^H)) M^-1` with `s_k = sum_j 2/S_j conj(J_kj) v_kj` built from each
frequency's own residuals (the frequency-domain form of the Morelli-Klein correction
for coloured residuals); it is reported never below the plain bound.
"""

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._engine import RESULTS
from ._estimator import AbstractFit
from ._fourier import finite_fourier, frequency_grid
from ._linear import (
    check_linear,
    check_linear_in_parameters,
    linear_system,
    parameter_sensitivity,
    system_jacobian,
)
from ._model import Model, Record


class FrequencyFit(AbstractFit):
    """A frequency-domain fit of a linear [`Model`][] to records.

    **Fields:**

    - `model`, `records`: what was fitted; `method`: `"fdee"` or `"fdoe"`.
    - `params` `(params,)`: estimates (held and not estimable ones at their start).
    - `free` `(params,)`: estimated here (free in the model and acting on the
      frequency grid: biases and trim constants do not).
    - `stderr` `(params,)`: Cramér-Rao standard errors; `stderr_corrected`: the same
      for the residuals' own spectrum (coloured residuals), never below `stderr`;
      NaN where not estimated.
    - `covariance` `(params, params)`: the corrected covariance (zero rows where not
      estimated); `correlation` from it.
    - `end_terms` `(records, states)`: `x(T) - x(0)` of every record (state units).
    - `frequencies`: per record, the grid frequencies used, Hz.
    - `measured`, `modelled`: per record `(frequencies, outputs)` complex, the
      transforms of the measured and the model outputs (output units times s).
    - `inputs`: per record `(frequencies, inputs)` complex, the inputs' transforms.
    - `noise`: `(outputs,)` residual power per output (output units times s, squared)
      averaged over the band.
    - `cost`: `sum_j log S_j` at the estimate; `iterations`; `result` a
      [`RESULTS`][] code (`converged` the bool) and `reason` in words.
    """

    model: Model = eqx.field(static=True)
    records: tuple[Record, ...]
    method: str = eqx.field(static=True)
    params: np.ndarray
    free: np.ndarray
    stderr: np.ndarray
    stderr_corrected: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    end_terms: np.ndarray
    frequencies: tuple[np.ndarray, ...]
    measured: tuple[np.ndarray, ...]
    modelled: tuple[np.ndarray, ...]
    inputs: tuple[np.ndarray, ...]
    noise: np.ndarray
    cost: float
    iterations: int
    result: RESULTS
    reason: str

    def residual_spectrum(self, record: int = 0) -> np.ndarray:
        """`(frequencies, outputs)`: `|Z - Y|^2` of one record (output units times s,
        squared): flat for white residuals, peaked where the model misses dynamics."""
        return np.abs(self.measured[record] - self.modelled[record]) ** 2

    def table(self) -> list[dict]:
        """One row per parameter: estimate, corrected standard error and plain bound,
        relative error (%), 95% interval; `estimated` False where not estimated."""
        from ._oem import parameter_table

        rows = parameter_table(
            list(self.model.parameters),
            self.params,
            np.nan_to_num(self.stderr_corrected),
            self.free,
        )
        for row, crb, e in zip(rows, self.stderr, self.free, strict=True):
            row["stderr_crb"] = float(crb) if e else None
            row["estimated"] = bool(e)
        return rows


def default_band(records: Sequence[Record]) -> tuple[float, float]:
    """`(0, high)` Hz: `high` is where the inputs' power above it falls below 1% of
    their power (the widest over inputs and records), at most 80% of the Nyquist
    frequency: the band where the manoeuvre excites the aircraft."""
    high = 0.0
    for rec in records:
        u = rec.inputs - rec.inputs.mean(axis=0)
        f = np.fft.rfftfreq(len(rec.t), rec.dt)
        power = np.abs(np.fft.rfft(u, axis=0)) ** 2
        total = power.sum(axis=0)
        for j in range(power.shape[1]):
            if total[j] <= 0:
                continue
            cum = np.cumsum(power[:, j]) / total[j]
            high = max(high, float(f[np.searchsorted(cum, 0.99)]))
        high = min(max(high, 0.0), 0.8 * 0.5 / rec.dt)
    if high <= 0:
        raise ValueError("the records' inputs are constant: nothing excites the model")
    return 0.0, high


class _Transforms(eqx.Module):
    """One record on its grid: `f` Hz, the trapezoidal transforms `u`, `z` of the
    inputs and outputs, their end changes `du = u(T) - u(0)`, `dz`, and `dt`."""

    f: np.ndarray
    u: np.ndarray
    z: np.ndarray
    du: np.ndarray
    dz: np.ndarray
    dt: float

    def sums(self, which):
        """The rectangle sums over all samples but the last (the sampled-data
        model's transforms): the trapezoid minus `dt/2 (x(T) - x(0))` on the grid."""
        x, d = (self.u, self.du) if which == "u" else (self.z, self.dz)
        return x - 0.5 * self.dt * d[None, :]


def _transforms(model, records, band, every):
    """Per record, its [`_Transforms`][]."""
    del model
    out = []
    for rec in records:
        f = frequency_grid(len(rec.t), rec.dt, band, every=every)
        u = np.asarray(finite_fourier(rec.inputs, rec.dt, f))
        z = np.asarray(finite_fourier(rec.measured, rec.dt, f))
        du = rec.inputs[-1] - rec.inputs[0]
        dz = rec.measured[-1] - rec.measured[0]
        out.append(_Transforms(f, u, z, du, dz, rec.dt))
    return out


def _prepare(model, records, band, every):
    records = (records,) if isinstance(records, Record) else tuple(records)
    if not records:
        raise ValueError("no records to fit")
    for rec in records:
        rec.check(model)
    start = np.asarray(model.start, float)
    check_linear(model, start, records[0])
    band = default_band(records) if band is None else band
    sensitive = parameter_sensitivity(model, start)
    estimable = np.asarray(model.free) & sensitive
    if not estimable.any():
        raise ValueError(
            "no free parameter changes the model's A, B, C or D: nothing to estimate "
            "in the frequency domain (biases and trim constants have no transform "
            "on the frequency grid)"
        )
    return records, start, estimable, _transforms(model, records, band, every)


def _covariances(jac_rows, resid_rows, weight_rows, groups):
    """Plain and coloured-residual covariances of a weighted complex least-squares
    fit. `jac_rows` `(rows, p)` complex d(model)/dz, `resid_rows` `(rows,)` complex,
    `weight_rows` `(rows,)` `1/S` of each row's channel, `groups` `(rows,)` int: rows
    of one frequency of one record share a group (their residuals may correlate)."""
    wj = jac_rows * weight_rows[:, None]
    info = 2.0 * np.real(wj.conj().T @ jac_rows)
    cov = np.linalg.pinv(info, hermitian=True)
    score = 2.0 * wj.conj() * resid_rows[:, None]
    n_groups = int(groups.max()) + 1
    s = np.zeros((n_groups, jac_rows.shape[1]), complex)
    np.add.at(s, groups, score)
    middle = 0.5 * np.real(s.T @ s.conj())
    rows, p = jac_rows.shape
    dof = 2 * rows / max(2 * rows - p, 1)
    cov_c = cov @ middle @ cov * dof
    return cov, cov_c


def _expand(cov, active):
    """A covariance of the active unknowns as one of all (zeros elsewhere)."""
    full = np.zeros((len(active), len(active)))
    full[np.ix_(active, active)] = cov
    return full


def _result(model, records, method, start, estimable, z, cov, cov_c, extra):
    p = len(model.parameters)
    idx = np.flatnonzero(estimable)
    k = len(idx)
    params = start.copy()
    params[idx] = z[:k]
    sd = np.full(p, np.nan)
    sd_c = np.full(p, np.nan)
    var = np.clip(np.diag(cov)[:k], 0.0, None)
    var_c = np.maximum(np.clip(np.diag(cov_c)[:k], 0.0, None), var)
    sd[idx], sd_c[idx] = np.sqrt(var), np.sqrt(var_c)
    full = np.zeros((p, p))
    full[np.ix_(idx, idx)] = cov_c[:k, :k]
    d = np.sqrt(np.clip(np.diag(full), 1e-300, None))
    correlation = np.where(np.outer(estimable, estimable), full / np.outer(d, d), 0.0)
    converged = extra.pop("converged")
    code = RESULTS.successful
    if not converged:
        code = (
            RESULTS.max_iterations
            if extra["iterations"] >= extra.pop("max_iter", 10**9)
            else RESULTS.slow_progress
        )
    extra.pop("max_iter", None)
    return FrequencyFit(
        model=model,
        records=records,
        method=method,
        params=params,
        free=estimable,
        stderr=sd,
        stderr_corrected=sd_c,
        covariance=full,
        correlation=correlation,
        end_terms=z[k:].reshape(len(records), len(model.states)),
        cost=float(np.sum(np.log(np.maximum(extra["noise"], 1e-300)))),
        result=code,
        **extra,
    )


def _expm(m, squarings: int = 10, terms: int = 16):
    """`exp(m)` by a Taylor series of `m / 2^squarings` squared back: no control
    flow, so a small program to compile and to differentiate (jax.scipy's expm
    selects its Padé order at run time). Accurate to rounding for `|m|` up to
    about 2^squarings; the sampled dynamics of a flight record are `|A dt| < 10`."""
    x = m / 2.0**squarings
    term = jnp.eye(m.shape[0], dtype=m.dtype)
    out = term
    for k in range(1, terms + 1):
        term = term @ x / k
        out = out + term
    for _ in range(squarings):
        out = out @ out
    return out


def _sampled_system(a, b, dt):
    """`Phi, G0, G1` of the exact discretisation with inputs linear between samples:
    `x[k+1] = Phi x[k] + G0 u[k] + G1 u[k+1]` (the time-domain engine's model)."""
    nx, nu = b.shape
    n = nx + 2 * nu
    f = jnp.zeros((n, n), a.dtype)
    f = f.at[:nx, :nx].set(a).at[:nx, nx : nx + nu].set(b)
    f = f.at[nx : nx + nu, nx + nu :].set(jnp.eye(nu))
    e = _expm(f * dt)
    phi, g1, g2 = e[:nx, :nx], e[:nx, nx : nx + nu], e[:nx, nx + nu :] / dt
    return phi, g1 - g2, g2


@eqx.filter_jit
def _predict(model, z, estimable_idx, start, u, w, nx, dt, du):
    """Model output transforms `(f, outputs)` for the unknowns `z` (estimated
    parameters then this record's end terms `x(T) - x(0)`), from the input transforms
    `u` `(f, inputs)` at `w = 2 pi f` and the input's end change `du` `(inputs,)`.

    The record is a sampled-data system: with `z = exp(j w dt)`, on the grid the
    transforms satisfy exactly `(z I - Phi) X = (G0 + z G1) U + z G1 dt du - z dt dx`
    and `Y = C X + D U` ([`_sampled_system`][]); as `dt -> 0` this is the continuous
    `(j w I - A) X = B U - dx`.
    """
    k = len(estimable_idx)
    theta = jnp.asarray(start).at[estimable_idx].set(z[:k])
    dx = z[k : k + nx]
    a, b, c, d = linear_system(model, theta)
    delays = model.input_delays(theta)
    if delays is not None:
        u = u * jnp.exp(-1j * w[:, None] * delays[None, :])
    phi, g0, g1 = _sampled_system(a, b, dt)
    zz = jnp.exp(1j * w * dt)[:, None]
    m = zz[:, :, None] * jnp.eye(nx)[None] - phi[None]
    rhs = u @ g0.T + zz * (u @ g1.T) + zz * (dt * (g1 @ du) - dt * dx)[None, :]
    x = jnp.linalg.solve(m, rhs[..., None])[..., 0]
    return x @ c.T.astype(x.dtype) + u @ d.T.astype(u.dtype)


def _model_outputs(model, records, data, params, end_terms):
    """Per record, the model output transforms at `params` and `end_terms`."""
    out = []
    nx = len(model.states)
    for r, d in enumerate(data):
        y = _predict(
            model.structure(),
            jnp.asarray(end_terms[r], float),
            jnp.zeros(0, int),
            jnp.asarray(params),
            jnp.asarray(d.sums("u")),
            jnp.asarray(2 * np.pi * d.f),
            nx,
            d.dt,
            jnp.asarray(d.du),
        )
        out.append(np.asarray(y))
    return tuple(out)


def frequency_equation_error(
    model: Model,
    records: Record | Sequence[Record],
    *,
    band: tuple[float, float] | None = None,
    every: int = 1,
    weighting_passes: int = 4,
) -> FrequencyFit:
    """Frequency-domain equation error: every state equation (and every output
    equation with parameters) as a complex regression on the measured states' and
    inputs' transforms.

    **Arguments:**

    - `model`: a [`Model`][] linear in its states and inputs and in its estimated
      parameters, every state measured (an output of the same name).
    - `records`: one [`Record`][] or several (each on its own frequency grid).
    - `band`: `(low, high)` Hz; default [`default_band`][] of the records.
    - `every`: use every `every`-th grid frequency.
    - `weighting_passes`: least-squares passes, each weighting the equations by the
      inverse of their residual power from the previous one.

    **Returns:** a [`FrequencyFit`][] with `method="fdee"`.
    """
    records, start, estimable, data = _prepare(model, records, band, every)
    missing = [s for s in model.states if s not in model.outputs]
    if missing:
        raise ValueError(
            f"equation error needs every state measured; {missing} are not outputs "
            "of the model (use output error, method 'fdoe')"
        )
    check_linear_in_parameters(model, start, estimable)
    nx, ny = len(model.states), len(model.outputs)
    idx = np.flatnonzero(estimable)
    mats, jac = system_jacobian(model.structure(), jnp.asarray(start))
    # the part of each matrix the estimated parameters do not carry
    base = [
        np.asarray(m) - np.asarray(j)[..., idx] @ start[idx]
        for m, j in zip(mats, jac, strict=True)
    ]
    dmat = [np.asarray(j)[..., idx] for j in jac]
    state_rows = [model.outputs.index(s) for s in model.states]
    out_eq = [j for j in range(ny) if np.any(dmat[2][j]) or np.any(dmat[3][j])]
    k, n_rec = len(idx), len(records)
    rows_h, rows_y, rows_eq, rows_group = [], [], [], []
    group = 0
    for r, d in enumerate(data):
        f, u, zt = d.f, d.sums("u"), d.sums("z")
        zf = np.exp(2j * np.pi * f * d.dt)
        # the derivative's transform by the trapezoidal rule between samples
        # (Tustin): s X + 2z/(z+1) (end term), s = 2/dt (z-1)/(z+1) -> j w
        s_op = 2.0 / d.dt * (zf - 1.0) / (zf + 1.0)
        end = 2.0 * zf / (zf + 1.0)
        xs = zt[:, state_rows]
        for i in range(nx):
            h = np.zeros((len(f), k + n_rec * nx), complex)
            h[:, :k] = xs @ dmat[0][i] + u @ dmat[1][i]
            h[:, k + r * nx + i] = -end
            y = s_op * xs[:, i] - xs @ base[0][i] - u @ base[1][i]
            rows_h.append(h), rows_y.append(y)
            (
                rows_eq.append(np.full(len(f), i)),
                rows_group.append(group + np.arange(len(f))),
            )
        for j in out_eq:
            h = np.zeros((len(f), k + n_rec * nx), complex)
            h[:, :k] = xs @ dmat[2][j] + u @ dmat[3][j]
            y = zt[:, j] - xs @ base[2][j] - u @ base[3][j]
            rows_h.append(h), rows_y.append(y)
            (
                rows_eq.append(np.full(len(f), nx + j)),
                rows_group.append(group + np.arange(len(f))),
            )
        group += len(f)
    h = np.concatenate(rows_h)
    y = np.concatenate(rows_y)
    eq = np.concatenate(rows_eq)
    groups = np.concatenate(rows_group)
    weight = np.ones(len(y))
    for _ in range(max(1, weighting_passes)):
        hr = np.concatenate([h.real, h.imag]) * np.sqrt(np.r_[weight, weight])[:, None]
        yr = np.concatenate([y.real, y.imag]) * np.sqrt(np.r_[weight, weight])
        z, *_ = np.linalg.lstsq(hr, yr, rcond=None)
        e = y - h @ z
        power = {int(q): float(np.mean(np.abs(e[eq == q]) ** 2)) for q in np.unique(eq)}
        weight = np.array([1.0 / max(power[int(q)], 1e-300) for q in eq])
    cov, cov_c = _covariances(h, e, weight, groups)
    end_terms = z[k:].reshape(n_rec, nx)
    params = start.copy()
    params[idx] = z[:k]
    modelled = _model_outputs(model, records, data, params, end_terms)
    noise = np.mean(
        np.concatenate(
            [np.abs(d.sums("z") - m) ** 2 for d, m in zip(data, modelled, strict=True)]
        ),
        axis=0,
    )
    return _result(
        model,
        records,
        "fdee",
        start,
        estimable,
        z,
        cov,
        cov_c,
        dict(
            frequencies=tuple(d.f for d in data),
            measured=tuple(d.sums("z") for d in data),
            modelled=modelled,
            inputs=tuple(d.sums("u") for d in data),
            noise=noise,
            iterations=max(1, weighting_passes),
            converged=True,
            reason="",
        ),
    )


@eqx.filter_jit
def _residuals_and_jacobian(model, z, idx, start, us, ws, zs, dts, dus, nx, n_rec):
    """Per record, the complex residuals `(f, outputs)` and their Jacobian with
    respect to all unknowns `(f, outputs, unknowns)`."""
    k = idx.shape[0]

    def resid(zz, r):
        mine = jnp.concatenate([zz[:k], zz[k + r * nx : k + (r + 1) * nx]])
        return zs[r] - _predict(
            model, mine, idx, start, us[r], ws[r], nx, dts[r], dus[r]
        )

    out = []
    for r in range(n_rec):
        e = resid(z, r)
        j = jax.jacfwd(lambda zz, r=r: -resid(zz, r))(z)
        out.append((e, j))
    return out


def frequency_output_error(
    model: Model,
    records: Record | Sequence[Record],
    *,
    band: tuple[float, float] | None = None,
    every: int = 1,
    start=None,
    end_terms: str = "estimated",
    rtol: float = 1e-9,
    max_iter: int = 100,
    throw: bool = True,
) -> FrequencyFit:
    """Frequency-domain output error: the maximum-likelihood fit of the model's output
    transforms to the measured ones.

    **Arguments:**

    - `model`: a [`Model`][] linear in its states and inputs (the parameters may
      enter nonlinearly); its `delays`, if any, become phase lags `exp(-j w tau)`.
    - `records`: one [`Record`][] or several (each on its own frequency grid, each
      with its own end terms).
    - `band`: `(low, high)` Hz; default [`default_band`][] of the records.
    - `every`: use every `every`-th grid frequency.
    - `start`: start values `(params,)` (default `model.start`; a frequency-domain
      equation-error fit is a good start when every state is measured).
    - `end_terms`: `"estimated"` (default) or `"measured"`: each record's `x(T) -
      x(0)` held at the measured states' (states that are not outputs are
      estimated either way).
    - `rtol`: stop when the cost `sum_j log S_j` changes by less than this.
    - `max_iter`: iteration cap.
    - `throw`: raise a `RuntimeError` if the fit does not converge; with
      `throw=False` the result says so in `converged` and `message`.

    **Returns:** a [`FrequencyFit`][] with `method="fdoe"`.
    """
    model0 = model if start is None else model.replace(start=tuple(map(float, start)))
    records, start, estimable, data = _prepare(model0, records, band, every)
    nx, ny = len(model.states), len(model.outputs)
    idx = np.flatnonzero(estimable)
    k, n_rec = len(idx), len(records)
    us = tuple(jnp.asarray(d.sums("u")) for d in data)
    ws = tuple(jnp.asarray(2 * np.pi * d.f) for d in data)
    zs = tuple(jnp.asarray(d.sums("z")) for d in data)
    dts = tuple(d.dt for d in data)
    dus = tuple(jnp.asarray(d.du) for d in data)
    structure = model.structure()

    def evaluate(z):
        parts = _residuals_and_jacobian(
            structure,
            jnp.asarray(z),
            jnp.asarray(idx),
            jnp.asarray(start),
            us,
            ws,
            zs,
            dts,
            dus,
            nx,
            n_rec,
        )
        e = np.concatenate([np.asarray(p[0]) for p in parts])
        j = np.concatenate([np.asarray(p[1]) for p in parts])
        return e, j

    def cost(e):
        return float(
            np.sum(np.log(np.maximum(np.mean(np.abs(e) ** 2, axis=0), 1e-300)))
        )

    # end terms from the measured states where there are any, else 0
    if end_terms not in ("estimated", "measured"):
        raise ValueError(
            f"end_terms must be 'estimated' or 'measured', got {end_terms!r}"
        )
    z = np.zeros(k + n_rec * nx)
    z[:k] = start[idx]
    active = np.ones(len(z), bool)
    for r, rec in enumerate(records):
        xs = rec.measured_states(model, [0, len(rec.t) - 1])
        z[k + r * nx : k + (r + 1) * nx] = np.nan_to_num(xs[1] - xs[0])
        if end_terms == "measured":
            active[k + r * nx : k + (r + 1) * nx] = np.isnan(xs[0])
    e, j = evaluate(z)
    current = cost(e)
    damping, converged, message, iterations = 1e-6, False, "", 0
    for it in range(1, max_iter + 1):
        iterations = it
        s = np.maximum(np.mean(np.abs(e) ** 2, axis=0), 1e-300)
        jr = np.concatenate([j.real, j.imag]) / np.sqrt(s)[None, :, None]
        er = np.concatenate([e.real, e.imag]) / np.sqrt(s)[None, :]
        jr = jr.reshape(-1, len(z)) * active[None, :]
        er = er.reshape(-1)
        g = jr.T @ er
        info = jr.T @ jr
        scale = np.sqrt(np.maximum(np.diag(info), 1e-300))
        scale = np.where(active, scale, 1.0)
        improved = False
        while damping < 1e12:
            step = (
                np.linalg.solve(
                    info / np.outer(scale, scale) + damping * np.eye(len(z)), g / scale
                )
                / scale
            )
            e_new, j_new = evaluate(z + step)
            new = cost(e_new)
            if np.isfinite(new) and new <= current:
                improved = True
                break
            damping *= 10.0
        if not improved:
            # at the optimum to rounding: the gradient is what is left
            converged = bool(np.max(np.abs(g / scale)) < 1e-6 * np.sqrt(len(er)))
            message = (
                ""
                if converged
                else "no step reduces the cost (start from a frequency-domain "
                "equation-error fit, method 'fdee', or hold poorly identified "
                "parameters)"
            )
            break
        z, e, j = z + step, e_new, j_new
        change = current - new
        current = new
        damping = max(damping / 10.0, 1e-9)
        if change <= rtol * max(1.0, abs(current)):
            converged = True
            break
    else:
        message = RESULTS[RESULTS.max_iterations]
    s = np.maximum(np.mean(np.abs(e) ** 2, axis=0), 1e-300)
    groups = np.repeat(np.arange(e.shape[0]), ny)
    cov, cov_c = _covariances(
        j.reshape(-1, len(z))[:, active],
        e.reshape(-1),
        np.tile(1.0 / s, e.shape[0]),
        groups,
    )
    cov, cov_c = (_expand(c, active) for c in (cov, cov_c))
    params = start.copy()
    params[idx] = z[:k]
    end_terms = z[k:].reshape(n_rec, nx)
    modelled = _model_outputs(model, records, data, params, end_terms)
    out = _result(
        model,
        records,
        "fdoe",
        start,
        estimable,
        z,
        cov,
        cov_c,
        dict(
            frequencies=tuple(d.f for d in data),
            measured=tuple(d.sums("z") for d in data),
            modelled=modelled,
            inputs=tuple(d.sums("u") for d in data),
            noise=s,
            iterations=iterations,
            max_iter=max_iter,
            converged=bool(converged),
            reason=message,
        ),
    )
    if throw and not out.converged:
        raise RuntimeError(f"frequency-domain output error failed: {message}")
    return out
