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
- each replicate's statistic is **studentised** exactly as the observed one (its
  variance from the replicate's own residuals after its own step,
  [`score_variance`][]), so the null holds whatever the residuals' scale;
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


def _flat_top(x):
    # the trapezoidal flat-top lag window of Politis and White (2004)
    x = np.abs(x)
    return np.where(x <= 0.5, 1.0, np.where(x <= 1.0, 2.0 * (1.0 - x), 0.0))


def block_length(residuals: np.ndarray) -> int:
    """Circular-block length, in samples, for a bootstrap of `residuals` `(samples,
    channels)`: Politis and White's (2004, corrected 2009) automatic choice for each
    channel, the largest over channels (all channels are resampled with the same
    blocks), at least 1 and at most their `min(3 sqrt(n), n / 3)`.

    Per channel: the first lag `m` after which `K = max(5, sqrt(log10 n))`
    autocorrelations in a row are below `2 sqrt(log10 n / n)`; the flat-top window
    to `2m` gives `G = sum lambda(k/2m) |k| gamma(k)` and the spectral density at zero
    `g = sum lambda(k/2m) gamma(k)`; the circular-block length is
    `(2 G^2 / D)^(1/3) n^(1/3)` with `D = 4/3 g^2`.
    """
    e = np.asarray(residuals, float)
    n = e.shape[0]
    e = e - e.mean(axis=0)
    spectrum = np.abs(np.fft.rfft(e, n=2 * n, axis=0)) ** 2
    gamma = np.fft.irfft(spectrum, axis=0)[:n] / n
    k_run = max(5, int(np.ceil(np.sqrt(np.log10(n)))))
    bound = 2.0 * np.sqrt(np.log10(n) / n)
    longest = 1.0
    for c in range(e.shape[1]):
        g = gamma[:, c]
        if not g[0] > 0:
            continue
        rho = np.abs(g / g[0])
        small = rho[1:] < bound
        m = n // 3
        for lag in range(len(small) - k_run):
            if small[lag : lag + k_run].all():
                m = lag
                break
        big_m = min(2 * max(m, 1), n - 1)
        lags = np.arange(-big_m, big_m + 1)
        w = _flat_top(lags / big_m)
        gk = g[np.abs(lags)]
        big_g = np.sum(w * np.abs(lags) * gk)
        g0 = np.sum(w * gk)
        if g0 <= 0:
            continue
        d = (4.0 / 3.0) * g0**2
        length = (2.0 * big_g**2 / d) ** (1.0 / 3.0) * n ** (1.0 / 3.0)
        longest = max(longest, float(length))
    most = int(np.ceil(min(3.0 * np.sqrt(n), n / 3.0)))
    return int(np.clip(np.ceil(longest), 1, max(1, most)))


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
    # what every replicate shares: the candidates' sensitivities in the frequency
    # domain (one-sided, `weight` counting each bin's mirror, zero-padded to an
    # even FFT length of small prime factors, at least `2 samples - 1`, so that
    # every product is a linear, not circular, correlation) and the sums over
    # frequency and time that do not depend on the residuals
    rows: Float[Array, "samples outputs k"]
    spectrum: Array  # (bins, outputs, k), complex
    power: Float[Array, "bins outputs k"]
    spectrum_power: Array  # spectrum x power
    weight: Float[Array, " bins"]
    curvature: Float[Array, " k"]
    offset: Float[Array, " k"]
    basis: Float[Array, "samples outputs unknowns"] | None
    by_output: Float[Array, "outputs k"]  # sum over samples of rows^2
    power_sq: Float[Array, "outputs k"]  # sum_f weight power^2
    power_pairs: Float[Array, "outputs outputs k"]  # sum_f weight power power'
    length: int = eqx.field(static=True)  # of the FFT


def _fft_length(n: int) -> int:
    # the smallest even length >= 2n - 1 of prime factors 2, 3 and 5: a log's 2n
    # (3002 = 2 x 19 x 79 at 1501 samples) transforms several times slower
    length = 2 * n
    m = length - 2 if length > 2 else length
    while m < 2 * n - 1:
        m += 2
    while True:
        rest = m
        for f in (2, 3, 5):
            while rest % f == 0:
                rest //= f
        if rest == 1:
            return m
        m += 2


