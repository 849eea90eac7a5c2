"""What the experiments and the tests share: where the validation data of
`shared/data/` lives (the repository is checked out beside a `shared/` folder;
`DIFFPEGASUS_SHARED`, the path of that folder, overrides the search), and the
simulated flights both use.
"""

import os
import pathlib

import numpy as np
import scipy.linalg
import scipy.signal


def shared_data(relative: str) -> pathlib.Path:
    """Path of `shared/data/<relative>`; the first candidate that exists, else the
    conventional location (so the error message names it)."""
    here = pathlib.Path(__file__).resolve()
    candidates = []
    if os.environ.get("DIFFPEGASUS_SHARED"):
        candidates.append(
            pathlib.Path(os.environ["DIFFPEGASUS_SHARED"]) / "data" / relative
        )
    candidates += [p / "shared" / "data" / relative for p in here.parents]
    for c in candidates:
        if c.exists():
            return c
    return here.parents[2] / "shared" / "data" / relative


# ATTAS-like lateral manoeuvres: the book's derivatives (1/s, 1/rad), simulated
# independently of the package (matrix exponential, inputs linear between samples)
ATTAS = dict(
    Lp=-2.5, Lr=0.6, Lda=-8.0, Ldr=0.6, Lbeta=-6.0,
    Np=-0.1, Nr=-0.4, Nda=-0.3, Ndr=-2.0, Nbeta=2.2,
    Yp=0.4, Yr=1.5, Yda=-0.5, Ydr=4.0, Ybeta=-20.0,
)  # fmt: skip
ATTAS_NOISE = np.array([0.02, 0.01, 0.05, 0.002, 0.002])  # pdot, rdot, ay, p, r


def attas_like(seed=3, duration=25.0, rate=25.0):
    """Aileron and rudder doublets; the sideslip a first-order (1.2 s) response to
    the rudder; outputs pdot, rdot, ay, p, r with white noise ([`ATTAS_NOISE`][]).

    **Returns:** `t` `(n,)` s, inputs `(n, 3)` (aileron, rudder, sideslip; rad),
    outputs `(n, 5)`.
    """
    dt = 1.0 / rate
    t = np.arange(0.0, duration + 0.5 * dt, dt)

    def doublet(start, width, amp):
        return amp * (((t >= start) & (t < start + width)) * 1.0
                      - ((t >= start + width) & (t < start + 2 * width)))  # fmt: skip

    da = doublet(1.0, 1.0, 0.03) + doublet(12.0, 0.6, -0.02)
    dr = doublet(5.0, 1.5, 0.03) + doublet(17.0, 0.8, 0.02)
    beta = scipy.signal.lfilter([dt / 1.2], [1, dt / 1.2 - 1], -0.5 * dr)
    u = np.column_stack([da, dr, beta])
    p = ATTAS
    a = np.array([[p["Lp"], p["Lr"]], [p["Np"], p["Nr"]]])
    b = np.array([[p["Lda"], p["Ldr"], p["Lbeta"]], [p["Nda"], p["Ndr"], p["Nbeta"]]])
    f = np.zeros((8, 8))
    f[:2, :2], f[:2, 2:5], f[2:5, 5:8] = a, b, np.eye(3)
    e = scipy.linalg.expm(f * dt)
    phi, g1, g2 = e[:2, :2], e[:2, 2:5], e[:2, 5:8] / dt
    x = np.zeros((len(t), 2))
    for k in range(len(t) - 1):
        x[k + 1] = phi @ x[k] + (g1 - g2) @ u[k] + g2 @ u[k + 1]
    c = np.array([[p["Yp"], p["Yr"]]])
    dy = np.array([[p["Yda"], p["Ydr"], p["Ybeta"]]])
    y = np.column_stack([x @ a.T + u @ b.T, x @ c.T + u @ dy.T, x])
    y = y + np.random.default_rng(seed).normal(size=y.shape) * ATTAS_NOISE
    return t, u, y


def segment_projection(n: int, outputs: int, segments: int = 10):
    """A linear problem shaped like a multiple-shooting fit's free unknowns: a
    constant and a slope on each of `segments` equal segments of each output, over
    `n` samples. Returns `(t, basis, refit)`: `t` `(n,)` on [0, 1]; `basis` `(n,
    outputs, unknowns)` orthonormal (as a score test's refit operator); `refit(v)`
    the residual `(n, outputs)` a least-squares fit of those unknowns leaves of
    `v`."""
    t = np.linspace(0.0, 1.0, n)
    cols = []
    for c in range(outputs):
        for s in range(segments):
            sel = (t >= s / segments) & (t < (s + 1) / segments + (s == segments - 1))
            for f in (np.ones(n), t - (s + 0.5) / segments):
                x = np.zeros((n, outputs))
                x[sel, c] = f[sel]
                cols.append(x)
    q, _ = np.linalg.qr(np.stack(cols, -1).reshape(n * outputs, -1))

    def refit(v):
        return v - (q @ (q.T @ v.reshape(-1))).reshape(n, outputs)

    return t, q.reshape(n, outputs, -1), refit


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


