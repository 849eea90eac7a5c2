from ._hfb320 import hfb320_model as hfb320_model
from ._lateral import (
    LATERAL_COLUMNS as LATERAL_COLUMNS,
    LATERAL_DERIVATIVES as LATERAL_DERIVATIVES,
    LATERAL_INPUTS as LATERAL_INPUTS,
    lateral_model as lateral_model,
    LATERAL_OUTPUTS as LATERAL_OUTPUTS,
    lateral_record as lateral_record,
    LATERAL_START as LATERAL_START,
    read_lateral_asc as read_lateral_asc,
)
from ._lateral_sixdof import (
    implied_lateral_derivatives as implied_lateral_derivatives,
    SIXDOF_LATERAL_EFFECTS as SIXDOF_LATERAL_EFFECTS,
    SIXDOF_LATERAL_INPUTS as SIXDOF_LATERAL_INPUTS,
    sixdof_lateral_model as sixdof_lateral_model,
    SIXDOF_LATERAL_OUTPUTS as SIXDOF_LATERAL_OUTPUTS,
    SIXDOF_LATERAL_STATES as SIXDOF_LATERAL_STATES,
)
from ._parts import (
    AbstractAerodynamics as AbstractAerodynamics,
    AbstractAtmosphere as AbstractAtmosphere,
    AbstractMassProperties as AbstractMassProperties,
    AbstractPropulsion as AbstractPropulsion,
    ConstantAtmosphere as ConstantAtmosphere,
    ConstantMass as ConstantMass,
    FlightVehicle as FlightVehicle,
    Geometry as Geometry,
    LoggedThrust as LoggedThrust,
    StandardAtmosphere as StandardAtmosphere,
    vehicle_model as vehicle_model,
)
from ._registry import vehicle_spec as vehicle_spec, VEHICLES as VEHICLES
