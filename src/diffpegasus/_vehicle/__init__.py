"""Vehicles: the parts of a flight vehicle, the one flight model, the HFB-320 and
Pegasus vehicles, lateral and six-degree-of-freedom models."""

from .._lazy import attach


# loaded on first use (see `_lazy`)
__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "_hfb320": ("hfb320_model",),
        "_lateral": (
            "LATERAL_COLUMNS",
            "LATERAL_DERIVATIVES",
            "LATERAL_INPUTS",
            "lateral_model",
            "LATERAL_OUTPUTS",
            "lateral_record",
            "LATERAL_START",
        ),
        "_lateral_sixdof": (
            "implied_lateral_derivatives",
            "SIXDOF_LATERAL_EFFECTS",
            "SIXDOF_LATERAL_INPUTS",
            "sixdof_lateral_model",
            "SIXDOF_LATERAL_OUTPUTS",
            "SIXDOF_LATERAL_STATES",
        ),
        "_parts": (
            "AbstractAerodynamics",
            "AbstractAtmosphere",
            "AbstractMassProperties",
            "AbstractPropulsion",
            "ConstantAtmosphere",
            "ConstantMass",
            "FlightVehicle",
            "Geometry",
            "LoggedMass",
            "LoggedThrust",
            "StandardAtmosphere",
            "vehicle_model",
        ),
        "_mach_spline": ("MachSplineAerodynamics",),
    },
)
