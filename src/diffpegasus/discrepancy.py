"""The model-discrepancy workflow (compare, localise, diagnose, add, refit) as a
library, on any vehicle's registry entry (`vehicle_entry("pegasus")`, a vehicle
file): see the guide "Vehicles"."""

from ._diagnose import (
    channel_metrics as channel_metrics,
    derivative_table as derivative_table,
    diagnose as diagnose,
    fit_log as fit_log,
    fit_metrics as fit_metrics,
    FlightFit as FlightFit,
    localise as localise,
)
from ._registry import vehicle_entry as vehicle_entry
from ._registry._pegasus import default_candidates as default_candidates
from ._report._runs import (
    run_compare as run_compare,
    run_diagnose as run_diagnose,
    run_fit as run_fit,
)
