"""Estimators: one module per method, sharing window bookkeeping and results."""

from ._coefficients import (
    MeasuredCoefficients as MeasuredCoefficients,
    reconstruct_coefficients as reconstruct_coefficients,
)
from ._lse import (
    estimate_lse as estimate_lse,
    lse_arrays as lse_arrays,
    lse_batch as lse_batch,
    window_truth as window_truth,
    windowed_least_squares as windowed_least_squares,
)
from ._result import Estimates as Estimates
from ._windows import WindowLayout as WindowLayout
