from ._columns import load_columns as load_columns, load_record as load_record
from ._diagnose import (
    diagnose_model as diagnose_model,
    score_candidates as score_candidates,
)
from ._engine import Layout as Layout, RESULTS as RESULTS, Solution as Solution
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
from ._model import Model as Model, Record as Record
from ._modelfile import load_model_file as load_model_file, ModelSpec as ModelSpec
