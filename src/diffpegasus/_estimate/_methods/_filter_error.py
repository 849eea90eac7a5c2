"""`FilterError`: maximum likelihood on the innovations of a Kalman filter (one
steady-state gain, or a gain scheduled along the trajectory), for records flown
through turbulence (process noise)."""

import equinox as eqx

from .._estimator import AbstractEstimator
from .._filter_error import filter_error, FilterErrorFit
from .._filter_gain import AbstractFilterGain, SteadyStateGain
from .._gust import Gust
from ._output_error import OutputError


class FilterError(AbstractEstimator):
    """The filter-error method: det(R) of the innovations minimised over the
    parameters and the process-noise intensities.

    **Fields:**

    - `process_noise`: the states whose equations get process noise (default: every
      state).
    - `intensities`: start intensities per state in `process_noise` (state units /
      sqrt(s)); default `None`: scaled to the residuals of an output-error fit
      made first (whose estimates are also the parameters' start), so a record the
      model already fits starts with little process noise and a turbulent one with
      more.
    - `full_R`: estimate the full innovation covariance (default its diagonal).
    - `rtol`: converged when det(R) changes by less than this, relatively.
    - `gain`: [`SteadyStateGain`][]`()` (default: one gain linearised at the
      record's initial state, for flights about one trim point) or
      [`ScheduledGain`][]`(points=16)` (the gain solved along the predicted
      trajectory and interpolated: for a vehicle whose flight condition changes
      through the record).
    - `start`: the [`OutputError`][] fit that gives the start (default single
      shooting from the held initial state; multiple shooting for long records
      of a vehicle a simulation from one state cannot follow, with
      `estimate_initial_state=True` its initial states start the filter).
    - `gust`: a [`Gust`][] (default `None`: white process noise only): coloured
      turbulence, first-order gust states on the airflow states it names with
      their correlation time estimated, besides the white noise.

    Returns a [`FilterErrorFit`][].
    """

    process_noise: tuple[str, ...] | None = eqx.field(static=True, default=None)
    intensities: tuple[float, ...] | None = eqx.field(static=True, default=None)
    full_R: bool = eqx.field(static=True, default=False)
    rtol: float = eqx.field(static=True, default=1e-6)
    gain: AbstractFilterGain = SteadyStateGain()
    start: OutputError = OutputError()
    gust: Gust | None = None

    def __check_init__(self):
        if self.intensities is not None and (
            self.process_noise is None
            or len(self.intensities) != len(self.process_noise)
        ):
            raise ValueError(
                "intensities needs process_noise naming one state per intensity"
            )
        if not self.rtol > 0:
            raise ValueError(f"rtol must be positive, got {self.rtol}")

    def estimate(self, model, records, *, max_iter, throw, progress) -> FilterErrorFit:
        names = tuple(
            model.states if self.process_noise is None else self.process_noise
        )
        noise = (
            names
            if self.intensities is None
            else dict(zip(names, self.intensities, strict=True))
        )
        return filter_error(
            model,
            records,
            process_noise=noise,
            full_R=self.full_R,
            rtol=self.rtol,
            max_iter=max_iter,
            throw=throw,
            progress=progress,
            gain=self.gain,
            start_fit={
                "shooting": self.start.shooting,
                "initial_state": "estimated"
                if self.start.estimate_initial_state
                else "fixed",
            },
            gust=self.gust,
        )
