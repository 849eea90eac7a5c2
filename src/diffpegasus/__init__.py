"""diffpegasus: differentiable launch-vehicle simulation and system identification.

The package follows the work: `_vehicle` (parts, the one flight model, effects, the
Pegasus and HFB-320 vehicles) -> `_simulate` (inputs, solves, sensors, input design)
-> `_log` (the log format, other layouts, plausibility checks) -> `_estimate` (the one
output-error engine, filter error, least squares, neural model) -> `_diagnose` (which
missing term explains a misfit) -> `_report` (figures and tables); `_campaign` runs
Monte Carlo campaigns and `_cli` is the command line.

The top level is the generic vocabulary: models and records, logs, input signals,
estimation, vehicles from parts, effects, six degrees of freedom and the diagnosis.
One vehicle's names live in its own namespace (`diffpegasus.pegasus`), and so do the
lateral-directional models (`diffpegasus.lateral`), input design
(`diffpegasus.design`), the discrepancy workflow (`diffpegasus.discrepancy`) and the
Monte Carlo campaign (`diffpegasus.montecarlo`).

The public names below are loaded when first used (PEP 562), so a command imports
only the modules it runs: `import diffpegasus` costs JAX's import and little more.
"""

import jax as _jax

from ._lazy import attach_stub as _attach_stub


_jax.config.update("jax_enable_x64", True)

__version__ = "0.1.0"

# the public names are listed once, in `__init__.pyi` (which type checkers read), and
# load on first use; names moved to a namespace of their own resolve here for one
# release
__getattr__, __dir__, __all__ = _attach_stub(
    __name__,
    __file__,
    moved={
        "Aircraft": "sixdof.Aircraft",
        "body_to_earth": "sixdof.body_to_earth",
        "business_jet": "sixdof.business_jet",
        "Controls": "sixdof.Controls",
        "euler_rates": "sixdof.euler_rates",
        "inertia_tensor": "sixdof.inertia_tensor",
        "linearise": "sixdof.linearise",
        "rigid_body_rates": "sixdof.rigid_body_rates",
        "simulate_sixdof": "sixdof.simulate_sixdof",
        "sixdof_evaluate": "sixdof.sixdof_evaluate",
        "sixdof_rates": "sixdof.sixdof_rates",
        "Trim": "sixdof.Trim",
        "trim": "sixdof.trim",
        "AeroCoefficients": "pegasus.AeroCoefficients",
        "AeroDatabase": "pegasus.AeroDatabase",
        "AeroDerivatives": "pegasus.AeroDerivatives",
        "body_axis": "pegasus.body_axis",
        "CoefficientNetwork": "pegasus.CoefficientNetwork",
        "coefficients": "pegasus.coefficients",
        "DERIVATIVE_NAMES": "pegasus.DERIVATIVE_NAMES",
        "elevator_command": "pegasus.elevator_command",
        "estimate_lse": "pegasus.estimate_lse",
        "estimate_nn": "pegasus.estimate_nn",
        "estimate_oem": "pegasus.estimate_oem",
        "Estimates": "pegasus.Estimates",
        "evaluate": "pegasus.evaluate",
        "fin_lift_slope": "pegasus.fin_lift_slope",
        "fit_global_oem": "pegasus.fit_global_oem",
        "fit_windowed_oem": "pegasus.fit_windowed_oem",
        "Flight": "pegasus.Flight",
        "flight_to_log": "pegasus.flight_to_log",
        "FlightModel": "pegasus.FlightModel",
        "GlobalFit": "pegasus.GlobalFit",
        "InitialCondition": "pegasus.InitialCondition",
        "load_database": "pegasus.load_database",
        "load_network": "pegasus.load_network",
        "lse_arrays": "pegasus.lse_arrays",
        "lse_batch": "pegasus.lse_batch",
        "MassModel": "pegasus.MassModel",
        "MassProperties": "pegasus.MassProperties",
        "MeasuredCoefficients": "pegasus.MeasuredCoefficients",
        "node_times": "pegasus.node_times",
        "nominal_elevator": "pegasus.nominal_elevator",
        "oem_setup": "pegasus.oem_setup",
        "OEMProblem": "pegasus.OEMProblem",
        "OEMSetup": "pegasus.OEMSetup",
        "pegasus_aircraft": "pegasus.pegasus_aircraft",
        "pegasus_lateral": "pegasus.pegasus_lateral",
        "pegasus_speed": "pegasus.pegasus_speed",
        "pegasus_vehicle": "pegasus.pegasus_vehicle",
        "PegasusConfig": "pegasus.PegasusConfig",
        "Perturbation": "pegasus.Perturbation",
        "reconstruct_coefficients": "pegasus.reconstruct_coefficients",
        "sample_perturbations": "pegasus.sample_perturbations",
        "save_network": "pegasus.save_network",
        "score_test": "pegasus.score_test",
        "ScoreTest": "pegasus.ScoreTest",
        "SensorModel": "pegasus.SensorModel",
        "simulate": "pegasus.simulate",
        "simulate_batch": "pegasus.simulate_batch",
        "SolidMotor": "pegasus.SolidMotor",
        "to_body": "pegasus.to_body",
        "to_lift_drag": "pegasus.to_lift_drag",
        "train_levenberg_marquardt": "pegasus.train_levenberg_marquardt",
        "train_network": "pegasus.train_network",
        "TrainingHistory": "pegasus.TrainingHistory",
        "Vehicle": "pegasus.Vehicle",
        "wind_axis": "pegasus.wind_axis",
        "window_truth": "pegasus.window_truth",
        "windowed_least_squares": "pegasus.windowed_least_squares",
        "windowed_lift_drag": "pegasus.windowed_lift_drag",
        "WindowedFit": "pegasus.WindowedFit",
        "WindowLayout": "pegasus.WindowLayout",
        "implied_lateral_derivatives": "lateral.implied_lateral_derivatives",
        "lateral_coefficients": "lateral.lateral_coefficients",
        "LATERAL_COLUMNS": "lateral.LATERAL_COLUMNS",
        "LATERAL_DERIVATIVE_NAMES": "lateral.LATERAL_DERIVATIVE_NAMES",
        "LATERAL_DERIVATIVES": "lateral.LATERAL_DERIVATIVES",
        "LATERAL_INPUTS": "lateral.LATERAL_INPUTS",
        "lateral_model": "lateral.lateral_model",
        "LATERAL_OUTPUTS": "lateral.LATERAL_OUTPUTS",
        "lateral_record": "lateral.lateral_record",
        "LATERAL_START": "lateral.LATERAL_START",
        "LateralDerivatives": "lateral.LateralDerivatives",
        "read_lateral_asc": "lateral.read_lateral_asc",
        "SIXDOF_LATERAL_EFFECTS": "lateral.SIXDOF_LATERAL_EFFECTS",
        "SIXDOF_LATERAL_INPUTS": "lateral.SIXDOF_LATERAL_INPUTS",
        "sixdof_lateral_model": "lateral.sixdof_lateral_model",
        "SIXDOF_LATERAL_OUTPUTS": "lateral.SIXDOF_LATERAL_OUTPUTS",
        "SIXDOF_LATERAL_STATES": "lateral.SIXDOF_LATERAL_STATES",
    },
)
