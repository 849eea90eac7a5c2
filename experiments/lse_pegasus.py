"""Thesis section 3.4-3.5: windowed least squares on one simulated Pegasus flight.

Simulates the reference flight (pulse excitation, default sensor noise), estimates the
six derivatives in 0.5 s windows and regenerates the content of thesis Figs 3.9-3.14
(derivatives against the truth, alpha and elevator, total coefficients) and Table 3.2
(MSE of the total coefficients and the derivatives, per degree), with the thesis's
numbers beside ours. Writes PNG, CSV, markdown and JSON to `--out`.

MSE definitions: a derivative's error is the window estimate minus the truth averaged
over that window; a total coefficient's error is, at every sample, the window's model
`CLa_hat alpha + CLde_hat de` minus the simulator's true coefficient. Counted: every
window with an estimate ("all"), and the windows from ignition on ("powered"), since
before ignition the elevator is constant and nothing separates CLde from the trim.

Run: `python experiments/lse_pegasus.py [--seed 1] [--out DIR]`.
"""

import argparse
import json
import pathlib

import jax
import matplotlib


matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import diffpegasus as dp  # noqa: E402
from diffpegasus._report._plotting import plot_estimates  # noqa: E402


THESIS_TABLE_3_2 = {
    "CL": 5.92e-6,
    "CD": 7.76e-6,
    "CM": 2.69e-5,
    "CLa": 2.25e-4,
    "CLde": 1.86e-5,
    "CDa": 3.23e-5,
    "CDde": 5.22e-6,
    "CMa": 3.89e-5,
    "CMde": 9.53e-6,
}
IGNITION = 5.0


def total_coefficient_mse(log, est, t_min):
    """Per-degree MSE of the totals: angles in degrees, derivatives per degree."""
    layout = dp.WindowLayout.make(len(log), log.sample_rate, 0.5)
    idx = np.minimum(np.arange(len(log)) // layout.per_window, layout.count - 1)
    keep = (np.arange(len(log)) < layout.used) & (log.t >= t_min)
    keep &= np.asarray(est.valid)[idx]
    v = np.asarray(est.values)[idx]
    out, model = {}, {}
    for j, name in enumerate(("CL", "CD", "CM")):
        model[name] = v[:, 2 * j] * log["alpha"] + v[:, 2 * j + 1] * log["de"]
        out[name] = float(np.mean((model[name] - log[f"true_{name}"])[keep] ** 2))
    return out, model


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/lse_pegasus")
    )
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    flight = dp.simulate(dp.PegasusConfig(), jax.random.key(args.seed))
    log = dp.flight_to_log(flight, {"seed": args.seed})
    dp.write_log(args.out / "flight.csv", log)
    est = dp.estimate_lse(log)
    est.write_csv(args.out / "lse_estimates.csv")
    plot_estimates(est, args.out / "fig3_9_11_derivatives.png")

    rows = {}
    for label, t_min in (("all", None), ("powered", IGNITION)):
        totals, model = total_coefficient_mse(
            log, est, -np.inf if t_min is None else t_min
        )
        rows[label] = {**totals, **est.mse("deg", t_min)}

    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    axes[0].plot(log.t, np.rad2deg(log["alpha"]), lw=0.6)
    axes[0].set_ylabel("alpha, deg")
    axes[1].plot(log.t, np.rad2deg(log["de"]), lw=0.6)
    axes[1].set_ylabel("elevator, deg")
    axes[1].set_xlabel("time since drop, s")
    fig.suptitle("Angle of attack and elevator (thesis Fig 3.12)")
    fig.tight_layout()
    fig.savefig(args.out / "fig3_12_alpha_elevator.png", dpi=110)
    plt.close(fig)

    for zoom, fname in (
        (None, "fig3_13_totals.png"),
        ((20.0, 24.0), "fig3_14_totals_zoom.png"),
    ):
        fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
        sel = slice(None) if zoom is None else (log.t >= zoom[0]) & (log.t <= zoom[1])
        for ax, name in zip(axes, ("CL", "CD", "CM"), strict=True):
            ax.plot(log.t[sel], log[f"true_{name}"][sel], "k-", lw=1, label="truth")
            ax.plot(log.t[sel], model[name][sel], "-", lw=0.7, label="LSE model")
            ax.set_ylabel(name)
            ax.grid(alpha=0.3)
        axes[0].legend()
        axes[-1].set_xlabel("time since drop, s")
        fig.suptitle(
            "Total coefficients, truth vs LSE model (thesis Fig 3.13"
            + ("-3.14 zoom)" if zoom else ")")
        )
        fig.tight_layout()
        fig.savefig(args.out / fname, dpi=110)
        plt.close(fig)

    names = list(THESIS_TABLE_3_2)
    lines = [
        "| parameter | thesis Table 3.2 | ours, all windows | ours, from ignition |",
        "|---|---|---|---|",
    ]
    for n in names:
        lines.append(
            f"| {n} | {THESIS_TABLE_3_2[n]:.3g} | {rows['all'][n]:.3g} | {rows['powered'][n]:.3g} |"
        )
    table = "\n".join(lines)
    (args.out / "table3_2.md").write_text(
        "MSE of the LSE estimates, per degree ((1/deg)^2 for derivatives).\n\n"
        + table
        + "\n"
    )
    with open(args.out / "table3_2.csv", "w") as f:
        f.write("parameter,thesis,ours_all,ours_powered\n")
        for n in names:
            f.write(
                f"{n},{THESIS_TABLE_3_2[n]},{rows['all'][n]},{rows['powered'][n]}\n"
            )
    summary = {
        "seed": args.seed,
        "windows": int(len(est.window_start)),
        "rank_deficient_windows": int(np.sum(np.asarray(est.flags["rank_deficient"]))),
        "mse_per_deg": rows,
        "thesis": THESIS_TABLE_3_2,
    }
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(table)


if __name__ == "__main__":
    main()
