"""Pegasus's derivatives tracked through the whole ascent in one pass.

Simulates the reference flight (the simulator's truth in the log), then runs the
recursive estimators over it sample by sample, as a flight computer would: `CL`,
`CD`, `CM` reconstructed from the measurements, each regressed on `[1, alpha, de]`
(recursive least squares with a forgetting memory, and the recursive Fourier
transform with the same memory). Compares every derivative with the truth and with
the windowed batch least squares of `estimate lse` (0.5 s windows), and counts how
often each 95% band holds the truth.

Run: `python experiments/recursive_pegasus.py [--seed 1] [--memory 1.0] [--out DIR]`;
the last stdout line is the JSON summary (also DIR/summary.json); DIR/tracking.png is
the figure.
"""

import argparse
import json
import pathlib
import time

import jax
import matplotlib


matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import diffpegasus as dp  # noqa: E402
from diffpegasus._estimate._recursive import forgetting_for  # noqa: E402


IGNITION = 5.0  # s: before it the elevator does not move and nothing is identifiable
DERIVATIVES = ("CLa", "CLde", "CDa", "CDde", "CMa", "CMde")
DEG = np.pi / 180.0


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--memory", type=float, default=1.0, help="s")
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/recursive_pegasus")
    )
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    flight = dp.pegasus.simulate(dp.pegasus.PegasusConfig(), jax.random.key(args.seed))
    log = dp.pegasus.flight_to_log(flight, {"seed": args.seed})
    dt = 1.0 / log.sample_rate
    reg = dp.pegasus.coefficient_regression(log.channels, log.s_ref, log.c_ref)
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
    t = np.asarray(log.t)
    truth = np.column_stack([np.asarray(log[f"true_{n}"]) for n in DERIVATIVES])
    cols = [reg.parameters.index(n) for n in DERIVATIVES]
    after = t >= IGNITION
    lse = dp.pegasus.estimate_lse(log)
    lse_mid = 0.5 * (np.asarray(lse.window_start) + np.asarray(lse.window_end))
    lse_vals = np.asarray(lse.values)
    lse_ok = np.asarray(lse.valid) & (lse_mid >= IGNITION)
    lse_truth = np.asarray(lse.truth)
    summary = {
        "seed": args.seed,
        "memory_s": args.memory,
        "forgetting": lam,
        "sample_rate_hz": log.sample_rate,
        "rft_frequencies_hz": [freqs[0], freqs[-1], step],
        "from_s": IGNITION,
        "units": "1/deg",
        "lse_0.5s": {
            "mse": {
                n: float(np.mean(((lse_vals - lse_truth)[lse_ok, j] * DEG) ** 2))
                for j, n in enumerate(DERIVATIVES)
            },
            "windows": int(lse_ok.sum()),
        },
        "methods": {},
    }
    histories = {}
    for label, est in estimators.items():
        start = time.perf_counter()
        hist = dp.replay(est, reg.h, reg.y, reg.o, np.zeros(9), float(t[0]))
        theta = np.asarray(hist.theta)[:, cols]
        elapsed = time.perf_counter() - start
        sd = np.asarray(hist.stderr_corrected)[:, cols]
        sd_white = np.asarray(hist.stderr)[:, cols]
        # the estimator's own 95% band (Student-t at its dof for the Fourier
        # transform, 1.96 corrected standard errors for least squares)
        half = np.asarray(hist.halfwidth)[:, cols]
        histories[label] = (theta, sd)
        err = (theta - truth)[after]
        # the recursive estimate sampled at the windows' ends (what it knew then)
        # against the same window-mean truth as the batch windows
        ends = np.minimum(
            np.searchsorted(t, np.asarray(lse.window_end)) - 1, len(t) - 1
        )
        win_err = (theta[ends] - lse_truth)[lse_ok]
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
            "coverage_95_white": {
                n: float(np.mean(np.abs(err[:, j]) <= 1.96 * sd_white[after, j]))
                for j, n in enumerate(DERIVATIVES)
            },
        }
    fig, axes = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
    for j, (name, ax) in enumerate(zip(DERIVATIVES, axes.flat, strict=True)):
        ax.plot(t, truth[:, j] * DEG, "k", lw=1.2, label="truth")
        for label, colour in (("rls", "C0"), ("rft", "C2")):
            theta, sd = histories[label]
            ax.plot(t, theta[:, j] * DEG, colour, lw=0.8, label=label)
            ax.fill_between(
                t,
                (theta[:, j] - 1.96 * sd[:, j]) * DEG,
                (theta[:, j] + 1.96 * sd[:, j]) * DEG,
                color=colour,
                alpha=0.2,
                lw=0,
            )
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
        print(label, {k: round(v, 3) for k, v in m["coverage_95_corrected"].items()})
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
