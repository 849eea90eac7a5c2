"""The public surface, for type checkers and for the lazy loader (`_lazy.attach_stub`)."""

from . import (
    design as design,
    discrepancy as discrepancy,
    lateral as lateral,
    montecarlo as montecarlo,
    pegasus as pegasus,
    sixdof as sixdof,
)
from ._campaign._sharding import (
    map_over_devices as map_over_devices,
    shard_batch as shard_batch,
)
from ._diagnose._candidates import (
    diagnose_model as diagnose_model,
    score_candidates as score_candidates,
)
from ._errors import (
    LogError as LogError,
)
from ._estimate._engine import (
    RESULTS as RESULTS,
)
from ._estimate._entry import estimate as estimate
from ._estimate._equation_error import (
    equation_error as equation_error,
    EquationErrorFit as EquationErrorFit,
)
from ._estimate._estimator import (
    AbstractEstimator as AbstractEstimator,
    AbstractFit as AbstractFit,
)
from ._estimate._filter_error import (
    FilterErrorFit as FilterErrorFit,
    fit_filter_error as fit_filter_error,
)
from ._estimate._filter_gain import (
    ScheduledGain as ScheduledGain,
    SteadyStateGain as SteadyStateGain,
)
from ._estimate._fit import (
    Fit as Fit,
    fit as fit,
    MultipleShooting as MultipleShooting,
    simulate_model as simulate_model,
    SingleShooting as SingleShooting,
)
from ._estimate._fourier import (
    finite_fourier as finite_fourier,
)
from ._estimate._frequency import (
    FrequencyFit as FrequencyFit,
)
from ._estimate._gust import (
    Gust as Gust,
)
from ._estimate._methods import (
    EquationError as EquationError,
    FilterError as FilterError,
    FrequencyEquationError as FrequencyEquationError,
    FrequencyOutputError as FrequencyOutputError,
    OutputError as OutputError,
)
from ._estimate._modelfile import (
    load_model_file as load_model_file,
    ModelSpec as ModelSpec,
)
from ._estimate._oem import (
    format_parameter_table as format_parameter_table,
    parameter_table as parameter_table,
)
from ._estimate._recursive import (
    model_regression as model_regression,
    RecursiveFourier as RecursiveFourier,
    RecursiveLeastSquares as RecursiveLeastSquares,
    replay as replay,
)
from ._estimate._solver import (
    BlockLevenbergMarquardt as BlockLevenbergMarquardt,
    output_error_residuals as output_error_residuals,
    OutputErrorProblem as OutputErrorProblem,
)
from ._inputs import (
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
from ._log._asc import (
    read_asc as read_asc,
)
from ._log._columns import (
    load_columns as load_columns,
    load_record as load_record,
)
from ._log._format import (
    FlightLog as FlightLog,
    read_log as read_log,
    validate_channels as validate_channels,
    write_log as write_log,
)
from ._log._rocketlogs import (
    read_rocket_log as read_rocket_log,
    RocketLog as RocketLog,
)
from ._model import (
    Model as Model,
    Record as Record,
)
from ._registry import (
    AbstractModelEntry as AbstractModelEntry,
    AbstractVehicleEntry as AbstractVehicleEntry,
    vehicle_entry as vehicle_entry,
    vehicle_spec as vehicle_spec,
)
from ._report._bode import (
    plot_bode as plot_bode,
)
from ._rk4 import (
    RK4 as RK4,
)
from ._vehicle._atmosphere import (
    Atmosphere as Atmosphere,
    isa as isa,
)
from ._vehicle._effects import (
    AbstractEffect as AbstractEffect,
    effect_names as effect_names,
    EFFECTS as EFFECTS,
    FlightCondition as FlightCondition,
    make_effect as make_effect,
    parse_assignment as parse_assignment,
)
from ._vehicle._flight import (
    moment_about_cg as moment_about_cg,
    pitch_plane as pitch_plane,
    pitch_plane_rates as pitch_plane_rates,
    PitchPlane as PitchPlane,
)
from ._vehicle._gravity import (
    gravity as gravity,
)
from ._vehicle._hfb320 import (
    hfb320_model as hfb320_model,
)
from ._vehicle._mach_spline import MachSplineAerodynamics as MachSplineAerodynamics
from ._vehicle._parts import (
    AbstractAerodynamics as AbstractAerodynamics,
    AbstractAtmosphere as AbstractAtmosphere,
    AbstractMassProperties as AbstractMassProperties,
    AbstractPropulsion as AbstractPropulsion,
    ConstantAtmosphere as ConstantAtmosphere,
    ConstantMass as ConstantMass,
    FlightVehicle as FlightVehicle,
    Geometry as Geometry,
    LoggedMass as LoggedMass,
    LoggedThrust as LoggedThrust,
    StandardAtmosphere as StandardAtmosphere,
    vehicle_model as vehicle_model,
)
