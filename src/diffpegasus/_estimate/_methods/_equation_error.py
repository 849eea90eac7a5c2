"""`EquationError`: least squares of the observation equations with the measured
states in place of simulated ones (regression; no integration)."""

import equinox as eqx

from .._equation_error import equation_error, EquationErrorFit
from .._estimator import AbstractEstimator


class EquationError(AbstractEstimator):
    """The equation-error method for a model whose outputs are linear in its
    parameters: weighted least squares of the outputs `equations` (default: every
    output that is not a state and that a free parameter enters), the states
    replaced by their measurements. Often a start for [`OutputError`][].

    Returns an [`EquationErrorFit`][] (`max_iter` bounds the re-weighting of the
    equations).
    """

    equations: tuple[str, ...] | None = eqx.field(static=True, default=None)

    def estimate(
        self, model, records, *, max_iter, throw, progress
    ) -> EquationErrorFit:
        del progress
        return equation_error(
            model,
            records,
            equations=self.equations,
            max_iterations=50 if max_iter is None else max(max_iter, 1),
            throw=throw,
        )
