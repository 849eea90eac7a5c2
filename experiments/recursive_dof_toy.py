"""The least-squares band on a toy with a closed form (NumPy only).

A scalar regression `y_i = h_i theta + e_i`, `n` samples, estimated by exponentially
weighted least squares (`lam = 1` or a memory of `n / 3` samples), the bound by batch
means over blocks of `2^j` samples at the estimate with the fitted residuals' loss
solved for, the block length the longest leaving at least three effective blocks
(as `dp.RecursiveLeastSquares` does; here written out after the flight). Residuals:
first-order autoregressive (correlation time `tau` samples) or differenced white
noise low-passed (the pitch equation's residual in the short-period Monte Carlo)
plus white. For each case, over `--flights` records, two bounds:

- *before*: the fitted residuals' loss taken as `K(V) = sum_b G_b V G_b` (right
  without forgetting only), the bound of the chosen block length alone, the
  Student-t quantile at the effective number of blocks less Satterthwaite's
  centering loss; with the exact critical value of that band's statistic for
  independent Gaussian block scores under the forgetting's weights (Imhof's
  inversion; tried in the estimator and not adopted, see docs/guides/recursive.md);
- *now* (the estimator's): the loss `(2 cross - 1) K(V)`, `cross` from the
  forgetting's weights (exact for independent blocks), and the bound extrapolated
  in one over the block length over the ladder, `V(b) + (V(b/2) - V(b/4)) / 2`,
  the Student-t quantile at the effective number of blocks less Satterthwaite's
  loss of that extrapolated, centered quadratic form.

Printed: the scatter of the estimates over the band's root mean square, the degrees
of freedom, and the coverage of the 95% bands.

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
    """The estimator's centering loss before: effective blocks less
    Satterthwaite's count of the centered sum of squares."""
    n, total = len(g), g.sum()
    btb = np.eye(n) - (g[:, None] + g[None, :]) / total + (g**2).sum() / total**2
    nu = (np.diag(btb) * v).sum() ** 2 / (btb**2 * v[:, None] * v[None, :]).sum()
    return v.sum() ** 2 / (v**2).sum() - nu


def cross_factor(g, v):
    """How much more the error shares with each block than `K(V)` says."""
    return (g @ v / (g.sum() * v.sum())) / ((g**2).sum() / g.sum() ** 2)


def extrapolated_share(lam, size, count, levels=((8, 1.0), (2, 0.25), (1, -0.25))):
    """The effective blocks of `size` less Satterthwaite's count of `V(b) + (V(b/2)
    - V(b/4)) / 2`, each level centered and scaled by its expected share, as a
    quadratic form in the scores of the blocks of `size / 4` (aggregation
    matrices written out)."""
    fine = size // levels[0][0]
    partial, full = count % fine, count // fine
    start = np.concatenate([[0], partial + np.arange(full) * fine])
    length = np.concatenate([[partial], np.full(full, fine)])
    pos = np.concatenate([[full], full - 1 - np.arange(full)])
    keep = length > 0
    g = (lam**start * (1 - lam**length) / (1 - lam) if lam < 1 else length * 1.0)[keep]
    v = (
        lam ** (2 * start) * (1 - lam ** (2 * length)) / (1 - lam**2)
        if lam < 1
        else length * 1.0
    )[keep]
    pos = pos[keep]
    form = np.zeros((len(g), len(g)))
    for group, coef in levels:
        ids = np.unique(pos // group)
        agg = (pos[None, :] // group == ids[:, None]).astype(float)  # (blocks, fine)
        gl, vl = agg @ g, agg @ v
        scale = (
            1 - 2 * (gl @ vl) / (gl.sum() * vl.sum()) + (gl**2).sum() / gl.sum() ** 2
        )
        b = agg - np.outer(gl / gl.sum(), np.ones(len(g)))
        form += coef * b.T @ b / scale
        if group == levels[0][0]:
            blocks = vl.sum() ** 2 / (vl**2).sum()
    a = form * v[None, :]
    return np.trace(a) ** 2 / np.trace(a @ a) / blocks


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
    before, now, usable = [], [], []
    for j in range(levels):
        size = 2**j
        nb = -(-n // size)
        pad = nb * size - n  # blocks counted from the first sample, the last partial

        ub, gb, cb = (block_sums(x, nb, size, pad) for x in (w * s, w * gi, w**2 * gi))
        kk = p**2 * (gb**2).sum()
        cross = cross_factor(*geometry(lam, size, n, seen=nb))
        with np.errstate(divide="ignore", invalid="ignore"):  # one block: no bound
            before.append(p**2 * (ub**2).sum(1) / (1 - kk))
            now.append(p**2 * (ub**2).sum(1) / (1 - (2 * cross - 1) * kk))
        kish = cb.sum() ** 2 / (cb**2).sum()
        if kish >= 3:
            usable.append((j, kish))
    j, kish = usable[-1]
    size = 2**j
    g, v = geometry(lam, size, n)
    var_before = before[j]
    var_now = now[j] + 0.25 * (now[j - 2] - now[j - 3])
    var_now = np.where(var_now > 0, var_now, now[j])
    dof_before = kish - satterthwaite_loss(g, v)
    dof_now = kish * extrapolated_share(lam, size, n)
    c = critical(g, v)
    nu = scipy.optimize.brentq(lambda d: scipy.stats.t.ppf(0.975, d) - c, 0.3, 1e6)
    dof_exact = kish - (v.sum() ** 2 / (v**2).sum() - nu)
    rows = []
    for var, dof in (
        (var_before, dof_before),
        (var_before, dof_exact),
        (var_now, dof_now),
    ):
        band = np.sqrt(var) * scipy.stats.t.ppf(0.975, dof)
        rows.append(
            (err.std() / np.sqrt(var.mean()), dof, np.mean(np.abs(err) <= band))
        )
    return size, kish, rows


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--flights", type=int, default=4000)
    parser.add_argument("--samples", type=int, default=1500)
    args = parser.parse_args()
    rng = np.random.default_rng(1)
    n = args.samples
    print(
        "memory | residual | regressor | block | blocks | scatter/band before, now | "
        "dof before, exact, now | coverage before, exact critical value, now"
    )
    for lam in (1.0, 1 - 3.0 / n):
        for residual in (("ar1", 1e-3), ("ar1", 5.0), ("ar1", 15.0), ("diff", 3.0)):
            for regressor in ("constant", "oscillation"):
                size, kish, rows = case(rng, args.flights, n, lam, residual, regressor)
                (r0, d0, c0), (_, d1, c1), (r2, d2, c2) = rows
                memory = "all" if lam == 1.0 else f"{1 / (1 - lam):.0f}"
                print(
                    f"{memory} | {residual[0]} {residual[1]:g} | {regressor} | {size} | "
                    f"{kish:.2f} | {r0:.3f}, {r2:.3f} | {d0:.2f}, {d1:.2f}, {d2:.2f} | "
                    f"{100 * c0:.1f}, {100 * c1:.1f}, {100 * c2:.1f}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
