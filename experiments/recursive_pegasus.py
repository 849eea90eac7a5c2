"""Pegasus's derivatives tracked through the whole ascent in one pass.

Simulates the reference flight (the simulator's truth in the log), then runs the
recursive estimators over it sample by sample, as a flight computer would: `CL`,
`CD`, `CM` reconstructed from the measurements, each regressed on `[1, alpha, de]`
(recursive least squares with a forgetting memory, and the recursive Fourier
transform with the same memory). Compares every derivative with the truth and with
the windowed batch least squares of `estimate lse` (0.5 s windows), and counts how
often each 95% band holds the truth, three ways:

- against the current truth with the band as the estimator gives it (noise only);
- against what the estimator estimates: its estimate from the noise-free
  regressands `y_i = h_i theta_i` of the truth (the intercepts held), the truth
  averaged over the memory as the estimator weights it; this asks whether the band
  covers the noise;
- against the current truth with the lag's bias bound added: the bias of a linear
  drift `theta'` is `-A theta'`, `A = t_k I - N^-1 B` the lag matrix (s): for least
  squares `N = sum_i w_i h_i^T h_i`, `B = sum_i w_i h_i^T h_i t_i`; for the Fourier
  transform `N = sum_f Re(X_f^H X_f)`, `B = sum_f Re(X_f^H X_f[t])` with `X_f` the
  forgetting-weighted transform of the regressors and `X_f[t]` that of `h_i t_i`
  (per equation: the regression's equations have separate parameters, so their
  weights do not enter, to their drift), and `theta'` the slope of the estimates
  themselves (exponentially weighted, causal) over the last memory, or over a
  baseline as long as each estimate's own lag `A_aa`;
- where the lag is at most 1.5, 2 or 4 memories ("not identifiable now"
  elsewhere): the fraction of samples given a band and the coverage there;
- least squares only: with the estimates' errors-in-variables bias removed (the
  noise of the measured alpha and elevator, variances from the channels
  themselves), and the coverage by how small the regressors' noise is against
  their own variation over the memory.

`--generator independent` flies tests/independent_generator.py instead (no shared
code; the truth is the local derivative of its coefficients); `--intercept-drift`
adds a column `t - t0` per equation (each intercept drifting linearly); `--cache
DIR` keeps the replays.

Run: `python experiments/recursive_pegasus.py [--seed 1] [--memory 1.0] [--out DIR]`
(and the options above);
the last stdout line is the JSON summary (also DIR/summary.json); DIR/tracking.png is
the figure.
"""

import argparse
import json
import pathlib
import time

import jax
import matplotlib
import scipy.signal


matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import diffpegasus as dp  # noqa: E402
from diffpegasus._estimate._recursive import forgetting_for, Regression  # noqa: E402


IGNITION = 5.0  # s: before it the elevator does not move and nothing is identifiable
DERIVATIVES = ("CLa", "CLde", "CDa", "CDde", "CMa", "CMde")
DEG = np.pi / 180.0


def memory_view(label, reg, t, lam, freqs, truth9):
    """What the estimator sees of a changing truth, at every sample: the lag
    matrix `A` `(n, 9, 9)` (s; the bias of a linear drift `theta'` is `-A
    theta'`), and the estimand `(n, 9)`: its estimate from the noise-free
    regressands `y_i = h_i theta_i` of the truth `truth9` `(n, 9)` (the weighted
    average of the truth over the memory; see the module docstring)."""
    h = np.asarray(reg.h)  # (n, 3, p), each equation on its own p / 3 columns
    n, _, p = h.shape
    m = p // 3
    tt = t - t[0]
    amat = np.zeros((n, p, p))
    target = np.zeros((n, p))
    for eq in range(3):
        cols = slice(m * eq, m * eq + m)
        r = h[:, eq, cols]  # (n, 3)
        yt = np.einsum("ka,ka->k", r, truth9[:, cols])
        if label == "rls":
            low = lambda x: scipy.signal.lfilter([1.0], [1.0, -lam], x, axis=0)  # noqa: E731
            rr = np.einsum("ka,kb->kab", r, r)
            norm, timed = low(rr), low(rr * tt[:, None, None])
            rhs = low(r * yt[:, None])
        else:
            norm, timed = np.zeros((n, m, m)), np.zeros((n, m, m))
            rhs = np.zeros((n, m))
            for f in freqs:
                rot = lam * np.exp(-2j * np.pi * f * (t[1] - t[0]))
                low = lambda x, rot=rot: scipy.signal.lfilter(  # noqa: E731
                    [1.0], [1.0, -rot], x + 0j, axis=0
                )
                x, xt, xy = low(r), low(r * tt[:, None]), low(yt)
                norm += np.real(np.einsum("ka,kb->kab", x.conj(), x))
                timed += np.real(np.einsum("ka,kb->kab", x.conj(), xt))
                rhs += np.real(x.conj() * xy[:, None])
        ridge = (1e-12 * np.trace(norm, axis1=1, axis2=2) + 1e-300)[:, None, None]
        norm = norm + ridge * np.eye(m)
        amat[:, cols, cols] = tt[:, None, None] * np.eye(m) - np.linalg.solve(
            norm, timed
        )
        target[:, cols] = np.linalg.solve(norm, rhs[..., None])[..., 0]
    return amat, target


