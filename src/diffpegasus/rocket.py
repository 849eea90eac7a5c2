"""Rocket flights: a rocket from its parts, identified from its flight computer's log.

import diffpegasus.rocket as dr

rocket = dr.read_rocket("rocket.toml")
problem = dr.prepare(rocket, log)          # log: a rocket log (channels, events)
result = dr.fit_rocket(problem)            # CD(Mach) knots, thrust scale, baro
cd, stderr = result.cd([0.3, 0.6, 0.9])    # band: noise and sensors' disagreement
# dr.fit_rocket(problem, spread=False): the noise's band alone
named, tests, _ = dr.diagnose(problem)     # missing effects
"""

from ._rocket._apogee import (
    apogee_band as apogee_band,
    apogee_function as apogee_function,
    ApogeeBand as ApogeeBand,
)
from ._rocket._checks import (
    equation_error_drag as equation_error_drag,
    resimulate as resimulate,
)
from ._rocket._diagnose import Candidate as Candidate, diagnose as diagnose
from ._rocket._identify import (
    default_free as default_free,
    fit_rocket as fit_rocket,
    prepare as prepare,
    Problem as Problem,
    RocketFit as RocketFit,
    simulate_flight as simulate_flight,
)
from ._rocket._pipeline import predict as predict, run_flight as run_flight
from ._rocket._spread import (
    between_variance as between_variance,
    determined as determined,
    sensor_estimates as sensor_estimates,
    SensorFits as SensorFits,
    Spread as Spread,
    structural_spread as structural_spread,
)
from ._vehicle._rocket import (
    axial_specific_force as axial_specific_force,
    baro_altitude as baro_altitude,
    baro_scale as baro_scale,
    DragKnots as DragKnots,
    EFFECTS as EFFECTS,
    Flight as Flight,
    layered_air as layered_air,
    Motor as Motor,
    pressure_altitude as pressure_altitude,
    read_drag_curve as read_drag_curve,
    read_motor as read_motor,
    read_rocket as read_rocket,
    Rocket as Rocket,
    rocket_model as rocket_model,
)


# the atmosphere's earlier name (one lapse rate; the layers came later, optional):
# kept for one release
linear_lapse_air = layered_air
