"""diffpegasus: differentiable launch-vehicle simulation and system identification.

The package follows the work: `_vehicle` (parts, the one flight model, effects, the
Pegasus and HFB-320 vehicles) -> `_simulate` (inputs, solves, sensors, input design)
-> `_log` (the log format, other layouts, plausibility checks) -> `_estimate` (the one
output-error engine, filter error, least squares, neural model) -> `_diagnose` (which
missing term explains a misfit) -> `_report` (figures and tables); `_campaign` runs
Monte Carlo campaigns and `_cli` is the command line.
"""

import jax as _jax


_jax.config.update("jax_enable_x64", True)

from ._campaign._sharding import (  # noqa: E402
    map_over_devices as map_over_devices,
    shard_batch as shard_batch,
)
from ._diagnose import (  # noqa: E402
    diagnose_model as diagnose_model,
    score_candidates as score_candidates,
)
from ._estimate import (  # noqa: E402  # noqa: E402
    CoefficientNetwork as CoefficientNetwork,
    equation_error as equation_error,
    EquationErrorFit as EquationErrorFit,
    estimate_lse as estimate_lse,
    estimate_nn as estimate_nn,
    estimate_oem as estimate_oem,
    Estimates as Estimates,
    FilterErrorFit as FilterErrorFit,
    Fit as Fit,
    fit as fit,
    fit_filter_error as fit_filter_error,
    fit_global_oem as fit_global_oem,
    fit_windowed_oem as fit_windowed_oem,
    format_parameter_table as format_parameter_table,
    GlobalFit as GlobalFit,
    load_model_file as load_model_file,
    load_network as load_network,
    lse_arrays as lse_arrays,
    lse_batch as lse_batch,
    MeasuredCoefficients as MeasuredCoefficients,
    Model as Model,
    ModelSpec as ModelSpec,
    MultipleShooting as MultipleShooting,
    node_times as node_times,
    oem_setup as oem_setup,
    OEMProblem as OEMProblem,
    OEMSetup as OEMSetup,
    parameter_table as parameter_table,
    reconstruct_coefficients as reconstruct_coefficients,
    Record as Record,
    RESULTS as RESULTS,
    save_network as save_network,
    score_test as score_test,
    ScoreTest as ScoreTest,
    simulate_model as simulate_model,
    SingleShooting as SingleShooting,
    to_body as to_body,
    to_lift_drag as to_lift_drag,
    train_network as train_network,
    window_truth as window_truth,
    windowed_least_squares as windowed_least_squares,
    windowed_lift_drag as windowed_lift_drag,
    WindowedFit as WindowedFit,
    WindowLayout as WindowLayout,
)
from ._estimate._training import (  # noqa: E402
    train_levenberg_marquardt as train_levenberg_marquardt,
    TrainingHistory as TrainingHistory,
)
from ._log._asc import read_asc as read_asc  # noqa: E402
from ._log._columns import load_columns as load_columns, load_record as load_record  # noqa: E402
from ._log._format import (  # noqa: E402
    FlightLog as FlightLog,
    LogError as LogError,
    read_log as read_log,
    validate_channels as validate_channels,
    write_log as write_log,
)
from ._simulate._inputs import (  # noqa: E402
    AbstractInput as AbstractInput,
    doublet as doublet,
    excitation as excitation,
    Multisine as Multisine,
    NoInput as NoInput,
    PulseTrain as PulseTrain,
    Ramp as Ramp,
    Schedule as Schedule,
    schroeder_multisine as schroeder_multisine,
    Sequence as Sequence,
    Sine as Sine,
    Step as Step,
    Sum as Sum,
    three_two_one_one as three_two_one_one,
)
from ._simulate._sensors import SensorModel as SensorModel  # noqa: E402
from ._simulate._solve import (  # noqa: E402
    elevator_command as elevator_command,
    Flight as Flight,
    flight_to_log as flight_to_log,
    InitialCondition as InitialCondition,
    nominal_elevator as nominal_elevator,
    PegasusConfig as PegasusConfig,
    Perturbation as Perturbation,
    sample_perturbations as sample_perturbations,
    simulate as simulate,
    simulate_batch as simulate_batch,
)
from ._vehicle import (  # noqa: E402
    AbstractAerodynamics as AbstractAerodynamics,
    AbstractAtmosphere as AbstractAtmosphere,
    AbstractMassProperties as AbstractMassProperties,
    AbstractPropulsion as AbstractPropulsion,
    ConstantAtmosphere as ConstantAtmosphere,
    ConstantMass as ConstantMass,
    FlightVehicle as FlightVehicle,
    Geometry as Geometry,
    hfb320_model as hfb320_model,
    implied_lateral_derivatives as implied_lateral_derivatives,
    LATERAL_COLUMNS as LATERAL_COLUMNS,
    LATERAL_DERIVATIVES as LATERAL_DERIVATIVES,
    LATERAL_INPUTS as LATERAL_INPUTS,
    lateral_model as lateral_model,
    LATERAL_OUTPUTS as LATERAL_OUTPUTS,
    lateral_record as lateral_record,
    LATERAL_START as LATERAL_START,
    LoggedThrust as LoggedThrust,
    read_lateral_asc as read_lateral_asc,
    SIXDOF_LATERAL_EFFECTS as SIXDOF_LATERAL_EFFECTS,
    SIXDOF_LATERAL_INPUTS as SIXDOF_LATERAL_INPUTS,
    sixdof_lateral_model as sixdof_lateral_model,
    SIXDOF_LATERAL_OUTPUTS as SIXDOF_LATERAL_OUTPUTS,
    SIXDOF_LATERAL_STATES as SIXDOF_LATERAL_STATES,
    StandardAtmosphere as StandardAtmosphere,
    vehicle_model as vehicle_model,
    vehicle_spec as vehicle_spec,
)
from ._vehicle._atmosphere import Atmosphere as Atmosphere, isa as isa  # noqa: E402
from ._vehicle._effects import (  # noqa: E402
    AbstractEffect as AbstractEffect,
    effect_names as effect_names,
    EFFECTS as EFFECTS,
    FlightCondition as FlightCondition,
    make_effect as make_effect,
    parse_assignment as parse_assignment,
)
from ._vehicle._flight import (  # noqa: E402
    moment_about_cg as moment_about_cg,
    pitch_plane as pitch_plane,
    pitch_plane_rates as pitch_plane_rates,
    PitchPlane as PitchPlane,
)
from ._vehicle._gravity import gravity as gravity  # noqa: E402
from ._vehicle._pegasus._aerodynamics import (  # noqa: E402
    AeroCoefficients as AeroCoefficients,
    AeroDatabase as AeroDatabase,
    AeroDerivatives as AeroDerivatives,
    body_axis as body_axis,
    coefficients as coefficients,
    DERIVATIVE_NAMES as DERIVATIVE_NAMES,
    load_database as load_database,
    wind_axis as wind_axis,
)
from ._vehicle._pegasus._dynamics import (  # noqa: E402
    evaluate as evaluate,
    FlightModel as FlightModel,
)
from ._vehicle._pegasus._lateral import (  # noqa: E402
    fin_lift_slope as fin_lift_slope,
    pegasus_aircraft as pegasus_aircraft,
    pegasus_lateral as pegasus_lateral,
    pegasus_speed as pegasus_speed,
)
from ._vehicle._pegasus._mass import (  # noqa: E402
    MassModel as MassModel,
    MassProperties as MassProperties,
)
from ._vehicle._pegasus._parts import pegasus_vehicle as pegasus_vehicle  # noqa: E402
from ._vehicle._pegasus._propulsion import SolidMotor as SolidMotor  # noqa: E402
from ._vehicle._pegasus._vehicle import Vehicle as Vehicle  # noqa: E402
from ._vehicle._sixdof import (  # noqa: E402
    Aircraft as Aircraft,
    body_to_earth as body_to_earth,
    business_jet as business_jet,
    Controls as Controls,
    euler_rates as euler_rates,
    inertia_tensor as inertia_tensor,
    lateral_coefficients as lateral_coefficients,
    LATERAL_DERIVATIVE_NAMES as LATERAL_DERIVATIVE_NAMES,
    LateralDerivatives as LateralDerivatives,
    linearise as linearise,
    rigid_body_rates as rigid_body_rates,
    simulate_sixdof as simulate_sixdof,
    sixdof_evaluate as sixdof_evaluate,
    sixdof_rates as sixdof_rates,
    Trim as Trim,
    trim as trim,
)


__version__ = "0.1.0"


def __getattr__(name):
    # imported on first use (see _estimate/__init__.py): diffrax takes 0.4 s to import
    if name == "RK4":
        from ._estimate._rk4 import RK4

        return RK4
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