def _yule_walker(e: np.ndarray, orders: np.ndarray) -> np.ndarray:
    """Each channel's autoregression of `e` `(samples, channels)` at its own
    order, by Yule-Walker: `(max order, channels)`, zero beyond a channel's
    order."""
    n, c = e.shape
    e = e - e.mean(axis=0)
    top = int(max(orders.max(initial=0), 0))
    out = np.zeros((top, c))
    if top == 0:
        return out
    gamma = np.fft.irfft(np.abs(np.fft.rfft(e, n=2 * n, axis=0)) ** 2, axis=0)
    for ch, p in enumerate(orders):
        g = gamma[: p + 1, ch]
        if p > 0 and g[0] > 0:
            out[:p, ch] = scipy.linalg.solve_toeplitz(g[:p], g[1 : p + 1])
    return out


def _stable(a: np.ndarray, n: int) -> bool:
    # every channel's filter 1 - sum a_j z^j with its roots outside the circle of
    # radius 1 / (1 - 1/n): no mode remembers longer than the record is long
    for col in a.T:
        if np.any(col != 0.0):
            roots = np.roots(np.concatenate([-col[::-1], [1.0]]))
            if np.any(np.abs(roots) * (1.0 - 1.0 / n) <= 1.0):
                return False
    return True


def refitted_sieve(
    fitted,
    basis: np.ndarray,
    *,
    draws: int = 16,
    rounds: int = 6,
    seed: int = 0,
):
    """The autoregression whose series, **once refitted** as the fit's residuals
    were (`e - basis basis^T e`), has the autoregression `fitted` found in them.

    A fit takes its free unknowns' share out of its residuals (for shooting
    nodes, a level and a slope per segment): the colour that share carried is
    gone from the residuals, so an autoregression fitted to them is whiter than
    the noise (an AR(1) of 0.9 reads 0.75 from a fit of a level and a slope per
    40 samples), and a replicate drawn from it and refitted again whiter still
    (0.63): its null is too light. Here the coefficients are moved until the
    replicates, refitted, read what the log's residuals read (indirect
    inference: each round, `draws` series filtered from the innovations, refitted,
    Yule-Walker at each channel's order; the coefficients moved by the
    difference, halved while the filter is not stable). The innovations stay
    those of `fitted` (each replicate is whitened again after its refit: their
    scale does not matter).

    Not used by the package's rule (measured in the decision-rule validation
    page): on the linear problem of `experiments/decision_rule.py --part colour`
    it brings the false alarms at AR(0.9) from 18 to 11 of 150, but on the real
    HFB-320 record with its pitch damping removed a channel's residuals are near a
    unit root (coefficients summing to 0.994), where a small move of the
    coefficients is a large change of the long-run variance, and the threshold
    rose from 133 to 540-3000 (one round to six), hiding an effect that explains
    91% of det(R)."""
    from diffpegasus._diagnose._calibration import Sieve

    a_obs = np.einsum("jcc->jc", np.asarray(fitted.coefficients))
    if a_obs.shape[0] == 0:
        return fitted
    orders = np.array(
        [
            (np.flatnonzero(a_obs[:, ch])[-1] + 1) if np.any(a_obs[:, ch]) else 0
            for ch in range(a_obs.shape[1])
        ]
    )
    basis = np.asarray(basis, float)
    n = basis.shape[0]
    u = np.asarray(fitted.innovations)
    rng = np.random.default_rng(seed)
    a = a_obs.copy()

    def read(a):
        filt = Sieve(order=fitted.order, coefficients=_diag(a), innovations=u)
        h = filt.transfer(n)
        found = []
        for _ in range(draws):
            w = np.fft.rfft(u[rng.integers(0, u.shape[0], n)], axis=0)
            e = np.fft.irfft(np.einsum("fab,fb->fa", h, w), n=n, axis=0)
            e = e - np.einsum("nou,u->no", basis, np.einsum("nou,no->u", basis, e))
            found.append(_yule_walker(e, orders))
        return np.mean(found, axis=0)

    for _ in range(rounds):
        step = a_obs - read(a)
        while True:
            trial = a + step
            if _stable(trial, n):
                break
            step = 0.5 * step
            if np.max(np.abs(step)) < 1e-6:
                trial = a
                break
        a = trial
    return Sieve(order=fitted.order, coefficients=_diag(a), innovations=u)


def _diag(a: np.ndarray) -> np.ndarray:
    # (order, channels) -> (order, channels, channels), each channel its own filter
    out = np.zeros((a.shape[0], a.shape[1], a.shape[1]))
    idx = np.arange(a.shape[1])
    out[:, idx, idx] = a
    return out