def noise_variance(x):
    """The white noise variance of a channel sampled much faster than it moves:
    half the variance of its sample-to-sample differences, from their median
    absolute deviation (robust to the elevator's steps)."""
    d = np.diff(np.asarray(x))
    mad = np.median(np.abs(d - np.median(d)))
    return (1.4826 * mad) ** 2 / 2.0


def errors_in_variables_bias(reg, channels, lam, theta):
    """The bias `(n, p)` of least squares from the noise in its regressors (the
    measured alpha and elevator), at every sample, to first order: `N^-1 sum_i
    w_i (E[h~_i y~_i] - E[h~_i h~_i^T] theta)`, `N = sum_i w_i h_i^T h_i` per
    equation. The noise variances come from the channels themselves
    ([`noise_variance`][]); `y~` shares alpha's noise through the rotation to the
    wind axes (`dCL/dalpha = -CD`, `dCD/dalpha = CL` at fixed body-axis
    coefficients; `CM` does not involve alpha)."""
    h = np.asarray(reg.h)
    y = np.asarray(reg.y)
    n, _, p = h.shape
    m = p // 3
    var_a = noise_variance(channels["alpha"])
    var_e = noise_variance(channels["de"])
    low = lambda x: scipy.signal.lfilter([1.0], [1.0, -lam], x, axis=0)  # noqa: E731
    shared = {0: -y[:, 1], 1: y[:, 0], 2: np.zeros(n)}  # d y_eq / d alpha
    out = np.zeros((n, p))
    ratio = np.zeros((n, p))  # noise variance over the regressor's own, per column
    for eq in range(3):
        cols = slice(m * eq, m * eq + m)
        names = reg.parameters[cols]
        ia = next(i for i, c in enumerate(names) if c.endswith("a"))
        ie = next(i for i, c in enumerate(names) if c.endswith("de"))
        r = h[:, eq, cols]
        norm = low(np.einsum("ka,kb->kab", r, r))
        norm = norm + (1e-12 * np.trace(norm, axis1=1, axis2=2) + 1e-300)[
            :, None, None
        ] * np.eye(m)
        nw = low(np.ones(n))
        vec = np.zeros((n, m))
        vec[:, ia] = var_a * (low(shared[eq]) - nw * theta[:, cols][:, ia])
        vec[:, ie] = -var_e * nw * theta[:, cols][:, ie]
        out[:, cols] = np.linalg.solve(norm, vec[..., None])[..., 0]
        inv = np.linalg.inv(norm)
        ratio[:, m * eq + ia] = var_a * nw * inv[:, ia, ia]
        ratio[:, m * eq + ie] = var_e * nw * inv[:, ie, ie]
    return out, ratio, var_a, var_e


NOISE_RATIOS = (0.01, 0.03, 0.1, 0.3)  # regressor noise over its variance
REPORT_RATIOS = (1.5, 2.0, 4.0)  # lag over memory up to which a band is reported
BASELINES = 2.0 ** np.arange(7)  # the drift's baselines, memories (1 to 64)


def weighted_slope(t, x, lam):
    """The slope `(n, ...)` of `x` against `t`, exponentially weighted
    (`lam` per sample), causal: `cov_w(t, x) / var_w(t)`."""
    tc = (t - t.mean()).reshape((-1,) + (1,) * (x.ndim - 1))
    filt = lambda v: scipy.signal.lfilter([1.0], [1.0, -lam], v, axis=0)  # noqa: E731
    sw, st_, stt = filt(np.ones_like(tc)), filt(tc), filt(tc**2)
    sx, stx = filt(x), filt(tc * x)
    return (sw * stx - st_ * sx) / np.maximum(sw * stt - st_**2, 1e-300)


