"""`estimate(model, records, method)`: the one entry for estimation, taking an
estimator strategy the way `diffeqsolve(..., solver=)` does (see
[`AbstractEstimator`][] for the contract a method fulfils)."""

from collections.abc import Sequence

from .._model import Model, Record
from ._estimator import AbstractEstimator, AbstractFit
from ._methods import OutputError


def estimate(
    model: Model,
    records: Record | Sequence[Record],
    method: AbstractEstimator | None = None,
    *,
    max_iter: int | None = None,
    throw: bool = True,
    progress: bool = False,
) -> AbstractFit:
    """Estimate `model`'s parameters from flight records by `method`.

    **Arguments:**

    - `model`: a [`Model`][] (states, inputs, outputs, parameters with start
      values, held ones).
    - `records`: a [`Record`][] or a sequence of them (manoeuvres sharing the
      parameters; any lengths and sample rates).
    - `method`: an estimator: [`OutputError`][] (the default, single shooting),
      [`FilterError`][], [`EquationError`][], or any other [`AbstractEstimator`][].
    - `max_iter`: iteration bound; `None` (default) is the method's adaptive
      budget.
    - `throw`: raise a `RuntimeError` saying why when the fit does not converge;
      with `False` the result carries the code (`result`) and `reason`.
    - `progress`: one line per iteration on standard error (for long fits).

    **Returns:** an [`AbstractFit`][] subclass: `estimates()`, `stderr`,
    `stderr_corrected`, `correlation`, `cost`, `result`, `iterations`, `reason`.
    """
    if method is None:
        method = OutputError()
    if not isinstance(method, AbstractEstimator):
        raise TypeError(
            f"method must be an estimator such as dp.OutputError(), got "
            f"{type(method).__name__}"
        )
    records = (records,) if isinstance(records, Record) else tuple(records)
    if not records:
        raise ValueError("no records to fit")
    if max_iter is not None and not (isinstance(max_iter, int) and max_iter >= 0):
        raise ValueError(f"max_iter must be a non-negative integer, got {max_iter!r}")
    return method.estimate(
        model, records, max_iter=max_iter, throw=throw, progress=progress
    )
