"""The library of physical effects, by canonical name."""

from ._aerodynamic import (
    AlphaDotDamping as AlphaDotDamping,
    DragAlphaSquared as DragAlphaSquared,
    DragOffset as DragOffset,
    LiftAlphaSquared as LiftAlphaSquared,
    LiftOffset as LiftOffset,
    MomentAlphaSquared as MomentAlphaSquared,
    MomentOffset as MomentOffset,
    PitchDamping as PitchDamping,
)
from ._base import AbstractEffect as AbstractEffect, FlightCondition as FlightCondition
from ._other import (
    AccelerometerOffset as AccelerometerOffset,
    ActuatorDelay as ActuatorDelay,
    SensorBias as SensorBias,
    ThrustMisalignment as ThrustMisalignment,
    VerticalWind as VerticalWind,
)
from ._registry import (
    effect_names as effect_names,
    EFFECTS as EFFECTS,
    make_effect as make_effect,
    parse_assignment as parse_assignment,
    RANDOM_EFFECTS as RANDOM_EFFECTS,
)
from ._turbulence import Turbulence as Turbulence
