"""diffpegasus: differentiable launch-vehicle simulation and system identification.

The package follows the work: `_vehicle` (parts, the one flight model, effects, the
Pegasus and HFB-320 vehicles) -> `_simulate` (inputs, solves, sensors, input design)
-> `_log` (the log format, other layouts, plausibility checks) -> `_estimate` (the one
output-error engine, filter error, least squares, neural model) -> `_diagnose` (which
missing term explains a misfit) -> `_report` (figures and tables); `_campaign` runs
Monte Carlo campaigns and `_cli` is the command line.

The public names below are loaded when first used (PEP 562), so a command imports
only the modules it runs: `import diffpegasus` costs JAX's import and little more.
"""

import jax as _jax

from ._lazy import attach as _attach


_jax.config.update("jax_enable_x64", True)

__version__ = "0.1.0"

# loaded on first use: the module (relative to the package) of each public name
__getattr__, __dir__, __all__ = _attach(
    __name__,
    {
        "_campaign._sharding": (
            "map_over_devices",
            "shard_batch",
        ),
        "_diagnose": (
            "diagnose_model",
            "score_candidates",
        ),
        "_estimate": (
            "CoefficientNetwork",
            "equation_error",
            "EquationErrorFit",
            "estimate_lse",
            "estimate_nn",
            "estimate_oem",
            "Estimates",
            "FilterErrorFit",
            "Fit",
            "fit",
            "fit_filter_error",
            "fit_global_oem",
            "fit_windowed_oem",
            "format_parameter_table",
            "GlobalFit",
            "load_model_file",
            "load_network",
            "lse_arrays",
            "lse_batch",
            "MeasuredCoefficients",
            "ModelSpec",
            "MultipleShooting",
            "node_times",
            "oem_setup",
            "OEMProblem",
            "OEMSetup",
            "parameter_table",
            "reconstruct_coefficients",
            "RESULTS",
            "save_network",
            "score_test",
            "ScoreTest",
            "simulate_model",
            "SingleShooting",
            "to_body",
            "to_lift_drag",
            "train_network",
            "window_truth",
            "windowed_least_squares",
            "windowed_lift_drag",
            "WindowedFit",
            "WindowLayout",
        ),
        "_estimate._training": (
            "train_levenberg_marquardt",
            "TrainingHistory",
        ),
        "_log._asc": ("read_asc",),
        "_log._columns": (
            "load_columns",
            "load_record",
        ),
        "_log._format": (
            "FlightLog",
            "read_log",
            "validate_channels",
            "write_log",
        ),
        "_inputs": (
            "AbstractInput",
            "doublet",
            "excitation",
            "Multisine",
            "NoInput",
            "PulseTrain",
            "Ramp",
            "Schedule",
            "schroeder_multisine",
            "Sequence",
            "Sine",
            "Step",
            "Sum",
            "three_two_one_one",
        ),
        "_simulate._sensors": ("SensorModel",),
        "_simulate._solve": (
            "elevator_command",
            "Flight",
            "flight_to_log",
            "InitialCondition",
            "nominal_elevator",
            "PegasusConfig",
            "Perturbation",
            "sample_perturbations",
            "simulate",
            "simulate_batch",
        ),
        "_vehicle": (
            "AbstractAerodynamics",
            "AbstractAtmosphere",
            "AbstractMassProperties",
            "AbstractPropulsion",
            "ConstantAtmosphere",
            "ConstantMass",
            "FlightVehicle",
            "Geometry",
            "hfb320_model",
            "implied_lateral_derivatives",
            "LATERAL_COLUMNS",
            "LATERAL_DERIVATIVES",
            "LATERAL_INPUTS",
            "lateral_model",
            "LATERAL_OUTPUTS",
            "lateral_record",
            "LATERAL_START",
            "LoggedThrust",
            "read_lateral_asc",
            "SIXDOF_LATERAL_EFFECTS",
            "SIXDOF_LATERAL_INPUTS",
            "sixdof_lateral_model",
            "SIXDOF_LATERAL_OUTPUTS",
            "SIXDOF_LATERAL_STATES",
            "StandardAtmosphere",
            "vehicle_model",
            "vehicle_spec",
        ),
        "_vehicle._atmosphere": (
            "Atmosphere",
            "isa",
        ),
        "_vehicle._effects": (
            "AbstractEffect",
            "effect_names",
            "EFFECTS",
            "FlightCondition",
            "make_effect",
            "parse_assignment",
        ),
        "_vehicle._flight": (
            "moment_about_cg",
            "pitch_plane",
            "pitch_plane_rates",
            "PitchPlane",
        ),
        "_vehicle._gravity": ("gravity",),
        "_vehicle._pegasus._aerodynamics": (
            "AeroCoefficients",
            "AeroDatabase",
            "AeroDerivatives",
            "body_axis",
            "coefficients",
            "DERIVATIVE_NAMES",
            "load_database",
            "wind_axis",
        ),
        "_vehicle._pegasus._dynamics": (
            "evaluate",
            "FlightModel",
        ),
        "_vehicle._pegasus._lateral": (
            "fin_lift_slope",
            "pegasus_aircraft",
            "pegasus_lateral",
            "pegasus_speed",
        ),
        "_vehicle._pegasus._mass": (
            "MassModel",
            "MassProperties",
        ),
        "_vehicle._pegasus._parts": ("pegasus_vehicle",),
        "_vehicle._pegasus._propulsion": ("SolidMotor",),
        "_vehicle._pegasus._vehicle": ("Vehicle",),
        "_vehicle._sixdof": (
            "Aircraft",
            "body_to_earth",
            "business_jet",
            "Controls",
            "euler_rates",
            "inertia_tensor",
            "lateral_coefficients",
            "LATERAL_DERIVATIVE_NAMES",
            "LateralDerivatives",
            "linearise",
            "rigid_body_rates",
            "simulate_sixdof",
            "sixdof_evaluate",
            "sixdof_rates",
            "Trim",
            "trim",
        ),
        "_rk4": ("RK4",),
        "_model": (
            "Model",
            "Record",
        ),
        "_errors": ("LogError",),
    },
)
