"""How the filter-error method's Kalman gain follows the record: one steady-state
gain, or a gain scheduled along the trajectory.

The filter-error method needs a gain for its innovations. Around a trim point one
steady-state gain serves the whole record ([`SteadyStateGain`][], FVSysID's
choice). A vehicle whose flight condition changes through the record (a launch
vehicle from drop to burnout: Mach 0.8 to 8, dynamic pressure up fifty-fold) needs
a gain that follows it: [`ScheduledGain`][] solves the steady-state Riccati
equation at a few points of the filter's predicted trajectory and interpolates the
gains linearly in time between them.

Why a schedule, not an extended Kalman filter (covariance propagated and gain
computed per sample inside the scan): measured on a turbulent Pegasus flight
(see the filter-error guide), the schedule's forward-mode Jacobian costs about
what the steady filter's does, because the Riccati solutions sit outside the
scan (a few per record, each with one implicit linear solve per tangent), while
the EKF differentiates a covariance update and a linearisation per sample for
every tangent; and the EKF's innovation covariance changes per sample, so the
filter-error method's closed-form relaxation of `R` no longer applies.
"""

import abc

import equinox as eqx
import numpy as np


class AbstractFilterGain(eqx.Module):
    """Where the filter-error method linearises the model for its gain."""

    @abc.abstractmethod
    def schedule(self, n: int) -> np.ndarray:
        """Sample indices `(points,)` of a record of `n` samples at which the gain
        is solved (the first is 0); the same number of points for every `n`."""


class SteadyStateGain(AbstractFilterGain):
    """One steady-state gain per record, from the model linearised at the record's
    initial state and first input (the classical filter-error method).

    `points` > 1 solves that one gain `points` times (all at the first sample):
    the same gain, but the compiled program is the one a
    [`ScheduledGain`][]`(points)` uses, so fits of one record with either gain
    share one compiled filter-error program (the fit's `gain` keeps one point).
    The diagnosis's own choice of gain uses the one-point gain: along a binding
    gain constraint the two programs' rounding led the HFB-320 record's fit to
    optima 0.9% apart in one parameter."""

    points: int = eqx.field(static=True, default=1)

    def __check_init__(self):
        if not self.points >= 1:
            raise ValueError(
                f"SteadyStateGain needs at least 1 point, got {self.points}"
            )

    def schedule(self, n: int) -> np.ndarray:
        del n
        return np.zeros(self.points, int)


class ScheduledGain(AbstractFilterGain):
    """A gain scheduled along the trajectory: the steady-state Riccati equation
    solved at `points` samples spread evenly over the record (the first and the
    last included), with the model linearised at the filter's predicted state
    there, and the gains interpolated linearly in time between them.

    The linearisation states are those the filter predicted at the previous
    iteration (at the start, the measured states where outputs measure them,
    else the start model's simulation): like the innovation covariance, they are
    relaxed between Gauss-Newton steps and held during each.
    """

    points: int = eqx.field(static=True, default=16)

    def __check_init__(self):
        if not self.points >= 2:
            raise ValueError(
                f"ScheduledGain needs at least 2 points, got {self.points}"
            )

    def schedule(self, n: int) -> np.ndarray:
        return np.round(np.linspace(0, max(n - 1, 0), self.points)).astype(int)
