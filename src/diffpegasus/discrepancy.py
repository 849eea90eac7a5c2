"""The model-discrepancy workflow (compare, localise, diagnose, add, refit) as a
library: see the README section "Find what the model is missing"."""

from ._diagnose import (
    channel_metrics as channel_metrics,
    default_candidates as default_candidates,
    derivative_table as derivative_table,
    diagnose as diagnose,
    fit as fit,
    fit_metrics as fit_metrics,
    fit_model as fit_model,
    localise as localise,
    make_model as make_model,
    ModelFit as ModelFit,
    ModelSpec as ModelSpec,
    OUTPUTS as OUTPUTS,
    run_compare as run_compare,
    run_diagnose as run_diagnose,
    run_fit as run_fit,
    Settings as Settings,
)
