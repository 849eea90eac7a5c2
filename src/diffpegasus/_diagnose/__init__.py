"""Diagnosis: which held term or physical effect explains a misfit. The score test
of candidates for any model, and the Pegasus discrepancy workflow (compare, localise,
diagnose, add, refit)."""

from ._candidates import (
    diagnose_model as diagnose_model,
    score_candidates as score_candidates,
)
from ._fit import fit_model as fit_model, ModelFit as ModelFit
from ._metrics import channel_metrics as channel_metrics
from ._model import (
    make_model as make_model,
    ModelSpec as ModelSpec,
    OUTPUTS as OUTPUTS,
)
from ._run import (
    run_compare as run_compare,
    run_diagnose as run_diagnose,
    run_fit as run_fit,
)
from ._workflow import (
    default_candidates as default_candidates,
    derivative_table as derivative_table,
    diagnose as diagnose,
    fit as fit,
    fit_metrics as fit_metrics,
    localise as localise,
    Settings as Settings,
)
