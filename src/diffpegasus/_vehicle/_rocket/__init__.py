"""A rocket from its parts: motor, masses, drag knots, rail, atmosphere, sensors."""

from ._config import read_rocket as read_rocket, Rocket as Rocket
from ._drag import DragKnots as DragKnots, read_drag_curve as read_drag_curve
from ._model import (
    EFFECTS as EFFECTS,
    Flight as Flight,
    OUTPUTS as OUTPUTS,
    rocket_model as rocket_model,
)
from ._motor import Motor as Motor, read_motor as read_motor
from ._sensors import (
    axial_specific_force as axial_specific_force,
    baro_altitude as baro_altitude,
    baro_scale as baro_scale,
    layered_air as layered_air,
    pressure_altitude as pressure_altitude,
)
