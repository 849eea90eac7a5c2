"""Diagnosis: which held term or physical effect explains a misfit. The score test
of candidates for any model, and the Pegasus discrepancy workflow (compare, localise,
diagnose, add, refit)."""

from .._lazy import attach


# loaded on first use (see `_lazy`)
__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "_candidates": (
            "diagnose_model",
            "score_candidates",
        ),
        "_fit": (
            "fit_model",
            "ModelFit",
        ),
        "_metrics": ("channel_metrics",),
        "_model": (
            "make_model",
            "ModelSpec",
            "OUTPUTS",
        ),
        "_run": (
            "run_compare",
            "run_diagnose",
            "run_fit",
        ),
        "_workflow": (
            "default_candidates",
            "derivative_table",
            "diagnose",
            "fit",
            "fit_metrics",
            "localise",
            "Settings",
        ),
    },
)
