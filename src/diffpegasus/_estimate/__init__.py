"""Estimation: the one output-error engine and its layouts, the filter-error method,
equation-error least squares and the neural model, with their results."""

from .._lazy import attach


# loaded on first use (see `_lazy`)
__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "_coefficients": (
            "aerodynamic_loads",
            "MeasuredCoefficients",
            "reconstruct_coefficients",
        ),
        "_engine": (
            "Layout",
            "RESULTS",
            "Solution",
        ),
        "_equation_error": (
            "equation_error",
            "EquationErrorFit",
        ),
        "_entry": ("estimate",),
        "_estimator": (
            "AbstractEstimator",
            "AbstractFit",
        ),
        "_methods": (
            "EquationError",
            "ESTIMATORS",
            "FilterError",
            "FrequencyEquationError",
            "FrequencyOutputError",
            "OutputError",
        ),
        "_fourier": (
            "finite_fourier",
            "frequency_grid",
        ),
        "_frequency": (
            "default_band",
            "frequency_equation_error",
            "frequency_output_error",
            "FrequencyFit",
        ),
        "_solver": (
            "BlockLevenbergMarquardt",
            "output_error_residuals",
            "OutputErrorProblem",
        ),
        "_filter_error": (
            "FilterErrorFit",
            "fit_filter_error",
        ),
        "_filter_gain": (
            "ScheduledGain",
            "SteadyStateGain",
        ),
        "_gust": ("Gust", "with_gust"),
        "_fit": (
            "Fit",
            "fit",
            "MultipleShooting",
            "simulate_model=simulate",
            "SingleShooting",
        ),
        "_global_oem": (
            "fit_global_oem",
            "GlobalFit",
            "score_test",
            "ScoreTest",
        ),
        "_lse": (
            "estimate_lse",
            "lse_arrays",
            "lse_batch",
            "window_truth",
            "windowed_least_squares",
        ),
        "_modelfile": (
            "load_model_file",
            "ModelSpec",
        ),
        "_nn": (
            "CoefficientNetwork",
            "DEFAULT_INPUTS",
            "estimate_nn",
            "LOAD_INPUTS",
            "load_network",
            "MinMax",
            "NN_INPUTS",
            "save_network",
            "train_network",
        ),
        "_oem": (
            "format_parameter_table",
            "node_times",
            "OEMProblem",
            "parameter_table",
        ),
        "_pegasus_oem": (
            "estimate_oem",
            "oem_setup",
            "OEMSetup",
            "thesis_model",
            "thesis_record",
            "to_body",
            "to_lift_drag",
            "windowed_lift_drag",
        ),
        "_result": ("Estimates",),
        "_windowed_oem": (
            "fit_windowed",
            "fit_windowed_oem",
            "WindowedFit",
            "Windows",
        ),
        "_windows": ("WindowLayout",),
    },
)
