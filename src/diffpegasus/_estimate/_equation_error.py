"""Equation-error least squares for any model whose outputs are linear in its
parameters (the textbooks' "regression" method, Jategaonkar ch. 6, Klein & Morelli
ch. 5).

Output error integrates the model; equation error does not: the states in the
observation equations are replaced by their measurements, and each output that is
linear in the parameters becomes one regression equation. For the linear lateral
model ([`lateral_model`][]) the measured `pdot, rdot, ay` are regressed on the
measured `p, r` and the inputs `da, dr, beta` with an intercept (the output bias):
three ordinary least-squares problems, solved here as one.

The regressors are the model's own Jacobian with respect to the parameters (forward
mode, exact for a model linear in them; the function checks the linearity), so there
is one copy of the model equations. Parameters that enter several equations (the
6-DOF rolling and yawing equations share `Cl_*` and `Cn_*` through the product of
inertia) are estimated from all of them jointly, each equation weighted by the inverse
of its residual variance, re-estimated until it settles (generalised least squares;
for equations with disjoint parameters this is exactly ordinary least squares of
each). Standard errors are the usual `s_j^2 (A^T A)^-1` (white residuals assumed:
with coloured equation errors they are optimistic, as the textbooks warn).
"""

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._model import Model, Record
from ._engine import coloured_information, RESULTS
from ._estimator import AbstractFit


class EquationErrorFit(AbstractFit):
    """The result of [`equation_error`][].

    **Fields:**

    - `model`: the model (with its held parameters).
    - `equations`: names of the outputs regressed, in order.
    - `params`: `(params,)` estimates; held and not estimable parameters keep their
      start values.
    - `stderr`: `(params,)` standard errors; NaN for held and not estimable ones.
    - `stderr_corrected`: the same corrected for coloured equation errors
      (Morelli-Klein), never below `stderr`.
    - `free`: `(params,)` the model's free parameters.
    - `covariance`: `(params, params)` covariance of the estimates (zero rows for
      held and not estimable parameters).
    - `estimable`: `(params,)` bool: free and entering at least one equation (a
      state-equation bias, for example, enters none).
    - `sigma`: `(equations,)` residual standard deviation of each equation (units
      of the output).
    - `r2`: `(equations,)` coefficient of determination of each equation.
    - `residuals`: per record `(samples, equations)`.
    - `samples`: number of samples used (all records).
    - `cost`: det of the equations' residual covariance (diagonal); `iterations`
      of the re-weighting; `result` (`successful`) and `reason` (""): a
      regression has no convergence to fail (dependent regressors raise).
    """

    model: Model = eqx.field(static=True)
    equations: tuple[str, ...] = eqx.field(static=True)
    params: np.ndarray
    stderr: np.ndarray
    covariance: np.ndarray
    estimable: np.ndarray
    sigma: np.ndarray
    r2: np.ndarray
    residuals: list
    samples: int = eqx.field(static=True)
    stderr_corrected: np.ndarray
    free: np.ndarray
    cost: float
    iterations: int
    result: RESULTS
    reason: str

    def start(self) -> dict[str, float]:
        """The estimated parameters by name: start values for output error,
        `model.replace(start=ee.start())`."""
        return {
            n: float(v)
            for n, v, e in zip(
                self.model.parameters, self.params, self.estimable, strict=True
            )
            if e
        }

    @property
    def correlation(self) -> np.ndarray:
        """`(params, params)` correlation of the estimates (zero where not
        estimated)."""
        d = np.sqrt(np.diag(self.covariance))
        with np.errstate(invalid="ignore", divide="ignore"):
            c = self.covariance / np.outer(d, d)
        return np.where(np.outer(self.estimable, self.estimable), c, 0.0)

    def table(self) -> list[dict]:
        """One row per parameter: estimate, standard error, relative error (%), 95%
        interval; `estimated` False for held and not estimable parameters."""
        from ._oem import parameter_table

        rows = parameter_table(
            list(self.model.parameters), self.params, self.stderr, self.estimable
        )
        for row, e in zip(rows, self.estimable, strict=True):
            row["estimated"] = bool(e)
        return rows


