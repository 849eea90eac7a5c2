"""The least-squares band's critical value on a toy with a closed form (NumPy only).

A scalar regression `y_i = h_i theta + e_i`, `n` samples, estimated by exponentially
weighted least squares (`lam = 1` or a memory of `n / 3` samples), the bound by batch
means over blocks of `2^j` samples at the estimate with the fitted residuals' loss
solved for, the block length the longest leaving at least three effective blocks
(as `dp.RecursiveLeastSquares` does; here written out after the flight). Residuals:
first-order autoregressive (correlation time `tau` samples) or differenced white
noise low-passed (the pitch equation's residual in the short-period Monte Carlo)
plus white. For each case, over `--flights` records: the scatter over the band's
root mean square, and the coverage of the 95% band with the normal quantile, with
the Student-t quantile at the effective number of blocks less Satterthwaite's
centering loss (the estimator's band), and with the exact critical value of the
band's statistic for independent Gaussian block scores under the forgetting's
weights (Imhof's inversion by adaptive quadrature; tried in the estimator and not
adopted, see docs/guides/recursive.md).

Run: `python experiments/recursive_dof_toy.py [--flights 4000]`.
"""

import argparse

import numpy as np
import scipy.integrate
import scipy.optimize
import scipy.stats


def geometry(lam, size, count, seen=64):
    """Blocks' weights `g` and variances `v` (evenly spread information),
    newest (partial) first."""
    partial, full = count % size, count // size
    m = np.arange(seen)
    start = np.concatenate([[0], partial + m * size])
    length = np.concatenate([[partial], np.where(m < full, size, 0)])

    def geo(r):
        if r == 1.0:
            return length.astype(float)
        return r**start * (1 - r**length) / (1 - r)

    keep = length > 0
    return geo(lam)[keep], geo(lam**2)[keep]


def satterthwaite_loss(g, v):
    """The estimator's centering loss: effective blocks less Satterthwaite's count
    of the centered sum of squares."""
    n, total = len(g), g.sum()
    btb = np.eye(n) - (g[:, None] + g[None, :]) / total + (g**2).sum() / total**2
    nu = (np.diag(btb) * v).sum() ** 2 / (btb**2 * v[:, None] * v[None, :]).sum()
    return v.sum() ** 2 / (v**2).sum() - nu


def critical(g, v, alpha=0.05):
    """The exact critical value: `P(e^2 (1 - k) > c^2 U^T B^T B U) = alpha`,
    eigenvalues and Imhof's formula."""
    g, v = g / g.sum(), v / v.sum()
    k, n = (g**2).sum(), len(g)
    btb = np.eye(n) - (g[:, None] + g[None, :]) + k
    a = np.sqrt(v)

    def exceed(c):
        lam = np.linalg.eigvalsh((1 - k) * np.outer(a, a) - c**2 * a[:, None] * btb * a)
        lam = lam[np.abs(lam) > 1e-13 * np.abs(lam).max()]

        def f(u):
            return np.sin(0.5 * np.arctan(2 * lam * u).sum()) / (
                u * np.prod((1 + 4 * lam**2 * u**2) ** 0.25)
            )

        val = scipy.integrate.quad(f, 0, np.inf, limit=1000, epsabs=1e-13)[0]
        return 0.5 + val / np.pi

    return scipy.optimize.brentq(lambda c: exceed(c) - alpha, 1.0, 60.0, xtol=1e-12)


def block_sums(x, nb, size, pad):
    """Sums of `x` along its last axis over `nb` blocks of `size` samples."""
    x = np.concatenate([x, np.zeros(x.shape[:-1] + (pad,))], axis=-1)
    return x.reshape(x.shape[:-1] + (nb, size)).sum(-1)


def case(rng, flights, n, lam, residual, regressor, levels=12):
    t = np.arange(n)
    if regressor == "constant":
        h = np.ones(n)
    else:  # a slow oscillation with a faster one on it
        h = np.sin(2 * np.pi * t / 400.0) + 0.3 * np.sin(2 * np.pi * t / 37.0)
    kind, tau = residual
    if kind == "ar1":
        rho = np.exp(-1.0 / tau)
        e = rng.normal(size=(flights, n))
        e[:, 1:] *= np.sqrt(1 - rho**2)
        for k in range(1, n):
            e[:, k] += rho * e[:, k - 1]
    else:  # differenced white noise through a first-order low-pass of tau samples, plus white
        x = rng.normal(size=(flights, n + 1))
        d = np.diff(x, axis=1)
        r = np.exp(-1.0 / tau)
        for k in range(1, n):
            d[:, k] = r * d[:, k - 1] + (1 - r) * d[:, k]
        e = 4.0 * d + 0.3 * rng.normal(size=(flights, n))
    w = lam ** (n - 1 - t)
    gi = h * h
    p = 1 / np.sum(w * gi)
    err = p * np.sum(w * h * e, axis=1)
    s = h * e - gi * err[:, None]  # scores at the estimate
    best = None
    for j in range(levels):
        size = 2**j
        nb = -(-n // size)
        pad = nb * size - n  # blocks counted from the first sample, the last partial

        ub, gb, cb = (block_sums(x, nb, size, pad) for x in (w * s, w * gi, w**2 * gi))
        kish = cb.sum() ** 2 / (cb**2).sum()
        if kish < 3:
            break
        var = p**2 * (ub**2).sum(1) / (1 - p**2 * (gb**2).sum())
        best = (size, var, kish)
    size, var, kish = best
    g, v = geometry(lam, size, n)
    old = scipy.stats.t.ppf(0.975, kish - satterthwaite_loss(g, v))
    # the exact count: the effective blocks less (the geometry's count less the
    # degrees of freedom whose t quantile is the exact critical value)
    c = critical(g, v)
    nu = scipy.optimize.brentq(lambda d: scipy.stats.t.ppf(0.975, d) - c, 0.3, 1e6)
    new = scipy.stats.t.ppf(0.975, kish - (v.sum() ** 2 / (v**2).sum() - nu))
    band = np.sqrt(var)
    cover = [np.mean(np.abs(err) <= q * band) for q in (1.959964, old, new)]
    return size, kish, old, new, err.std() / np.sqrt(var.mean()), cover


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--flights", type=int, default=4000)
    parser.add_argument("--samples", type=int, default=1500)
    args = parser.parse_args()
    rng = np.random.default_rng(1)
    n = args.samples
    print(
        "memory | residual | regressor | block | blocks | t (estimator) | exact | "
        "scatter/band | coverage normal, estimator, exact"
    )
    for lam in (1.0, 1 - 3.0 / n):
        for residual in (("ar1", 1e-3), ("ar1", 5.0), ("ar1", 15.0), ("diff", 3.0)):
            for regressor in ("constant", "oscillation"):
                size, kish, old, new, ratio, cover = case(
                    rng, args.flights, n, lam, residual, regressor
                )
                memory = "all" if lam == 1.0 else f"{1 / (1 - lam):.0f}"
                print(
                    f"{memory} | {residual[0]} {residual[1]:g} | {regressor} | {size} | "
                    f"{kish:.2f} | {old:.3f} | {new:.3f} | {ratio:.3f} | "
                    + ", ".join(f"{100 * x:.1f}" for x in cover),
                    flush=True,
                )


if __name__ == "__main__":
    main()