def long_baseline_bias(t, theta, amat, memory):
    """The lag's bias `(n, p)`, `-A theta'`, with the drift `theta'` the slope
    of the estimates over a baseline as long as each parameter's own lag
    `A_aa` (the span its estimate averages; at least the memory): per row `a`
    the slopes of every estimate over the baseline of the ladder
    `memory * BASELINES` nearest above `A_aa`."""
    dt = t[1] - t[0]
    slopes = np.stack(
        [weighted_slope(t, theta, np.exp(-dt / (b * memory))) for b in BASELINES]
    )  # (baselines, n, p)
    lag = np.einsum("kaa->ka", amat)
    pick = np.clip(
        np.ceil(np.log2(np.maximum(lag / memory, 1.0))), 0, len(BASELINES) - 1
    ).astype(int)  # (n, p)
    n, p = lag.shape
    # row a of A against the slopes of every parameter over row a's baseline
    chosen = slopes[pick, np.arange(n)[:, None]]  # (n, p_rows, p_cols)
    return -np.einsum("kab,kab->ka", amat, chosen)


def with_drifting_intercepts(reg, t):
    """The regression with each equation's intercept drifting linearly in
    time: `[1, t - t0, alpha, de]` per equation (twelve parameters; the drift
    rates named `CL0t`, `CD0t`, `CM0t`, 1/s)."""
    h = np.asarray(reg.h)
    n = h.shape[0]
    out = np.zeros((n, 3, 12))
    names = []
    for eq, c in enumerate("LDM"):
        out[:, eq, 4 * eq] = h[:, eq, 3 * eq]
        out[:, eq, 4 * eq + 1] = (t - t[0]) * h[:, eq, 3 * eq]
        out[:, eq, 4 * eq + 2 : 4 * eq + 4] = h[:, eq, 3 * eq + 1 : 3 * eq + 3]
        names += [f"C{c}0", f"C{c}0t", f"C{c}a", f"C{c}de"]
    return Regression(
        h=out,
        y=reg.y,
        o=reg.o,
        derivative=reg.derivative,
        equations=reg.equations,
        parameters=tuple(names),
        index=tuple(range(12)),
    )


