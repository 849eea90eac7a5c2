"""Estimation: the one output-error engine and its layouts, the filter-error method,
equation-error least squares and the neural model, with their results."""

from ._coefficients import (
    MeasuredCoefficients as MeasuredCoefficients,
    reconstruct_coefficients as reconstruct_coefficients,
)
from ._engine import Layout as Layout, RESULTS as RESULTS, Solution as Solution
from ._equation_error import (
    equation_error as equation_error,
    EquationErrorFit as EquationErrorFit,
)
from ._filter_error import (
    FilterErrorFit as FilterErrorFit,
    fit_filter_error as fit_filter_error,
)
from ._fit import (
    Fit as Fit,
    fit as fit,
    MultipleShooting as MultipleShooting,
    simulate as simulate_model,  # noqa: F401
    SingleShooting as SingleShooting,
)
from ._global_oem import (
    fit_global_oem as fit_global_oem,
    GlobalFit as GlobalFit,
    score_test as score_test,
    ScoreTest as ScoreTest,
)
from ._lse import (
    estimate_lse as estimate_lse,
    lse_arrays as lse_arrays,
    lse_batch as lse_batch,
    window_truth as window_truth,
    windowed_least_squares as windowed_least_squares,
)
from ._model import Model as Model, Record as Record
from ._modelfile import load_model_file as load_model_file, ModelSpec as ModelSpec
from ._nn import (
    CoefficientNetwork as CoefficientNetwork,
    estimate_nn as estimate_nn,
    load_network as load_network,
    MinMax as MinMax,
    save_network as save_network,
    train_network as train_network,
)
from ._oem import (
    format_parameter_table as format_parameter_table,
    node_times as node_times,
    OEMProblem as OEMProblem,
    parameter_table as parameter_table,
)
from ._pegasus_oem import (
    estimate_oem as estimate_oem,
    oem_setup as oem_setup,
    OEMSetup as OEMSetup,
    to_body as to_body,
    to_lift_drag as to_lift_drag,
    windowed_lift_drag as windowed_lift_drag,
)
from ._result import Estimates as Estimates
from ._windowed_oem import (
    fit_windowed_oem as fit_windowed_oem,
    WindowedFit as WindowedFit,
)
from ._windows import WindowLayout as WindowLayout


def __getattr__(name):
    # RK4 is a diffrax solver: importing diffrax (with optimistix and lineax) takes
    # 0.4 s, which commands that never use it should not pay
    if name == "RK4":
        from ._rk4 import RK4

        return RK4
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