def _regressors(model, record, states, index, theta0):
    """Model outputs `index` at `theta0` `(samples, k)` and their Jacobian
    `(samples, k, params)` with the measured states `states` `(samples, nx)`."""

    def g(theta, t, x, u):
        return model.g(t, x, u, theta)[index]

    def at(theta):
        return jax.vmap(g, (None, 0, 0, 0))(theta, record.t, states, record.inputs)

    theta0 = jnp.asarray(theta0)
    y0 = at(theta0)
    jac = jax.jacfwd(at)(theta0)
    # linear in the parameters: the outputs at another point are the tangent's
    step = (
        0.1
        * jnp.maximum(jnp.abs(theta0), 1.0)
        * jnp.where(jnp.arange(len(theta0)) % 2 == 0, 1.0, -1.0)
    )
    gap = at(theta0 + step) - (y0 + jac @ step)
    scale = jnp.max(jnp.abs(y0)) + jnp.max(jnp.abs(jac @ step)) + 1e-300
    return np.asarray(y0), np.asarray(jac), float(jnp.max(jnp.abs(gap)) / scale)


def equation_error(
    model: Model,
    records: Record | Sequence[Record],
    *,
    equations: Sequence[str] | None = None,
    states: Sequence | None = None,
    max_iterations: int = 50,
    throw: bool = True,
) -> EquationErrorFit:
    """Equation-error least squares of a model linear in its parameters (see the
    module docstring).

    **Arguments:**

    - `model`: a [`Model`][]; held parameters stay at their start values.
    - `records`: one [`Record`][] or several (the equations of all are stacked).
    - `equations`: the outputs to regress (default: every output that is not
      itself a state and that a free parameter enters, e.g. `pdot, rdot, ay` of
      [`lateral_model`][]).
    - `states`: per record, the measured states `(samples, states)` in the model's
      state units; default the outputs of the same names (a `ValueError` names the
      states that are not measured).
    - `max_iterations`: of the equation re-weighting (one suffices when no parameter
      enters two equations).
    - `throw`: accepted for the one entry's contract (a regression either solves
      or raises a `ValueError` naming what is wrong).

    **Returns:** an [`EquationErrorFit`][].
    """
    records = [records] if isinstance(records, Record) else list(records)
    if not records:
        raise ValueError("equation_error needs at least one record")
    chosen = equations is not None
    if equations is None:
        equations = [o for o in model.outputs if o not in model.states]
    equations = tuple(equations)
    unknown = [e for e in equations if e not in model.outputs]
    if unknown or not equations:
        raise ValueError(
            f"equations {unknown or '()'} are not outputs of the model "
            f"({', '.join(model.outputs)})"
        )
    if states is not None and len(states) != len(records):
        raise ValueError(f"{len(states)} state arrays for {len(records)} records")
    index = np.array([model.outputs.index(e) for e in equations])
    theta0 = np.asarray(model.start, float)
    free = model.free
    rows_a, rows_b, sizes = [], [], []
    for k, rec in enumerate(records):
        rec.check(model)
        if states is None:
            xs = rec.measured_states(model, np.arange(len(rec.t)))
            missing = [s for j, s in enumerate(model.states) if np.isnan(xs[0, j])]
            if missing:
                raise ValueError(
                    f"{rec.name}: states {missing} are not measured outputs; give "
                    "them with states=[(samples, states) per record]"
                )
        else:
            xs = np.asarray(states[k], float)
            if xs.shape != (len(rec.t), len(model.states)):
                raise ValueError(
                    f"{rec.name}: states must be ({len(rec.t)}, {len(model.states)})"
                    f", got {xs.shape}"
                )
        y0, jac, gap = _regressors(model, rec, xs, index, theta0)
        if gap > 1e-8:
            raise ValueError(
                f"the outputs {equations} are not linear in the parameters (relative "
                f"gap {gap:.2g}); equation error needs a model linear in them (fit "
                "it by output error instead)"
            )
        # y = y0 + J (theta - theta0): the free part is the regression
        z = rec.measured[:, index] - y0 + jac[..., free] @ theta0[free]
        rows_a.append(jac[..., free])
        rows_b.append(z)
        sizes.append(len(rec.t))
    a = np.concatenate(rows_a)  # (N, k, f)
    b = np.concatenate(rows_b)  # (N, k)
    enters = np.any(a != 0.0, axis=0)  # (k, f): parameter enters equation
    if not chosen:
        # by default only the outputs some free parameter enters (not, e.g., a
        # sideslip computed from the states alone)
        keep = enters.any(axis=1)
        equations = tuple(e for e, k in zip(equations, keep, strict=True) if k)
        index = index[keep]
        a, b, enters = a[:, keep], b[:, keep], enters[keep]
    n, k = b.shape
    used = enters.any(axis=0)
    a = a[..., used]
    per_eq = enters[:, used].sum(axis=1)
    if np.any(per_eq >= n):
        raise ValueError(f"{n} samples are too few for {per_eq.max()} parameters")
    del throw
    weight = np.ones(k)
    est = np.zeros(a.shape[-1])
    iterations = 0
    for _ in range(max_iterations):
        iterations += 1
        aw = (a * weight[None, :, None]).reshape(n * k, -1)
        bw = (b * weight[None, :]).reshape(-1)
        scale = np.linalg.norm(aw, axis=0)
        sol, _, rank, _ = np.linalg.lstsq(aw / scale, bw, rcond=None)
        if rank < aw.shape[1]:
            raise ValueError(
                "the regressors are linearly dependent: the records do not excite "
                "every estimated parameter"
            )
        est = sol / scale
        resid = b - np.einsum("nkf,f->nk", a, est)
        sigma = np.sqrt(np.sum(resid**2, axis=0) / (n - per_eq))
        # (an equation fitted exactly, e.g. noise-free data: a finite weight)
        new = 1.0 / np.maximum(sigma, 1e-150)
        if np.max(np.abs(new - weight) / new) < 1e-12:
            weight = new
            break
        weight = new
    aw = (a * weight[None, :, None]).reshape(n * k, -1)
    cov_used = np.linalg.inv(aw.T @ aw)
    p = len(model.parameters)
    free_idx = np.flatnonzero(free)[used]
    params = theta0.copy()
    params[free_idx] = est
    cov = np.zeros((p, p))
    cov[np.ix_(free_idx, free_idx)] = cov_used
    stderr = np.full(p, np.nan)
    stderr[free_idx] = np.sqrt(np.diag(cov_used))
    estimable = np.zeros(p, bool)
    estimable[free_idx] = True
    resid = b - np.einsum("nkf,f->nk", a, est)
    sigma = np.sqrt(np.sum(resid**2, axis=0) / (n - per_eq))
    # Morelli-Klein per record (lags do not cross records)
    kk = a * weight[None, :, None] @ cov_used  # (N, k, f)
    starts = np.r_[0, np.cumsum(sizes)]
    info = sum(
        np.asarray(
            coloured_information(
                jnp.asarray(kk[i:j]), jnp.asarray(resid[i:j] * weight[None, :])
            )
        )
        for i, j in zip(starts[:-1], starts[1:], strict=True)
    )
    stderr_c = np.full(p, np.nan)
    stderr_c[free_idx] = np.maximum(
        np.sqrt(np.clip(np.diag(info), 0.0, None)), stderr[free_idx]
    )
    # R^2 of the measured output (the regressand holds the held terms too)
    meas = np.concatenate([r.measured[:, index] for r in records])
    r2 = 1.0 - np.sum(resid**2, axis=0) / np.sum((meas - meas.mean(0)) ** 2, axis=0)
    return EquationErrorFit(
        model=model,
        equations=equations,
        params=params,
        stderr=stderr,
        covariance=cov,
        estimable=estimable,
        sigma=sigma,
        r2=r2,
        residuals=list(np.split(resid, np.cumsum(sizes)[:-1])),
        samples=n,
        stderr_corrected=stderr_c,
        free=np.asarray(free),
        cost=float(np.prod(np.sum(resid**2, axis=0) / n)),
        iterations=iterations,
        result=RESULTS.successful,
        reason="",
    )
