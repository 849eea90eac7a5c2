"""Fit metrics per output channel, and where the misfit lives.

All functions take plain arrays: `measured`, `model` `(samples, channels)`; they work
for any model and log, not only the global Pegasus model.
"""

import math

import numpy as np


WHITENESS_LAGS = 20


def chi2_sf(x: float, dof: float) -> float:
    """Survival function of the chi-square distribution."""
    # scipy on the host (imported here: it takes a while): jax's would compile a
    # program for one number
    import scipy.special

    return float(scipy.special.gammaincc(dof / 2.0, max(float(x), 0.0) / 2.0))


def noise_sigma(x: np.ndarray) -> float:
    """White-noise standard deviation of a signal from its second differences
    (insensitive to smooth content): `std(x[i+1] - 2 x[i] + x[i-1]) / sqrt(6)`."""
    d2 = np.diff(np.asarray(x, float), 2)
    return float(np.sqrt(np.mean(d2**2) / 6.0))


def residual_noise_sigma(e: np.ndarray, band: float = 0.5) -> float:
    """White-noise standard deviation of a residual from its spectrum above the
    model's bandwidth: the median periodogram ordinate over the top `band` of the
    frequencies (a white series has a flat spectrum whose ordinates are exponential,
    median `sigma^2 ln 2`). The residual has the signal removed, and the median is
    robust to the few broad-band transients a step between samples leaves, so real
    high-frequency content of the measurement (a pulse's edges in qdot, which second
    differences of the measurement count as noise) is not counted."""
    e = np.asarray(e, float)
    e = e - e.mean()
    n = len(e)
    if n < 8:
        return float(np.std(e))
    power = np.abs(np.fft.rfft(e)) ** 2 / n
    upper = power[int(np.ceil((1.0 - band) * (len(power) - 1))) : len(power) - 1]
    if upper.size == 0:
        return float(np.std(e))
    return float(np.sqrt(np.median(upper) / np.log(2.0)))


def autocorrelation(e: np.ndarray, lags: int) -> np.ndarray:
    """Sample autocorrelation at lags `1..lags`."""
    e = e - e.mean()
    c0 = np.dot(e, e)
    if c0 == 0:
        return np.zeros(lags)
    return np.array([np.dot(e[:-k], e[k:]) / c0 for k in range(1, lags + 1)])


def ljung_box(e: np.ndarray, lags: int = WHITENESS_LAGS) -> tuple[float, float]:
    """Ljung-Box statistic over `lags` lags and its p-value (small: not white)."""
    n = len(e)
    rho = autocorrelation(e, lags)
    q = n * (n + 2) * float(np.sum(rho**2 / (n - np.arange(1, lags + 1))))
    return q, chi2_sf(q, lags)


def long_run_variance(e: np.ndarray) -> float:
    """Variance of the mean times `n` for a correlated series (Newey-West, Bartlett
    weights, bandwidth `4 (n / 100)^(2/9)`)."""
    n = len(e)
    e = e - e.mean()
    lag = int(math.floor(4 * (n / 100.0) ** (2.0 / 9.0)))
    v = np.dot(e, e) / n
    for k in range(1, lag + 1):
        v += 2 * (1 - k / (lag + 1)) * np.dot(e[:-k], e[k:]) / n
    return float(max(v, 0.0))


def cross_correlation(e: np.ndarray, u: np.ndarray, lags: int) -> np.ndarray:
    """Normalised cross-correlation of residual `e` with input `u` at lags
    `-lags..lags` (positive: the input leads)."""
    e = e - e.mean()
    u = u - u.mean()
    norm = np.sqrt(np.dot(e, e) * np.dot(u, u))
    if norm == 0:
        return np.zeros(2 * lags + 1)
    out = []
    for k in range(-lags, lags + 1):
        if k >= 0:
            out.append(np.dot(e[k:], u[: len(u) - k]))
        else:
            out.append(np.dot(e[: len(e) + k], u[-k:]))
    return np.array(out) / norm


def channel_metrics(
    measured: np.ndarray,
    model: np.ndarray,
    inputs: np.ndarray | None = None,
    noise: float | None = None,
) -> dict[str, float]:
    """Metrics of one channel's fit (SI units of the channel).

    `rms` of the residual; `nrms` (rms over the measured range); `bias` (mean
    residual) and its 95% interval `bias_ci95` (from the long-run variance, so
    coloured residuals do not shrink it); `tic` (Theil's inequality coefficient, 0
    perfect, above about 0.3 poor); `r2`; `noise` (white-noise sigma of the
    measurement: the given `noise`, e.g. from the log's sidecar, else
    [`residual_noise_sigma`][] of the residual) and `misfit_ratio = rms / noise`
    (about 1: the model explains everything but the noise); `ljung_box`, `ljung_box_p`
    (whiteness over 20 lags; a small p says the residual is not white: structure is
    left); `autocorrelation` (lags 1..20); `xcorr_input_max` (largest residual-input
    cross-correlation over +/-20 lags) with its 95% white-noise bound
    `xcorr_bound`.
    """
    e = measured - model
    n = len(e)
    rms = float(np.sqrt(np.mean(e**2)))
    span = float(np.ptp(measured))
    sst = float(np.sum((measured - measured.mean()) ** 2))
    half = 1.96 * math.sqrt(long_run_variance(e) / n)
    bias = float(e.mean())
    denom = float(np.sqrt(np.mean(measured**2)) + np.sqrt(np.mean(model**2)))
    q, p = ljung_box(e)
    sigma = residual_noise_sigma(e) if noise is None else float(noise)
    out = {
        "rms": rms,
        "nrms": rms / span if span > 0 else float("nan"),
        "bias": bias,
        "bias_ci95": [bias - half, bias + half],
        "tic": rms / denom if denom > 0 else float("nan"),
        "r2": 1.0 - float(np.sum(e**2)) / sst if sst > 0 else float("nan"),
        "noise": sigma,
        "misfit_ratio": rms / sigma if sigma > 0 else float("inf"),
        "ljung_box": q,
        "ljung_box_p": p,
        "autocorrelation": autocorrelation(e, WHITENESS_LAGS).tolist(),
    }
    if inputs is not None:
        xc = cross_correlation(e, inputs, WHITENESS_LAGS)
        out["xcorr_input_max"] = float(np.max(np.abs(xc)))
        out["xcorr_bound"] = 1.96 / math.sqrt(n)
    return out


def binned_misfit(
    residuals: np.ndarray, noise: np.ndarray, variable: np.ndarray, edges: np.ndarray
) -> list[dict]:
    """Residual RMS over noise sigma per channel in each bin of `variable`
    (`edges` increasing); bins with fewer than 10 samples are left out."""
    rows = []
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        sel = (variable >= lo) & (variable <= hi)
        if sel.sum() < 10:
            continue
        ratio = np.sqrt(np.mean(residuals[sel] ** 2, axis=0)) / noise
        rows.append(
            {
                "low": float(lo),
                "high": float(hi),
                "samples": int(sel.sum()),
                "misfit_ratio": ratio.tolist(),
            }
        )
    return rows
