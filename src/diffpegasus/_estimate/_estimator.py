"""The estimator contract: what every estimation method provides, the one result
type every method returns, and the one entry [`estimate`][] that takes a method as a
strategy object (as `diffrax.diffeqsolve(..., solver=)` and
`optimistix.least_squares(fn, solver, y0)` do).

Adding an estimator is one file and one registry line:

1. a module in `_estimate/_methods/` with one final class subclassing
   [`AbstractEstimator`][] (its settings as fields) and implementing
   `estimate(self, model, records, *, max_iter, throw, progress)`, returning a
   subclass of [`AbstractFit`][] (an existing one, or its own final class in the
   same file);
2. one line `"name": Class` in `ESTIMATORS` (`_estimate/_methods/__init__.py`):
   `diffpegasus fit --method name` then runs it with its default settings (and
   `--max-iter`), and reports it through the fields of [`AbstractFit`][].
"""

import abc
from collections.abc import Sequence

import equinox as eqx
import numpy as np
from equinox import AbstractVar

from .._model import Model, Record
from ._engine import RESULTS


def is_successful(result) -> bool:
    """Whether a [`RESULTS`][] item is `successful`, compared on the host (`==` of
    two enumeration items is a JAX operation: a program compiled for one bool)."""
    return int(np.asarray(result._value)) == int(np.asarray(RESULTS.successful._value))


def covariance(stderr, correlation):
    """`(..., k, k)`: the covariance of estimates from their standard errors
    `(..., k)` and correlation `(..., k, k)`, `sd_i corr_ij sd_j` (NumPy or JAX
    arrays, any leading axes: a windowed fit's per window)."""
    return correlation * (stderr[..., :, None] * stderr[..., None, :])


class AbstractFit(eqx.Module):
    """The result of any estimator: what a report, a diagnosis or a user reads.

    **Fields every estimator provides** (NumPy arrays on the host; a subclass adds
    its own, e.g. the filter-error method's process-noise intensities):

    - `model`: the [`Model`][] that was fitted.
    - `params` `(params,)`: estimates in the model's parameter units (held
      parameters at their start values).
    - `free` `(params,)` bool: which parameters were estimated.
    - `stderr` `(params,)`: Cramér-Rao standard errors, assuming white residuals
      (0 or NaN for held parameters).
    - `stderr_corrected` `(params,)`: the same corrected for coloured residuals
      (Morelli and Klein), never below `stderr`; use these to judge estimates from
      real flight data.
    - `correlation` `(params, params)`: correlation of the estimates.
    - `cost`: the method's cost at the estimate (det R of the residuals for the
      maximum-likelihood methods).
    - `result`: a [`RESULTS`][] code; `iterations` taken.
    - `reason`: why the fit stopped and what to try, in words (`""` when it
      converged).
    """

    model: AbstractVar[Model]
    params: AbstractVar[np.ndarray]
    free: AbstractVar[np.ndarray]
    stderr: AbstractVar[np.ndarray]
    stderr_corrected: AbstractVar[np.ndarray]
    correlation: AbstractVar[np.ndarray]
    cost: AbstractVar[float]
    result: AbstractVar[RESULTS]
    iterations: AbstractVar[int]
    reason: AbstractVar[str]

    @property
    def converged(self) -> bool:
        """Whether the fit converged (`result` is `RESULTS.successful`)."""
        return is_successful(self.result)

    @property
    def message(self) -> str:
        """Why the fit stopped, in words, with what to try (`""` when it
        converged)."""
        return self.reason

    def estimates(self) -> dict[str, float]:
        """Every parameter's value by name."""
        return dict(
            zip(self.model.parameters, np.asarray(self.params).tolist(), strict=True)
        )

    def standard_errors(self, corrected: bool = True) -> dict[str, float]:
        """Every estimated parameter's standard error by name: corrected for
        coloured residuals (default) or the plain Cramér-Rao bound."""
        sd = self.stderr_corrected if corrected else self.stderr
        return {
            n: float(s)
            for n, s, f in zip(
                self.model.parameters, np.asarray(sd), self.free, strict=True
            )
            if f
        }

    def covariance_of(
        self, names: Sequence[str] | None = None, corrected: bool = True
    ) -> np.ndarray:
        """`(k, k)` covariance of the estimates of `names` (default: every
        estimated parameter, in the model's order), in their units squared: the
        standard errors (corrected for coloured residuals, or with `corrected=False`
        the Cramér-Rao ones) times the correlation, `sd_i corr_ij sd_j`."""
        params = list(self.model.parameters)
        if names is None:
            idx = [i for i, f in enumerate(np.asarray(self.free)) if f]
        else:
            unknown = [n for n in names if n not in params]
            if unknown:
                raise ValueError(
                    f"no parameter {unknown[0]!r} in the model (parameters: "
                    f"{', '.join(params)})"
                )
            idx = [params.index(n) for n in names]
        sd = np.asarray(self.stderr_corrected if corrected else self.stderr)[idx]
        return covariance(sd, np.asarray(self.correlation)[np.ix_(idx, idx)])

    def high_correlations(self, limit: float = 0.9) -> list[tuple[str, str, float]]:
        """Pairs of estimated parameters correlated above `limit` in magnitude."""
        names, c, free = self.model.parameters, np.asarray(self.correlation), self.free
        return [
            (names[i], names[j], float(c[i, j]))
            for i in range(len(names))
            for j in range(i + 1, len(names))
            if free[i] and free[j] and abs(c[i, j]) > limit
        ]


class AbstractEstimator(eqx.Module):
    """An estimation method: its settings as fields, one method that runs it.

    A concrete estimator is a final class (all fields and `__init__` in it, no
    subclass of a concrete estimator) in its own module under `_estimate/_methods/`,
    registered by one line in `ESTIMATORS`; see the module docstring. Settings that
    change the compiled program are static fields. Validate settings in
    `__check_init__` (a `ValueError` that says how to fix it), data in `estimate`.
    """

    @abc.abstractmethod
    def estimate(
        self,
        model: Model,
        records: tuple[Record, ...],
        *,
        max_iter: int | None,
        throw: bool,
        progress: bool,
    ) -> AbstractFit:
        """Fit `model` to `records` (at least one).

        **Arguments:**

        - `model`: the [`Model`][]; its `fixed` parameters are held at `start`.
        - `records`: the [`Record`][]s (manoeuvres) that share the parameters.
        - `max_iter`: the iteration bound (`None`: the method's adaptive budget,
          iterating while the cost still falls by more than its tolerance, up to a
          generous bound).
        - `throw`: raise a `RuntimeError` with the `reason` when the fit does not
          converge; with `False` return the result with its code.
        - `progress`: print one line per iteration to standard error.

        **Returns:** an [`AbstractFit`][].
        """