def independent_flight(seed, duration):
    """A flight of the independent generator (tests/independent_generator.py:
    no diffpegasus code, its own aerodynamic table non-linear in alpha with an
    alpha-elevator cross term): `(t, channels, s_ref, c_ref, truth (n, 6))`, the
    truth the local derivatives (1/rad) of its coefficients at the noise-free
    alpha, elevator and Mach number, by central differences."""
    import sys

    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
    from tests import independent_generator as ig

    channels, meta = ig.generate(seed, 1000.0, duration)
    clean, _ = ig.generate(seed, 1000.0, duration, noise=False)
    a, de, mach = clean["alpha"], clean["de"], clean["mach"]
    step = 1e-6
    up_a, dn_a = (
        ig.coefficients(a + step, de, mach),
        ig.coefficients(a - step, de, mach),
    )
    up_e, dn_e = (
        ig.coefficients(a, de + step, mach),
        ig.coefficients(a, de - step, mach),
    )
    truth = []
    for k in range(3):  # CL, CD, CM: alpha then elevator
        truth += [(up_a[k] - dn_a[k]) / (2 * step), (up_e[k] - dn_e[k]) / (2 * step)]
    return channels["t"], channels, meta["S_ref"], meta["c_ref"], np.column_stack(truth)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--memory", type=float, default=1.0, help="s")
    parser.add_argument(
        "--generator",
        choices=("package", "independent"),
        default="package",
        help="the package's simulator (80 s ascent) or the independent generator",
    )
    parser.add_argument(
        "--duration", type=float, default=30.0, help="s (independent generator)"
    )
    parser.add_argument(
        "--intercept-drift",
        action="store_true",
        help="each intercept drifts linearly in time (a column t - t0 per equation)",
    )
    parser.add_argument(
        "--cache", type=pathlib.Path, default=None, help="keep the replays here"
    )
    parser.add_argument(
        "--methods", default="rls,rft", help="comma-separated: rls, rft"
    )
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/recursive_pegasus")
    )
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    if args.generator == "package":
        flight = dp.pegasus.simulate(
            dp.pegasus.PegasusConfig(), jax.random.key(args.seed)
        )
        log = dp.pegasus.flight_to_log(flight, {"seed": args.seed})
        channels, s_ref, c_ref = log.channels, log.s_ref, log.c_ref
        t = np.asarray(log.t)
        truth = np.column_stack([np.asarray(log[f"true_{n}"]) for n in DERIVATIVES])
    else:
        t, channels, s_ref, c_ref, truth = independent_flight(args.seed, args.duration)
        log = None
    dt = float(t[1] - t[0])
    reg = dp.pegasus.coefficient_regression(channels, s_ref, c_ref)
    if args.intercept_drift:
        reg = with_drifting_intercepts(reg, t)
    lam = forgetting_for(args.memory, dt)
    # the Fourier estimator's frequencies: what the memory resolves (1 / memory
    # apart) up to the elevator's bandwidth (5 Hz, well under Nyquist)
    step = 1.0 / args.memory
    freqs = tuple(float(f) for f in np.arange(step, 5.0 + 1e-9, step))
    estimators = {
        "rls": dp.RecursiveLeastSquares(
            forgetting=lam, derivative=reg.derivative, dt=dt
        ),
        "rft": dp.RecursiveFourier(
            frequencies=freqs, forgetting=lam, derivative=reg.derivative, dt=dt
        ),
    }
    estimators = {k: v for k, v in estimators.items() if k in args.methods.split(",")}
    cols = [reg.parameters.index(n) for n in DERIVATIVES]
    after = t >= IGNITION
    summary = {
        "generator": args.generator,
        "seed": args.seed,
        "memory_s": args.memory,
        "forgetting": lam,
        "sample_rate_hz": 1.0 / dt,
        "rft_frequencies_hz": [freqs[0], freqs[-1], step],
        "from_s": IGNITION,
        "units": "1/deg",
        "methods": {},
    }
    if log is not None:
        lse = dp.pegasus.estimate_lse(log)
        lse_mid = 0.5 * (np.asarray(lse.window_start) + np.asarray(lse.window_end))
        lse_vals = np.asarray(lse.values)
        lse_ok = np.asarray(lse.valid) & (lse_mid >= IGNITION)
        lse_truth = np.asarray(lse.truth)
        summary["lse_0.5s"] = {
            "mse": {
                n: float(np.mean(((lse_vals - lse_truth)[lse_ok, j] * DEG) ** 2))
                for j, n in enumerate(DERIVATIVES)
            },
            "windows": int(lse_ok.sum()),
        }
    histories = {}
    grid = np.arange(len(t))
    sel = after[grid]
    for label, est in estimators.items():
        start = time.perf_counter()
        drift = "_drift" if args.intercept_drift else ""
        name = f"{args.generator}_{args.seed}_{args.memory:g}{drift}_{label}.npz"
        cached = args.cache / name if args.cache else None
        if cached is not None and cached.exists():
            hist = dict(np.load(cached))
        else:
            p = reg.h.shape[-1]
            out = dp.replay(est, reg.h, reg.y, reg.o, np.zeros(p), float(t[0]))
            hist = {
                k: np.asarray(getattr(out, k)) for k in ("theta", "stderr", "halfwidth")
            }
            if cached is not None:
                args.cache.mkdir(parents=True, exist_ok=True)
                np.savez(cached, **hist)
        theta = hist["theta"][:, cols]
        elapsed = time.perf_counter() - start
        sd_white = hist["stderr"][:, cols]
        # the estimator's own 95% band (Student-t at its dof)
        half = hist["halfwidth"][:, cols]
        histories[label] = (theta, half)
        err = (theta - truth)[after]
        # the truth with the intercepts held (they carry the trim, not tracked)
        truth9 = np.zeros((len(t), reg.h.shape[-1]))
        truth9[:, [reg.parameters.index(n) for n in DERIVATIVES]] = truth
        amat, target = memory_view(label, reg, t, lam, freqs, truth9)
        amat, target = amat[grid], target[grid][:, cols]
        lag = np.einsum("kaa->ka", amat)[:, cols]
        # the estimates' own slope over the last memory (weighted like the
        # estimator's memory, causal): cov_w(t, theta) / var_w(t)
        # (no estimate yet before the transforms hold data: taken as zero)
        th_all = np.nan_to_num(hist["theta"])
        tc = (t - t.mean())[:, None]
        filt = lambda x: scipy.signal.lfilter([1.0], [1.0, -lam], x, axis=0)  # noqa: E731
        sw, st_, stt = filt(np.ones_like(tc)), filt(tc), filt(tc**2)
        sth, stth = filt(th_all), filt(tc * th_all)
        slope = (sw * stth - st_ * sth) / np.maximum(sw * stt - st_**2, 1e-300)
        bias = np.abs(np.einsum("kab,kb->ka", amat, slope[grid]))[:, cols]
        truth_lagged = target
        hg, thg = half[grid], theta[grid]
        # the drift from a longer baseline: the estimates' slope over their own
        # lag (the span the estimate averages), not over the memory
        bias_long = np.abs(long_baseline_bias(t, th_all, amat, args.memory))[:, cols]
        # "not identifiable now": the estimate's information older on average
        # than `ratio` memories (its lag A_aa); those samples get no band
        reported = {ratio: lag[sel] <= ratio * args.memory for ratio in REPORT_RATIOS}
        miss = np.abs(thg - truth[grid])[sel]
        ok_long = miss <= (hg + bias_long)[sel]
        ok_short = miss <= (hg + bias)[sel]
        if label == "rls":
            # the regressors' noise: a bias, not scatter, where the regressor
            # hardly moves over the memory (attenuation, and CD's regressand
            # sharing alpha's noise through the wind-axis rotation)
            eiv, ratio, var_a, var_e = errors_in_variables_bias(
                reg, channels, lam, th_all
            )
            eiv, ratio = eiv[grid][:, cols], ratio[grid][:, cols][sel]
            miss_c = np.abs(thg - eiv - truth[grid])[sel]
            extra = {
                "noise_sd_alpha_de_rad": [float(np.sqrt(var_a)), float(np.sqrt(var_e))],
                "median_eiv_bias_per_deg": {
                    n: float(np.median(np.abs(eiv[sel, j])) * DEG)
                    for j, n in enumerate(DERIVATIVES)
                },
                "coverage_95_eiv_corrected_band_as_given": {
                    n: float(np.mean(miss_c[:, j] <= hg[sel, j]))
                    for j, n in enumerate(DERIVATIVES)
                },
                "coverage_95_eiv_corrected_with_long_baseline_lag_bias_bound": {
                    n: float(np.mean(miss_c[:, j] <= (hg + bias_long)[sel, j]))
                    for j, n in enumerate(DERIVATIVES)
                },
                "coverage_95_eiv_corrected_against_memory_average": {
                    n: float(
                        np.mean(np.abs(thg - eiv - truth_lagged)[sel, j] <= hg[sel, j])
                    )
                    for j, n in enumerate(DERIVATIVES)
                },
                "by_noise_ratio": {
                    f"noise_variance_at_most_{lim:g}_of_the_regressors": {
                        "fraction": {
                            n: float(np.mean(ratio[:, j] <= lim))
                            for j, n in enumerate(DERIVATIVES)
                        },
                        "coverage_long_baseline": {
                            n: float(np.mean(ok_long[ratio[:, j] <= lim, j]))
                            for j, n in enumerate(DERIVATIVES)
                        },
                        "coverage_eiv_corrected_long_baseline": {
                            n: float(
                                np.mean(
                                    (miss_c[:, j] <= (hg + bias_long)[sel, j])[
                                        ratio[:, j] <= lim
                                    ]
                                )
                            )
                            for j, n in enumerate(DERIVATIVES)
                        },
                    }
                    for lim in NOISE_RATIOS
                },
                "mse_eiv_corrected": {
                    n: float(np.mean(((thg - eiv - truth[grid])[sel, j] * DEG) ** 2))
                    for j, n in enumerate(DERIVATIVES)
                },
            }
        else:
            extra = {}
        # the recursive estimate sampled at the windows' ends (what it knew then)
        # against the same window-mean truth as the batch windows
        if log is not None:
            ends = np.minimum(
                np.searchsorted(t, np.asarray(lse.window_end)) - 1, len(t) - 1
            )
            win_err = (theta[ends] - lse_truth)[lse_ok]
        else:
            win_err = np.full((1, len(DERIVATIVES)), np.nan)
        summary["methods"][label] = {
            "seconds": elapsed,
            "mse_all_samples": {
                n: float(np.mean((err[:, j] * DEG) ** 2))
                for j, n in enumerate(DERIVATIVES)
            },
            "mse_at_window_ends": {
                n: float(np.mean((win_err[:, j] * DEG) ** 2))
                for j, n in enumerate(DERIVATIVES)
            },
            "coverage_95_corrected": {
                n: float(np.mean(np.abs(err[:, j]) <= half[after, j]))
                for j, n in enumerate(DERIVATIVES)
            },
            "coverage_95_against_memory_average": {
                n: float(np.mean(np.abs(thg - truth_lagged)[sel, j] <= hg[sel, j]))
                for j, n in enumerate(DERIVATIVES)
            },
            "coverage_95_with_lag_bias_bound": {
                n: float(
                    np.mean(np.abs(thg - truth[grid])[sel, j] <= (hg + bias)[sel, j])
                )
                for j, n in enumerate(DERIVATIVES)
            },
            "coverage_95_with_long_baseline_lag_bias_bound": {
                n: float(np.mean(ok_long[:, j])) for j, n in enumerate(DERIVATIVES)
            },
            "reported": {
                f"lag_within_{ratio:g}_memories": {
                    "fraction_reported": {
                        n: float(np.mean(reported[ratio][:, j]))
                        for j, n in enumerate(DERIVATIVES)
                    },
                    "coverage_where_reported_long_baseline": {
                        n: float(np.mean(ok_long[reported[ratio][:, j], j]))
                        for j, n in enumerate(DERIVATIVES)
                    },
                    "coverage_where_reported_memory_baseline": {
                        n: float(np.mean(ok_short[reported[ratio][:, j], j]))
                        for j, n in enumerate(DERIVATIVES)
                    },
                    "coverage_where_reported_band_as_given": {
                        n: float(
                            np.mean(
                                miss[reported[ratio][:, j], j]
                                <= hg[sel][reported[ratio][:, j], j]
                            )
                        )
                        for j, n in enumerate(DERIVATIVES)
                    },
                }
                for ratio in REPORT_RATIOS
            },
            "median_long_baseline_bias_bound_per_deg": {
                n: float(np.median(bias_long[sel, j]) * DEG)
                for j, n in enumerate(DERIVATIVES)
            },
            **extra,
            "coverage_95_on_the_grid": {
                n: float(np.mean(np.abs(thg - truth[grid])[sel, j] <= hg[sel, j]))
                for j, n in enumerate(DERIVATIVES)
            },
            "median_lag_s": {
                n: float(np.median(lag[sel, j])) for j, n in enumerate(DERIVATIVES)
            },
            "median_halfwidth_per_deg": {
                n: float(np.median(hg[sel, j]) * DEG) for j, n in enumerate(DERIVATIVES)
            },
            "median_lag_bias_bound_per_deg": {
                n: float(np.median(bias[sel, j]) * DEG)
                for j, n in enumerate(DERIVATIVES)
            },
            "coverage_95_white": {
                n: float(np.mean(np.abs(err[:, j]) <= 1.96 * sd_white[after, j]))
                for j, n in enumerate(DERIVATIVES)
            },
        }
    fig, axes = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
    for j, (name, ax) in enumerate(zip(DERIVATIVES, axes.flat, strict=True)):
        ax.plot(t, truth[:, j] * DEG, "k", lw=1.2, label="truth")
        for label, colour in (("rls", "C0"), ("rft", "C2")):
            if label not in histories:
                continue
            theta, half_ = histories[label]
            ax.plot(t, theta[:, j] * DEG, colour, lw=0.8, label=label)
            ax.fill_between(
                t,
                (theta[:, j] - half_[:, j]) * DEG,
                (theta[:, j] + half_[:, j]) * DEG,
                color=colour,
                alpha=0.2,
                lw=0,
            )
        if log is not None:
            ok = lse_ok
            ax.plot(lse_mid[ok], lse_vals[ok, j] * DEG, "C3.", ms=3, label="LSE 0.5 s")
        lo, hi = np.percentile(truth[after, j] * DEG, [0, 100])
        pad = 0.5 * (hi - lo) + 0.2 * abs(hi) + 1e-4
        ax.set_ylim(lo - pad, hi + pad)
        ax.set_title(name)
        ax.set_ylabel(f"{name}, 1/deg")
        ax.axvline(IGNITION, color="0.5", lw=0.6, ls=":")
        ax.grid(True, alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time, s")
    axes[0, 0].legend(fontsize=7, ncol=2)
    fig.suptitle(f"Pegasus ascent, one pass; memory {args.memory:g} s; bands 95%")
    fig.tight_layout()
    fig.savefig(args.out / "tracking.png", dpi=110)
    plt.close(fig)
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    for label, m in summary["methods"].items():
        for key in (
            "coverage_95_corrected",
            "coverage_95_against_memory_average",
            "coverage_95_with_lag_bias_bound",
            "median_lag_s",
        ):
            print(label, key, {k: round(v, 3) for k, v in m[key].items()})
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
