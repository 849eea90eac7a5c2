"""The score statistics' null distribution from the log itself: a sieve bootstrap
of the fit's residuals through the efficient score.

At a fit with the candidates held, each candidate's score is `sum rows * residuals`,
`rows` its whitened sensitivities with every free unknown projected out
([`ScoreTest`][]'s `rows`). Because they are projected, the score is unchanged, to
first order, when the free unknowns are refitted to other residuals: a residual
series `e*` drawn under the null gives the statistic a refit would give without
refitting (measured against refits in the validation page). So the null
distribution is the statistic recomputed on replicate residuals at the fitted
Jacobian, vmapped over replicates:

- the replicates' residuals come from a **vector autoregression fitted to the
  fit's residuals** ([`sieve`][]: order by Schwarz's criterion, Yule-Walker), its
  innovation rows drawn with replacement (all outputs at once: their covariance
  is kept) and filtered again: the residuals' colour is kept at every lag, where
  a block bootstrap keeps it only within a block (and so gives a null too light
  for strongly coloured residuals: measured in the validation page);
- each replicate's statistic is **studentised** exactly as the observed one. A
  score is fixed sensitivities (the manoeuvre's) times residuals, so its
  variance is the residuals' autocovariance (between outputs too) weighed by the
  sensitivities' own, summed over lags under a Bartlett lag window
  ([`_statistics`][]); the window's bandwidth is Andrews' rule on the log's
  residuals after each candidate's own step ([`windows_of`][]), taken once and
  used unchanged on every replicate, whose autocovariance is its own. A lag
  window, not the sum over all lags the score test reports ([`score_variance`][]):
  the all-lag sum scatters from record to record by an amount no resampling
  reproduces; and the residuals' colour, not that of the per-sample product of
  sensitivity and residual: a candidate's signature is local to the manoeuvre
  (a doublet, a step), and a lag window on the product counts what is left of it
  after the step as noise, at its full local strength (measured in the
  validation page);
- the family-wise null is the **maximum** over all candidates of each replicate,
  so a candidate's p-value (Westfall and Young's single-step max-T) is the share of
  replicates whose largest statistic reaches its own, and the threshold at level
  `a` is the `1 - a` quantile of those maxima: candidates correlated with each
  other are not counted as independent tests, as Bonferroni would.

What the bootstrap cannot do: a structural misfit of the baseline is systematic,
aligned with the manoeuvre, and resampling moves it off that alignment. How the
rule deals with it is the business of [`_rule`][]; this module gives the null of
the statistic for residuals with the log's own colour and cross-correlation.
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int


class Sieve(eqx.Module):
    """A vector autoregression of a residual series, the null's generator: `order`
    lags, chosen by Schwarz's criterion; `coefficients` `(order, channels,
    channels)`; `innovations` `(samples - order, channels)`, centred."""

    order: int
    coefficients: Float[Array, "order channels channels"]
    innovations: Float[Array, "rows channels"]

    def transfer(self, n: int) -> np.ndarray:
        """`(n // 2 + 1, channels, channels)` complex: the filter from innovations to
        the series at the real FFT's frequencies of `n` samples."""
        a = np.asarray(self.coefficients)
        f = np.arange(n // 2 + 1) / n
        h = np.tile(np.eye(a.shape[-1], dtype=complex), (len(f), 1, 1))
        for j in range(a.shape[0]):
            h -= a[j][None] * np.exp(-2j * np.pi * f * (j + 1))[:, None, None]
        return np.linalg.inv(h)


def sieve(
    residuals: np.ndarray, most: int | None = None, order: int | None = None
) -> Sieve:
    """The autoregression of each channel of `residuals` `(samples, channels)`
    (centred), its order minimising Schwarz's criterion `n ln sigma_p^2 + p ln n`
    over `p = 0 .. most` (default `10 log10 n`, as R's `ar`, at most `n / 4`), fitted by
    Yule-Walker (always a stable filter), and the innovations the filters leave
    (centred, rows of all channels together). A sieve bootstrap (Buhlmann 1997)
    draws innovation rows with replacement and filters them: each channel's colour
    is kept at every lag the order reaches and beyond it by the recursion, where a
    block bootstrap cuts it at the block's length; the channels' covariance is kept
    through the innovations' (drawn as whole rows). Schwarz's criterion, not
    Akaike's: a fit's residuals have its free unknowns' share projected out (for
    shooting nodes, a line per segment), a colour of the fit, not of the noise,
    which the replicates' own refit takes out again; Akaike's criterion models it
    (order 10 on white noise so projected) and the null, projected twice, is too
    light (measured: 23 false alarms in 150 at level 0.05, 7 with Schwarz's). Each channel has its own order:
    a joint (vector) autoregression pays `channels^2` parameters a lag, and on a
    log of 8 outputs an information criterion then keeps none, losing one channel's slow
    colour. `order` fixes every channel's order instead. The returned `order` is
    the largest."""
    import scipy.linalg

    e = np.asarray(residuals, float)
    n, c = e.shape
    e = e - e.mean(axis=0)
    if most is None:
        most = int(np.ceil(10.0 * np.log10(n)))
    most = max(0, min(most, n // 4))
    spectrum = np.fft.rfft(e, n=2 * n, axis=0)
    gamma = np.fft.irfft(np.abs(spectrum) ** 2, axis=0)[: most + 1] / n
    fitted = []
    for ch in range(c):
        g = gamma[:, ch]
        best = (0.0, 0, np.zeros(0))
        if g[0] > 0:
            best = (n * np.log(g[0]), 0, np.zeros(0))
            for p in range(1, most + 1) if order is None else (int(order),):
                a_p = scipy.linalg.solve_toeplitz(g[:p], g[1 : p + 1])
                sigma = g[0] - a_p @ g[1 : p + 1]
                if not sigma > 0:
                    break
                aic = n * np.log(sigma) + p * np.log(n)
                if order is not None or aic < best[0]:
                    best = (aic, p, a_p)
        fitted.append(best[2])
    top = max(len(a_p) for a_p in fitted)
    a = np.zeros((top, c, c))
    u = e[top:].copy()
    for ch, a_p in enumerate(fitted):
        a[: len(a_p), ch, ch] = a_p
        for j in range(len(a_p)):
            u[:, ch] -= a_p[j] * e[top - 1 - j : n - 1 - j, ch]
    return Sieve(order=int(top), coefficients=a, innovations=u - u.mean(axis=0))


class Calibration(eqx.Module):
    """The null distribution of the largest score statistic over the candidates.

    **Fields:** `threshold` (the statistic a candidate must exceed: the `1 - level`
    quantile of `maxima`); `level` (the family-wise false-alarm level it holds);
    `maxima` `(replicates,)` the largest statistic of each bootstrap replicate;
    `order` (lags of the autoregression that generated the replicates' residuals);
    `samples` (residual samples).
    """

    threshold: float
    level: float
    maxima: Float[Array, " replicates"]
    order: int
    samples: int

    def p_values(self, statistic) -> np.ndarray:
        """Family-wise (max-T) p-values of observed statistics: the share of
        replicates whose largest statistic reaches each, counting the observation
        itself (never 0)."""
        m = np.asarray(self.maxima)
        s = np.atleast_1d(np.asarray(statistic, float))
        return (1.0 + np.sum(m[None, :] >= s[:, None], axis=1)) / (1.0 + m.shape[0])

    def describe(self) -> str:
        return (
            f"threshold {self.threshold:.3g}: the {100 * (1 - self.level):g}% point of "
            f"the largest score statistic over all candidates in {self.maxima.shape[0]} "
            f"sieve-bootstrap replicates of this fit's residuals (an autoregression "
            f"of order {self.order} fitted to them): a false-alarm level of "
            f"{self.level:g} for the whole diagnosis"
        )


class _Spectra(eqx.Module):
    # what every replicate shares: the candidates' sensitivities, the fit's refit
    # operator, and the lag-windowed products of the sensitivities that turn a
    # residual series' autocovariance into each score's variance ([`_windows`][])
    rows: Float[Array, "samples outputs k"]
    curvature: Float[Array, " k"]
    offset: Float[Array, " k"]
    basis: Float[Array, "samples outputs unknowns"] | None
    windowed: Float[Array, "lags outputs outputs k"]  # w(l) C(l), l = -(L-1)..L-1
    smoothed: Float[Array, "samples outputs k"]
    own: Float[Array, "outputs outputs k"]


def _spectra(rows, curvature, offset, basis=None, windows=None) -> _Spectra:
    # without windows, those of white residuals (a bandwidth of one lag)
    if windows is None:
        windows = _windows(rows, 1.0)
    return _Spectra(rows, curvature, offset, basis, *windows)


def bandwidth(e) -> float:
    """Andrews' (1991) plug-in bandwidth, samples, of the Bartlett lag window for
    the long-run covariance of a residual series `e` `(samples, channels)`: an
    autoregression of order one per channel (`rho`, variance `s2`),
    `S = 1.1447 (alpha n)^(1/3)`, `alpha = sum 4 rho^2 s2^2 / ((1 - rho)^6
    (1 + rho)^2) / sum s2^2 / (1 - rho)^4`; between 1 and `n`."""
    e = np.asarray(e, float)
    n = e.shape[0]
    e = e - e.mean(axis=0)
    g0 = np.sum(e * e, axis=0)
    g1 = np.sum(e[:-1] * e[1:], axis=0)
    rho = np.clip(g1 / np.maximum(g0, np.finfo(float).tiny), -1 + 1e-9, 1 - 1e-9)
    s4 = (g0 / n) ** 2
    num = np.sum(4 * rho**2 * s4 / ((1 - rho) ** 6 * (1 + rho) ** 2))
    den = np.sum(s4 / (1 - rho) ** 4)
    alpha = num / den if den > 0 else 0.0
    return float(np.clip(1.1447 * (alpha * n) ** (1.0 / 3.0), 1.0, n))


def _windows(rows, bandwidths):
    """The parts of the lag-window variance that depend on the sensitivities only,
    candidate `k` with Bartlett weights `w(l) = 1 - |l| / S_k`:
    `windowed[l, a, b] = w(l) C_ab(l)`, `C_ab(l) = sum_t rows[t, a] rows[t + l, b]`
    (`l = -(L-1)..L-1`, `L` the largest bandwidth rounded up to a power of two,
    so that few shapes are compiled); `own[a, b] = sum_t rows[t, a] H[t, a, b]`
    and `smoothed[t, a] = sum_b H[t, a, b]`, with
    `H[t, a, b] = (1 / n) sum_l w(l) C_ab(l) rows[t + l, b]`."""
    rows = np.asarray(rows, float)
    n, o, k = rows.shape
    bandwidths = np.broadcast_to(np.asarray(bandwidths, float), (k,))
    lags = 2 ** int(np.ceil(np.log2(max(1.0, np.max(bandwidths)))))
    lags = max(1, min(lags, n))
    ell = np.arange(-(lags - 1), lags)
    w = np.clip(1.0 - np.abs(ell)[:, None] / bandwidths[None, :], 0.0, 1.0)
    c = np.empty((len(ell), o, o, k))
    for i, lag in enumerate(ell):
        if lag >= 0:
            c[i] = np.einsum("tak,tbk->abk", rows[: n - lag], rows[lag:])
        else:
            c[i] = np.einsum("tak,tbk->abk", rows[-lag:], rows[: n + lag])
    windowed = w[:, None, None, :] * c
    smoothed = np.zeros((n, o, k))
    for i, lag in enumerate(ell):
        lo, hi = max(0, -lag), min(n, n - lag)  # 0 <= t + lag < n
        smoothed[lo:hi] += np.einsum(
            "abk,tbk->tak", windowed[i], rows[lo + lag : hi + lag]
        )
    smoothed /= n
    # sum_t rows[t, a] H[t, a, b] = (1 / n) sum_l w(l) C_ab(l)^2
    own = np.einsum("labk,labk->abk", windowed, c) / n
    return windowed, smoothed, own


def windows_of(rows, residuals, curvature, offset):
    """Each candidate's Bartlett window, taken once from the log: Andrews'
    bandwidth ([`bandwidth`][]) of the residuals the candidate's own step leaves
    (`residuals - slope / curvature * rows_k`: under an alternative the step takes
    the candidate's signature out, which would otherwise read as colour), and the
    window's products ([`_windows`][]). **Returns** `(parts, bandwidths (k,))`."""
    rows = np.asarray(rows, float)
    e = np.asarray(residuals, float)
    slope = np.einsum("nok,no->k", rows, e) + np.asarray(offset, float)
    a = -slope / np.asarray(curvature, float)
    s = np.array([bandwidth(e + a[j] * rows[..., j]) for j in range(rows.shape[2])])
    return _windows(rows, s), s


def _refitted(sp: _Spectra, e_star):
    """The residual a linearised refit of the fit's free unknowns leaves of
    `e_star` (unchanged without a basis)."""
    if sp.basis is None:
        return e_star
    return e_star - jnp.einsum(
        "nou,u->no", sp.basis, jnp.einsum("nou,no->u", sp.basis, e_star)
    )


def _statistics(sp: _Spectra, e_star, refit: bool = False):
    """Studentised score statistic of every candidate on one residual series
    `e_star` `(samples, outputs)` and its variance: `(k,)`, `(k,)`.

    The score is `sum_t sum_o rows[t, o] e[t, o]`: fixed sensitivities (the
    manoeuvre's, not a random series) times residuals. Its variance is
    `sum_l w(l) sum_ab gamma_ab(l) C_ab(l)`: `gamma` the residuals'
    autocovariance (between outputs too) estimated from `e_star`, `C` the
    sensitivities' own, `w` the candidate's Bartlett lag window, the same for the
    log and every replicate ([`windows_of`][]). The residuals are taken after the
    candidate's own step (`e - slope / curvature * rows`: under an alternative
    the step's signature would otherwise count as noise), expanded in the step so
    that no per-candidate series is formed. Never below `curvature`, the variance
    under white residuals of unit variance. `sp.offset` `(k,)` is the score's
    part from the fit's continuity defects, which do not depend on the data.

    With `refit` (a bootstrap replicate), as a refit to data with these residuals
    would see them, to first order: the free unknowns refitted (`sp.basis`), then
    the output weights re-estimated from the refitted residuals (an
    output-error fit's weights make the observed residuals unit mean
    square; a replicate's, once refitted, have less). Each output's residuals and
    sensitivities are whitened again by it, which is a weight `1 / c` per output
    on every product (`c` the refitted replicate's mean square there)."""
    n = e_star.shape[0]
    if refit:
        e_star = _refitted(sp, e_star)
        c = jnp.mean(e_star**2, axis=0)
        v = 1.0 / jnp.maximum(c, 1e-12 * jnp.max(c))
    else:
        v = jnp.ones(e_star.shape[1])
    slope = jnp.einsum("nok,no,o->k", sp.rows, e_star, v) + sp.offset
    # the curvature's part from the outputs is reweighted; the defects' part not
    q = jnp.einsum("nok,o->k", sp.rows**2, v)
    curvature = sp.curvature + q - jnp.sum(sp.rows**2, axis=(0, 1))
    a = -slope / curvature
    e = e_star - jnp.mean(e_star, axis=0)[None, :]
    vv = v[:, None] * v[None, :]
    # gamma_ab(l) = (1 / n) sum_t e[t, a] e[t + l, b], l = -(L-1)..L-1, by FFT
    lags = (sp.windowed.shape[0] + 1) // 2
    spectrum = jnp.fft.rfft(e, n=2 * n, axis=0)
    cross = jnp.fft.irfft(
        jnp.conj(spectrum)[:, :, None] * spectrum[:, None, :], n=2 * n, axis=0
    )
    gamma = jnp.concatenate([cross[2 * n - lags + 1 :], cross[:lags]], axis=0) / n
    noise = jnp.einsum("lab,labk,ab->k", gamma, sp.windowed, vv)
    # the cross term weighs the partner output b by the mean weight, not its own
    # (exact when the weights are equal, as for a log's own residuals; a refit
    # moves them apart by the free unknowns' share, and the term is first order
    # in the step, small under the null): an array (samples, outputs, k) instead
    # of (samples, outputs, outputs, k)
    step = jnp.einsum("na,nak,a->k", e, sp.smoothed, v) * jnp.mean(v)
    signal = jnp.einsum("abk,ab->k", sp.own, vv)
    variance = jnp.maximum(noise + 2.0 * a * step + a**2 * signal, curvature)
    return slope**2 / variance, variance


@functools.partial(jax.jit, static_argnames=("replicates", "chunk"))
def _bootstrap(
    rows,
    innovations,
    transfer,
    curvature,
    offset,
    key,
    basis,
    windows,
    *,
    replicates,
    chunk,
):
    n = rows.shape[0]
    sp = _spectra(rows, curvature, offset, basis, windows)

    def one(k):
        # innovation rows drawn with replacement (all channels at once: their
        # covariance is kept), filtered by the autoregression (circularly, by FFT)
        index = jax.random.randint(k, (n,), 0, innovations.shape[0])
        u = jnp.fft.rfft(innovations[index], axis=0)
        e = jnp.fft.irfft(jnp.einsum("fab,fb->fa", transfer, u), n=n, axis=0)
        return jnp.max(_statistics(sp, e, refit=True)[0])

    keys = jax.random.split(key, replicates)
    return jax.lax.map(one, keys, batch_size=chunk)


@jax.jit
def _observed(rows, residuals, curvature, offset, windows):
    return _statistics(_spectra(rows, curvature, offset, None, windows), residuals)


def statistics(
    rows: Float[Array, "samples outputs k"],
    residuals: Float[Array, "samples outputs"],
    curvature: Float[Array, " k"],
    slope: Float[Array, " k"],
    *,
    variance: bool = False,
):
    """The studentised score statistics `(k,)` of the candidates of a score test
    from its parts (`rows`, `residuals` of the valid samples, `curvature`,
    `slope`), as the bootstrap computes them on every replicate (see
    [`_statistics`][]); with `variance`, also the score's variance `(k,)` (a
    candidate's standard error is its square root over `curvature`)."""
    rows = np.asarray(rows, float)
    residuals = np.asarray(residuals, float)
    curvature = np.asarray(curvature, float)
    offset = np.asarray(slope, float) - np.einsum("nok,no->k", rows, residuals)
    windows, _ = windows_of(rows, residuals, curvature, offset)
    stat, var = _observed(rows, residuals, curvature, offset, windows)
    if variance:
        return np.asarray(stat), np.asarray(var)
    return np.asarray(stat)


def calibrate(
    rows: Float[Array, "samples outputs k"],
    residuals: Float[Array, "samples outputs"],
    curvature: Float[Array, " k"],
    slope: Float[Array, " k"],
    *,
    level: float = 0.01,
    replicates: int = 2000,
    key: Int[Array, ""] | None = None,
    order: int | None = None,
    resample: Float[Array, "samples outputs"] | None = None,
    basis: Float[Array, "samples outputs unknowns"] | None = None,
) -> Calibration:
    """The family-wise null of a score test from its own residuals (see the module).

    A parametric bootstrap of the fitted model: data = the fit's outputs plus
    residuals drawn from the autoregression fitted to the fit's residuals ([`sieve`][]),
    each replicate's statistic by the efficient score at the fitted Jacobian
    (first-order equal to refitting the free unknowns).

    **Arguments:** `rows` `(samples, outputs, k)` whitened projected sensitivities
    and `residuals` `(samples, outputs)` whitened residuals, valid samples only, in
    time order; `curvature` `(k,)`; `slope` `(k,)` the observed scores (their part
    not explained by `rows x residuals`, from the continuity defects of a multiple-
    shooting fit, is the same in every replicate: it does not depend on the data);
    all from a [`ScoreTest`][]. `level` the family-wise false-alarm level;
    `replicates`; `key` (default a fixed one: the same log gives the same
    threshold); `order` of the autoregression (default chosen by Schwarz's
    criterion on the series resampled); `resample` the series the autoregression
    is fitted to (default `residuals`; the diagnosis passes the residuals with the
    strongest candidate's step taken, so that a strong effect in the log does not
    widen its own null), centred per channel; `basis` `(samples, outputs,
    unknowns)` the fit's refit operator ([`ScoreTest`][]'s `basis`): each
    replicate's residual is first refitted (to first order, `e - basis basis^T e`)
    as the observed one was, so its statistic is studentised by the residual a
    refit leaves (without it the null is lighter than the refitted one: a fit
    takes its free unknowns' share out of the observed residual's variance, not
    out of a resampled one's).

    **Returns:** a [`Calibration`][].
    """
    rows = np.asarray(rows, float)
    residuals = np.asarray(residuals, float)
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1), got {level}")
    if replicates * level < 5:
        raise ValueError(
            f"{replicates} replicates cannot place a threshold at level {level}: "
            f"use at least {int(np.ceil(5 / level))}"
        )
    resample = residuals if resample is None else np.asarray(resample, float)
    # centred per channel, as in any residual bootstrap: an offset in the residuals
    # (a bias the log has and the fit lacks) would otherwise be in every replicate
    # and hide itself
    resample = resample - resample.mean(axis=0)
    fitted = sieve(resample, order=order)
    n = rows.shape[0]
    if key is None:
        key = jax.random.key(0)
    offset = np.asarray(slope, float) - np.einsum("nok,no->k", rows, residuals)
    # the windows are the observed log's, used unchanged on every replicate
    windows, _ = windows_of(rows, residuals, curvature, offset)
    maxima = _bootstrap(
        jnp.asarray(rows),
        jnp.asarray(fitted.innovations, float),
        jnp.asarray(fitted.transfer(n)),
        jnp.asarray(curvature, float),
        jnp.asarray(offset),
        key,
        None if basis is None else jnp.asarray(basis, float),
        windows,
        replicates=int(replicates),
        chunk=8,
    )
    maxima = np.asarray(maxima)
    threshold = float(np.quantile(maxima, 1.0 - level, method="higher"))
    return Calibration(
        threshold=threshold,
        level=float(level),
        maxima=maxima,
        order=int(fitted.order),
        samples=int(n),
    )
