"""Lateral-directional motion: the linear lateral model of the HFB-320 and ATTAS
records, the six-degree-of-freedom lateral model, their channel names and derivatives.
"""

from ._lazy import attach


# loaded on first use (see `_lazy`); a module key "._x" is the package's `_x`
__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "._vehicle._lateral": (
            "LATERAL_COLUMNS",
            "LATERAL_DERIVATIVES",
            "LATERAL_INPUTS",
            "lateral_model",
            "LATERAL_OUTPUTS",
            "lateral_record",
            "LATERAL_START",
            "read_lateral_asc",
        ),
        "._vehicle._lateral_sixdof": (
            "implied_lateral_derivatives",
            "SIXDOF_LATERAL_EFFECTS",
            "SIXDOF_LATERAL_INPUTS",
            "sixdof_lateral_model",
            "SIXDOF_LATERAL_OUTPUTS",
            "SIXDOF_LATERAL_STATES",
        ),
        "._vehicle._sixdof": (
            "lateral_coefficients",
            "LATERAL_DERIVATIVE_NAMES",
            "LateralDerivatives",
        ),
    },
)
