"""`OutputError`: maximum likelihood with the model integrated open loop (single
or multiple shooting) by the structured Levenberg-Marquardt engine."""

import equinox as eqx

from .._estimator import AbstractEstimator
from .._fit import Fit, MultipleShooting, output_error, SingleShooting
from .._solver import BlockLevenbergMarquardt


class OutputError(AbstractEstimator):
    """The output-error method: det(R) of the output residuals minimised over the
    parameters (and, with multiple shooting, the node states), R relaxed between
    Levenberg-Marquardt steps.

    **Fields:**

    - `shooting`: [`SingleShooting`][] (default) or [`MultipleShooting`][]`(interval=s)`.
    - `estimate_initial_state`: estimate each record's initial state (default:
      held at the record's `x0`, by default its first measured sample).
    - `biases`: outputs that get a constant bias per record (estimated).
    - `rtol`: converged when det(R) changes by less than this, relatively.
    - `solver`: `None` (default) iterates in the engine's own loop; a
      [`BlockLevenbergMarquardt`][] takes the same steps through
      `optimistix.least_squares`, one per relaxation of R.
    - `acceleration`: Levenberg-Marquardt with geodesic acceleration (a second-
      order correction of each step from one more evaluation of the residuals):
      the same optimum in fewer steps where the cost's valley bends (the engine's
      loop only). Off by default.

    Returns a [`Fit`][].
    """

    shooting: SingleShooting | MultipleShooting = SingleShooting()
    estimate_initial_state: bool = eqx.field(static=True, default=False)
    biases: tuple[str, ...] = eqx.field(static=True, default=())
    rtol: float = eqx.field(static=True, default=1e-7)
    solver: BlockLevenbergMarquardt | None = eqx.field(static=True, default=None)
    acceleration: bool = eqx.field(static=True, default=False)

    def __check_init__(self):
        if not isinstance(self.shooting, SingleShooting | MultipleShooting):
            raise ValueError(
                "shooting must be dp.SingleShooting() or "
                f"dp.MultipleShooting(interval=...), got {self.shooting!r}"
            )
        if self.acceleration and self.solver is not None:
            raise ValueError("acceleration is the engine's own loop's (solver=None)")
        if not self.rtol > 0:
            raise ValueError(f"rtol must be positive, got {self.rtol}")

    def estimate(self, model, records, *, max_iter, throw, progress) -> Fit:
        return output_error(
            model,
            records,
            shooting=self.shooting,
            initial_state="estimated" if self.estimate_initial_state else "fixed",
            biases=tuple(self.biases),
            rtol=self.rtol,
            max_iter=max_iter,
            throw=throw,
            progress=progress,
            solver=self.solver,
            acceleration=self.acceleration,
        )
