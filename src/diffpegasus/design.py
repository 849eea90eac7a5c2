"""Gradient-optimal input design through the differentiable output-error model (see the
thesis-reproduction tutorial in the documentation)."""

from ._design._optimal import (
    criterion as criterion,
    DesignProblem as DesignProblem,
    fisher_information as fisher_information,
    HAND_PICKED as HAND_PICKED,
    Limits as Limits,
    multisine_spec as multisine_spec,
    optimise_input as optimise_input,
    peaks as peaks,
    pegasus_design as pegasus_design,
    predicted_covariance as predicted_covariance,
    predicted_stderr as predicted_stderr,
    run_design as run_design,
    Scaled as Scaled,
    simulate_outputs as simulate_outputs,
    within_limits as within_limits,
)
