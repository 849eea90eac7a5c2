"""`FrequencyOutputError` and `FrequencyEquationError`: the frequency-domain methods
for models linear in their states and inputs (see `_estimate/_frequency.py`)."""

import equinox as eqx

from .._estimator import AbstractEstimator
from .._frequency import frequency_equation_error, frequency_output_error, FrequencyFit


def _check_band(band):
    if band is None:
        return
    if len(band) != 2 or not float(band[1]) > float(band[0]) >= 0:
        raise ValueError(
            f"band must be (low, high) Hz with high > low >= 0, got {band}"
        )


class FrequencyOutputError(AbstractEstimator):
    """Output error in the frequency domain (Klein & Morelli ch. 7, SIDPAC `fdoe`):
    the model's output transforms fitted to the measured ones on the record's
    frequency grid in `band` (Hz; default from the inputs' spectrum), biases and trim
    left out by omitting 0 Hz. Starts from a frequency-domain equation-error fit
    when every state is measured and `start_from_equation_error`. Each record's
    end terms `x(T) - x(0)` are estimated (`end_terms="estimated"`, the default):
    held at the measured states' (`"measured"`), the two samples' noise enters
    every frequency's equation, and the estimates differ from the time-domain
    optimum by up to two of its standard errors on simulated lateral manoeuvres
    (0.1-0.5 estimated).

    Returns a [`FrequencyFit`][].
    """

    band: tuple[float, float] | None = eqx.field(static=True, default=None)
    every: int = eqx.field(static=True, default=1)
    end_terms: str = eqx.field(static=True, default="estimated")
    start_from_equation_error: bool = eqx.field(static=True, default=True)

    def __check_init__(self):
        _check_band(self.band)
        if self.end_terms not in ("estimated", "measured"):
            raise ValueError("end_terms must be 'estimated' or 'measured'")

    def estimate(self, model, records, *, max_iter, throw, progress) -> FrequencyFit:
        del progress
        start = None
        if self.start_from_equation_error and all(
            s in model.outputs for s in model.states
        ):
            try:
                start = frequency_equation_error(
                    model, records, band=self.band, every=self.every
                ).params
            except ValueError:
                start = None  # not linear in its parameters: the model's start
        return frequency_output_error(
            model,
            records,
            band=self.band,
            every=self.every,
            start=start,
            end_terms=self.end_terms,
            max_iter=100 if max_iter is None else max(max_iter, 1),
            throw=throw,
        )


class FrequencyEquationError(AbstractEstimator):
    """Equation error in the frequency domain (Klein & Morelli ch. 7, SIDPAC
    `fdee`): every state equation and every output equation with parameters as a
    complex regression on the measured states' and inputs' transforms in `band`
    (Hz; default from the inputs' spectrum). Needs every state measured and the
    model linear in its estimated parameters; a start for
    [`FrequencyOutputError`][].

    Returns a [`FrequencyFit`][] (`max_iter` bounds the re-weighting passes).
    """

    band: tuple[float, float] | None = eqx.field(static=True, default=None)
    every: int = eqx.field(static=True, default=1)

    def __check_init__(self):
        _check_band(self.band)

    def estimate(self, model, records, *, max_iter, throw, progress) -> FrequencyFit:
        del throw, progress
        return frequency_equation_error(
            model,
            records,
            band=self.band,
            every=self.every,
            weighting_passes=4 if max_iter is None else max(max_iter, 1),
        )