def _spectra(rows, curvature, offset, basis=None) -> _Spectra:
    n = rows.shape[0]
    length = _fft_length(n)
    spectrum = jnp.fft.rfft(rows, n=length, axis=0)
    weight = jnp.full(spectrum.shape[0], 2.0).at[0].set(1.0).at[-1].set(1.0)
    power = jnp.abs(spectrum) ** 2
    return _Spectra(
        rows,
        spectrum,
        power,
        spectrum * power,
        weight,
        curvature,
        offset,
        basis,
        jnp.einsum("nok,nok->ok", rows, rows),
        jnp.einsum("f,fok->ok", weight, power**2),
        jnp.einsum("f,fok,fpk->opk", weight, power, power),
        length,
    )


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
    `e_star` `(samples, outputs)`, exactly as [`score`][] computes it (the variance
    of [`score_variance`][] from the residuals after the candidate's own step),
    expanded in the step so that no `(bins, outputs, k)` product is formed per
    candidate: `(k,)`. `sp.offset` `(k,)` is the score's part from the fit's
    continuity defects, which do not depend on the data.

    With `refit` (a bootstrap replicate), as a refit to data with these residuals
    would see them, to first order: the free unknowns refitted (`sp.basis`), then
    the residual variance of every output estimated again (the fit's R is the
    mean square of its own residuals, so its whitened residuals have unit mean
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
    curvature = sp.curvature + jnp.einsum("o,ok->k", v - 1.0, sp.by_output)
    a = -slope / curvature
    e_f = jnp.fft.rfft(e_star, n=sp.length, axis=0) * v[None, :]  # reweighted
    w = sp.weight
    # joint: sum_f |sum_o v (conj(E) R + a |R|^2)|^2
    cross = jnp.einsum("fo,fok->fk", jnp.conj(e_f), sp.spectrum)
    q = jnp.einsum("fok,o->fk", sp.power, v)
    joint = (
        jnp.einsum("f,fk->k", w, jnp.abs(cross) ** 2)
        + 2.0 * a * jnp.einsum("f,fk,fk->k", w, jnp.real(cross), q)
        + a**2 * jnp.einsum("o,p,opk->k", v, v, sp.power_pairs)
    )
    # own: sum_f sum_o v^2 |conj(E) R + a |R|^2|^2
    wv = w[:, None] * v[None, :]
    own = (
        jnp.einsum("fo,fok->k", w[:, None] * jnp.abs(e_f) ** 2, sp.power)
        + 2.0
        * a
        * (
            jnp.einsum("fo,fok->k", wv * jnp.real(e_f), jnp.real(sp.spectrum_power))
            + jnp.einsum("fo,fok->k", wv * jnp.imag(e_f), jnp.imag(sp.spectrum_power))
        )
        + a**2 * jnp.einsum("o,ok->k", v**2, sp.power_sq)
    )
    # the sums over the FFT's bins are `length` times the sums over lags
    variance = jnp.maximum(joint, own) / (sp.length * n)
    return slope**2 / jnp.maximum(variance, curvature)


@functools.partial(jax.jit, static_argnames=("replicates", "chunk"))
def _bootstrap(
    rows,
    innovations,
    count,
    transfer,
    curvature,
    offset,
    key,
    basis,
    *,
    replicates,
    chunk,
):
    n = rows.shape[0]
    sp = _spectra(rows, curvature, offset, basis)

    def one(k):
        # innovation rows drawn with replacement (all channels at once: their
        # covariance is kept), filtered by the autoregression (circularly, by FFT)
        index = jax.random.randint(k, (n,), 0, count)
        u = jnp.fft.rfft(innovations[index], axis=0)
        e = jnp.fft.irfft(jnp.einsum("fab,fb->fa", transfer, u), n=n, axis=0)
        return jnp.max(_statistics(sp, e, refit=True))

    keys = jax.random.split(key, replicates)
    return jax.lax.map(one, keys, batch_size=chunk)


@jax.jit
def _observed(rows, residuals, curvature, offset):
    return _statistics(_spectra(rows, curvature, offset), residuals)


def padded_count(k: int) -> int:
    """Candidates are padded to a multiple of 4, so that diagnoses of one log with
    a few candidates more or fewer (after an effect is added) share one compiled
    score test and bootstrap."""
    return max(4, -(-int(k) // 4) * 4)


def _pad(rows, curvature, offset):
    # a padded candidate has no sensitivity and unit curvature: its statistic is
    # 0, below every real one, so the maximum over candidates is unchanged
    k = rows.shape[-1]
    extra = padded_count(k) - k
    if not extra:
        return rows, curvature, offset
    return (
        np.concatenate([rows, np.zeros(rows.shape[:-1] + (extra,))], axis=-1),
        np.concatenate([curvature, np.ones(extra)]),
        np.concatenate([offset, np.zeros(extra)]),
    )


def statistics(
    rows: Float[Array, "samples outputs k"],
    residuals: Float[Array, "samples outputs"],
    curvature: Float[Array, " k"],
    slope: Float[Array, " k"],
) -> np.ndarray:
    """The score statistics `(k,)` of [`score`][] from its parts (the same numbers
    as its `statistic` when given its own; other residuals or conditioned rows give
    the statistic a fit with those would)."""
    rows = np.asarray(rows, float)
    residuals = np.asarray(residuals, float)
    k = rows.shape[-1]
    offset = np.asarray(slope, float) - np.einsum("nok,no->k", rows, residuals)
    rows, curvature, offset = _pad(rows, np.asarray(curvature, float), offset)
    return np.asarray(_observed(rows, residuals, curvature, offset))[:k]


# The refit operator's unknowns are padded with zero columns to a multiple of this:
# they leave `e - basis basis^T e` unchanged, and a diagnosis after an effect is added
# (one more free unknown) runs the bootstrap compiled for the first one (it compiled
# it again, 3 s of XLA, for every effect added)
UNKNOWNS_QUANTUM = 32


def _pad_unknowns(basis) -> np.ndarray:
    """`basis` `(samples, outputs, unknowns)` with zero columns appended up to a
    multiple of [`UNKNOWNS_QUANTUM`][] unknowns."""
    basis = np.asarray(basis, float)
    u = basis.shape[-1]
    extra = -u % UNKNOWNS_QUANTUM
    return np.concatenate([basis, np.zeros(basis.shape[:-1] + (extra,))], axis=-1)


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
    rows, curvature, offset = _pad(rows, np.asarray(curvature, float), offset)
    # the innovations padded to the log's length and their number traced: one
    # compiled program whatever order the autoregression takes (the same draws)
    innovations = np.asarray(fitted.innovations, float)
    padded = np.zeros((n, innovations.shape[1]))
    padded[: len(innovations)] = innovations
    maxima = _bootstrap(
        jnp.asarray(rows),
        jnp.asarray(padded),
        jnp.asarray(len(innovations)),
        jnp.asarray(fitted.transfer(n)),
        jnp.asarray(curvature, float),
        jnp.asarray(offset),
        key,
        None if basis is None else jnp.asarray(_pad_unknowns(basis)),
        replicates=int(replicates),
        chunk=64,
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
