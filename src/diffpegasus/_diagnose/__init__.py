"""Diagnosis: which held term or physical effect explains a misfit. The score test
of candidates for any model, and the discrepancy workflow (compare, localise,
diagnose, add, refit) on any vehicle's registry entry."""

from .._lazy import attach


# loaded on first use (see `_lazy`)
__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "_candidates": (
            "diagnose_model",
            "score_candidates",
        ),
        "_metrics": ("channel_metrics",),
        "_workflow": (
            "derivative_table",
            "diagnose",
            "fit_log",
            "fit_metrics",
            "FlightFit",
            "localise",
        ),
    },
)
