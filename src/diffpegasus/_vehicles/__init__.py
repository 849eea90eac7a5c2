from ._hfb320 import hfb320_model as hfb320_model
from ._lateral import (
    LATERAL_COLUMNS as LATERAL_COLUMNS,
    LATERAL_DERIVATIVES as LATERAL_DERIVATIVES,
    LATERAL_INPUTS as LATERAL_INPUTS,
    LATERAL_OUTPUTS as LATERAL_OUTPUTS,
    LATERAL_START as LATERAL_START,
    lateral_model as lateral_model,
    lateral_record as lateral_record,
    read_lateral_asc as read_lateral_asc,
    sixdof_lateral_model as sixdof_lateral_model,
    SIXDOF_LATERAL_INPUTS as SIXDOF_LATERAL_INPUTS,
    SIXDOF_LATERAL_OUTPUTS as SIXDOF_LATERAL_OUTPUTS,
    SIXDOF_LATERAL_STATES as SIXDOF_LATERAL_STATES,
)
from ._registry import vehicle_spec as vehicle_spec, VEHICLES as VEHICLES
