"""The Pegasus first stage: the reference vehicle of the thesis this package began
with. Its simulator and aerodynamic database, its lateral fin model, and the thesis's
window-by-window estimators (least squares, neural model plus least squares, output
error) with their results.

The generic vocabulary (models, records, the estimation entry, vehicles from parts,
the diagnosis) is at the top level, `diffpegasus`; this namespace holds what only the
Pegasus vehicle and the thesis reproduction use.
"""

from ._lazy import attach


# loaded on first use (see `_lazy`); a module key "._x" is the package's `_x`
__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "._estimate": (
            "CoefficientNetwork",
            "estimate_lse",
            "estimate_nn",
            "estimate_oem",
            "Estimates",
            "fit_global_oem",
            "fit_windowed_oem",
            "GlobalFit",
            "load_network",
            "lse_arrays",
            "lse_batch",
            "MeasuredCoefficients",
            "node_times",
            "oem_setup",
            "OEMProblem",
            "OEMSetup",
            "reconstruct_coefficients",
            "save_network",
            "score_test",
            "ScoreTest",
            "to_body",
            "to_lift_drag",
            "train_network",
            "window_truth",
            "windowed_least_squares",
            "windowed_lift_drag",
            "WindowedFit",
            "WindowLayout",
        ),
        "._estimate._training": (
            "train_levenberg_marquardt",
            "TrainingHistory",
        ),
        "._simulate._sensors": ("SensorModel",),
        "._simulate._solve": (
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
        "._vehicle._pegasus._aerodynamics": (
            "AeroCoefficients",
            "AeroDatabase",
            "AeroDerivatives",
            "body_axis",
            "coefficients",
            "DERIVATIVE_NAMES",
            "load_database",
            "wind_axis",
        ),
        "._vehicle._pegasus._dynamics": (
            "evaluate",
            "FlightModel",
        ),
        "._vehicle._pegasus._lateral": (
            "fin_lift_slope",
            "pegasus_aircraft",
            "pegasus_lateral",
            "pegasus_speed",
        ),
        "._vehicle._pegasus._mass": (
            "MassModel",
            "MassProperties",
        ),
        "._vehicle._pegasus._parts": ("pegasus_vehicle",),
        "._vehicle._pegasus._propulsion": ("SolidMotor",),
        "._vehicle._pegasus._vehicle": ("Vehicle",),
    },
)
