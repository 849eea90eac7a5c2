"""The Pegasus namespace, for type checkers and for the lazy loader."""

from ._estimate._coefficients import (
    MeasuredCoefficients as MeasuredCoefficients,
    reconstruct_coefficients as reconstruct_coefficients,
)
from ._estimate._global_oem import (
    fit_global_oem as fit_global_oem,
    GlobalFit as GlobalFit,
    score_test as score_test,
    ScoreTest as ScoreTest,
)
from ._estimate._lse import (
    estimate_lse as estimate_lse,
    lse_arrays as lse_arrays,
    lse_batch as lse_batch,
    window_truth as window_truth,
    windowed_least_squares as windowed_least_squares,
)
from ._estimate._nn import (
    CoefficientNetwork as CoefficientNetwork,
    DEFAULT_INPUTS as DEFAULT_INPUTS,
    estimate_nn as estimate_nn,
    LOAD_INPUTS as LOAD_INPUTS,
    load_network as load_network,
    NN_INPUTS as NN_INPUTS,
    save_network as save_network,
    train_network as train_network,
)
from ._estimate._oem import (
    node_times as node_times,
    OEMProblem as OEMProblem,
)
from ._estimate._pegasus_oem import (
    estimate_oem as estimate_oem,
    oem_setup as oem_setup,
    OEMSetup as OEMSetup,
    thesis_model as thesis_model,
    thesis_record as thesis_record,
    to_body as to_body,
    to_lift_drag as to_lift_drag,
    windowed_lift_drag as windowed_lift_drag,
)
from ._estimate._recursive import (
    coefficient_regression as coefficient_regression,
)
from ._estimate._result import (
    Estimates as Estimates,
)
from ._estimate._training import (
    train_levenberg_marquardt as train_levenberg_marquardt,
    TrainingHistory as TrainingHistory,
)
from ._estimate._windowed_oem import (
    fit_windowed as fit_windowed,
    fit_windowed_oem as fit_windowed_oem,
    WindowedFit as WindowedFit,
    Windows as Windows,
)
from ._estimate._windows import (
    WindowLayout as WindowLayout,
)
from ._simulate._sensors import (
    SensorModel as SensorModel,
)
from ._simulate._solve import (
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
from ._vehicle._pegasus._aerodynamics import (
    AeroCoefficients as AeroCoefficients,
    AeroDatabase as AeroDatabase,
    AeroDerivatives as AeroDerivatives,
    body_axis as body_axis,
    coefficients as coefficients,
    DERIVATIVE_NAMES as DERIVATIVE_NAMES,
    load_database as load_database,
    wind_axis as wind_axis,
)
from ._vehicle._pegasus._dynamics import (
    evaluate as evaluate,
    FlightModel as FlightModel,
)
from ._vehicle._pegasus._lateral import (
    fin_lift_slope as fin_lift_slope,
    pegasus_aircraft as pegasus_aircraft,
    pegasus_lateral as pegasus_lateral,
    pegasus_speed as pegasus_speed,
)
from ._vehicle._pegasus._mass import (
    MassModel as MassModel,
    MassProperties as MassProperties,
)
from ._vehicle._pegasus._parts import (
    pegasus_vehicle as pegasus_vehicle,
)
from ._vehicle._pegasus._propulsion import (
    SolidMotor as SolidMotor,
)
from ._vehicle._pegasus._vehicle import (
    Vehicle as Vehicle,
)
