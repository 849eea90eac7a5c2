"""The lateral namespace, for type checkers and for the lazy loader."""

from ._log._asc import read_lateral_asc as read_lateral_asc
from ._vehicle._lateral import (
    LATERAL_COLUMNS as LATERAL_COLUMNS,
    LATERAL_DERIVATIVES as LATERAL_DERIVATIVES,
    LATERAL_INPUTS as LATERAL_INPUTS,
    lateral_model as lateral_model,
    LATERAL_OUTPUTS as LATERAL_OUTPUTS,
    lateral_record as lateral_record,
    LATERAL_START as LATERAL_START,
)
from ._vehicle._lateral_sixdof import (
    implied_lateral_derivatives as implied_lateral_derivatives,
    SIXDOF_LATERAL_EFFECTS as SIXDOF_LATERAL_EFFECTS,
    SIXDOF_LATERAL_INPUTS as SIXDOF_LATERAL_INPUTS,
    sixdof_lateral_model as sixdof_lateral_model,
    SIXDOF_LATERAL_OUTPUTS as SIXDOF_LATERAL_OUTPUTS,
    SIXDOF_LATERAL_STATES as SIXDOF_LATERAL_STATES,
)
from ._vehicle._sixdof import (
    lateral_coefficients as lateral_coefficients,
    LATERAL_DERIVATIVE_NAMES as LATERAL_DERIVATIVE_NAMES,
    LateralDerivatives as LateralDerivatives,
)
