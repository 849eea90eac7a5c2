"""Thesis chapter 4: neural model plus least squares on simulated Pegasus flights.

Trains the coefficient network (default inputs, 10 tanh units, 3 outputs; Levenberg-
Marquardt, 70/15/15 split, early stopping) on three training flights (pulse, 3-2-1-1
and multisine excitation, seeds 11-13) and evaluates it on the held-out reference
flight (seed 1): training curves (thesis Fig 4.2), network coefficients against the
truth (Figs 4.3-4.5), derivatives by central differences of the network (the
thesis's poor first attempt, Figs 4.6-4.8) and by windowed least squares of its
outputs (Figs 4.9-4.11), and Table 4.1 beside the thesis. Saves the network for reuse.

Run: `python experiments/nn_pegasus.py [--out DIR] [--max-epochs 1000]`.
"""

import argparse
import json
import pathlib
import time

import jax
import matplotlib
import numpy as np


matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import diffpegasus as dp  # noqa: E402
from diffpegasus._report._plotting import plot_estimates  # noqa: E402


THESIS_TABLE_4_1 = {
    "CL": 9.02e-6,
    "CD": 9.82e-6,
    "CM": 2.88e-5,
    "CLa": 3.81e-5,
    "CLde": 1.89e-6,
    "CDa": 6.90e-6,
    "CDde": 1.31e-6,
    "CMa": 1.82e-5,
    "CMde": 7.11e-6,
}


def fly(name, seed):
    config = dp.PegasusConfig(elevator=dp.elevator_command(name))
    return dp.flight_to_log(
        dp.simulate(config, jax.random.key(seed)), {"seed": seed, "input": name}
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/nn_pegasus")
    )
    parser.add_argument("--max-epochs", type=int, default=1000)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    train_logs = [
        fly(n, s) for n, s in (("pulse", 11), ("3211", 12), ("multisine", 13))
    ]
    log = fly("pulse", 1)
    t0 = time.perf_counter()
    net, hist = dp.train_network(
        train_logs, jax.random.key(0), max_epochs=args.max_epochs
    )
    jax.block_until_ready(net)
    train_s = time.perf_counter() - t0
    dp.save_network(args.out / "network.eqx", net)
    n = int(hist.epochs)

    fig, ax = plt.subplots(figsize=(8, 5))
    for label, h in (
        ("training", hist.train),
        ("validation", hist.validation),
        ("test", hist.test),
    ):
        ax.semilogy(np.arange(1, n + 1), np.asarray(h)[:n], label=label)
    ax.set_xlabel("epoch")
    ax.set_ylabel("MSE (normalised outputs)")
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title("Levenberg-Marquardt training (thesis Fig 4.2)")
    fig.tight_layout()
    fig.savefig(args.out / "fig4_2_training.png", dpi=110)
    plt.close(fig)

    coeffs = np.asarray(net.coefficients(log.channels))
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    totals = {}
    powered = log.t >= 5.0
    for j, (ax, name) in enumerate(zip(axes, ("CL", "CD", "CM"), strict=True)):
        ax.plot(log.t, log[f"true_{name}"], "k-", lw=1, label="truth")
        ax.plot(log.t, coeffs[:, j], "-", lw=0.6, label="network")
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
        totals[name] = float(
            np.mean((coeffs[powered, j] - log[f"true_{name}"][powered]) ** 2)
        )
    axes[0].legend()
    axes[-1].set_xlabel("time since drop, s")
    fig.suptitle("Network coefficients on the held-out flight (thesis Figs 4.3-4.5)")
    fig.tight_layout()
    fig.savefig(args.out / "fig4_3_5_coefficients.png", dpi=110)
    plt.close(fig)

    central = dp.estimate_nn(log, net, derivatives="central")
    nn_lse = dp.estimate_nn(log, net, derivatives="lse")
    lse = dp.estimate_lse(log)
    plot_estimates(central, args.out / "fig4_6_8_central_differences.png")
    plot_estimates(nn_lse, args.out / "fig4_9_11_nn_lse.png")
    rows = {
        "nn+lse": {**totals, **nn_lse.mse("deg", 5.0)},
        "central differences": central.mse("deg", 5.0),
        "lse": lse.mse("deg", 5.0),
    }
    names = list(THESIS_TABLE_4_1)
    lines = [
        "| parameter | thesis Table 4.1 | ours NN+LSE | ours NN central differences | ours LSE |",
        "|---|---|---|---|---|",
    ]
    for k in names:
        cd = rows["central differences"].get(k)
        ls = rows["lse"].get(k)
        lines.append(
            f"| {k} | {THESIS_TABLE_4_1[k]:.3g} | {rows['nn+lse'][k]:.3g} | "
            f"{'-' if cd is None else f'{cd:.3g}'} | {'-' if ls is None else f'{ls:.3g}'} |"
        )
    md = (
        "MSE on the held-out flight from ignition on (coefficients: network output vs "
        "truth per sample; derivatives per degree, window estimate vs window-mean truth).\n\n"
        + "\n".join(lines)
        + "\n"
    )
    (args.out / "table4_1.md").write_text(md)
    summary = {
        "epochs": n,
        "training_s": train_s,
        "final_mse_normalised": {
            "train": float(hist.train[n - 1]),
            "validation": float(hist.validation[n - 1]),
            "test": float(hist.test[n - 1]),
        },
        "mse": rows,
        "thesis_table_4_1": THESIS_TABLE_4_1,
    }
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(md)
    print(f"trained {n} epochs in {train_s:.0f} s")


if __name__ == "__main__":
    main()
