"""The estimation methods, one module each, and the registry of their names.

`ESTIMATORS` maps the name the command line's `fit --method NAME` takes to the
estimator class (built with its default settings there). A new method is one
module here and one line below (see `_estimate/_estimator.py`).
"""

from .._estimator import AbstractEstimator
from ._equation_error import EquationError as EquationError
from ._filter_error import FilterError as FilterError
from ._frequency import (
    FrequencyEquationError as FrequencyEquationError,
    FrequencyOutputError as FrequencyOutputError,
)
from ._output_error import OutputError as OutputError


ESTIMATORS: dict[str, type[AbstractEstimator]] = {
    "oem": OutputError,
    "fem": FilterError,
    "eqe": EquationError,
    "fdoe": FrequencyOutputError,
    "fdee": FrequencyEquationError,
}
