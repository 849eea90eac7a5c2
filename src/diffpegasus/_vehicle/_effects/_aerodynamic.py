"""Aerodynamic effects missing from the linear-in-alpha database model."""

from ..._custom_types import ScalarLike
from ._base import AbstractEffect


class PitchDamping(AbstractEffect):
    """Pitch damping: CM += Cmq q c / (2 V)."""

    Cmq: ScalarLike = 0.0
    name = "pitch_damping"
    description = "pitching moment proportional to pitch rate, Cmq q c / 2V"
    parameter = "Cmq"

    def moment_coefficient(self, c):
        return self.Cmq * c.q * c.c_ref / (2 * c.airspeed)


class AlphaDotDamping(AbstractEffect):
    """Alpha-dot damping: CM += Cmad alpha_dot c / (2 V) (downwash lag)."""

    Cmad: ScalarLike = 0.0
    name = "alpha_dot_damping"
    description = "pitching moment from downwash lag, Cm_alphadot alphadot c / 2V"
    parameter = "Cmad"

    def moment_coefficient(self, c):
        return self.Cmad * c.alpha_dot * c.c_ref / (2 * c.airspeed)


class LiftOffset(AbstractEffect):
    """Zero-alpha lift: CL += CL0."""

    CL0: ScalarLike = 0.0
    name = "lift_offset"
    description = "lift at zero alpha and elevator (camber, incidence), CL0"
    parameter = "CL0"

    def force_coefficients(self, c):
        return self.CL0 + 0.0 * c.alpha, 0.0 * c.alpha


class DragOffset(AbstractEffect):
    """Zero-lift drag: CD += CD0."""

    CD0: ScalarLike = 0.0
    name = "drag_offset"
    description = "zero-lift (skin-friction, base and wave) drag, CD0"
    parameter = "CD0"

    def force_coefficients(self, c):
        return 0.0 * c.alpha, self.CD0 + 0.0 * c.alpha


class MomentOffset(AbstractEffect):
    """Zero-alpha pitching moment: CM += CM0."""

    CM0: ScalarLike = 0.0
    name = "moment_offset"
    description = "pitching moment at zero alpha and elevator, CM0"
    parameter = "CM0"

    def moment_coefficient(self, c):
        return self.CM0 + 0.0 * c.alpha


class LiftAlphaSquared(AbstractEffect):
    """Non-linear lift: CL += CLa2 alpha^2."""

    CLa2: ScalarLike = 0.0
    name = "lift_alpha_squared"
    description = "lift non-linear in alpha (vortex, cross-flow), CLa2 alpha^2"
    parameter = "CLa2"

    def force_coefficients(self, c):
        return self.CLa2 * c.alpha**2, 0.0 * c.alpha


class DragAlphaSquared(AbstractEffect):
    """Induced drag: CD += CDa2 alpha^2."""

    CDa2: ScalarLike = 0.0
    name = "drag_alpha_squared"
    description = "drag quadratic in alpha (induced drag), CDa2 alpha^2"
    parameter = "CDa2"

    def force_coefficients(self, c):
        return 0.0 * c.alpha, self.CDa2 * c.alpha**2


class MomentAlphaSquared(AbstractEffect):
    """Non-linear pitching moment: CM += CMa2 alpha^2."""

    CMa2: ScalarLike = 0.0
    name = "moment_alpha_squared"
    description = "pitching moment non-linear in alpha, CMa2 alpha^2"
    parameter = "CMa2"

    def moment_coefficient(self, c):
        return self.CMa2 * c.alpha**2
