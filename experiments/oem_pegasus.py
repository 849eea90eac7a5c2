"""Thesis chapter 5: the output-error method on one simulated Pegasus flight.

Runs, on the reference flight (seed 1, pulse excitation, default sensor noise):
multiple-shooting OEM (0.5 s windows, nodes every 2 s, derivatives linear in time
between window boundaries, and the thesis's constant-per-window model) in body axes
(the thesis's choice) and in lift/drag axes (thesis Figs 5.1-5.2), from three starting points
(equation-error LSE estimates of the same windows — what a user has —, the a-priori
database, and the thesis's truth +/- 10%), the thesis's sequential single shooting
(Figs 5.3-5.6), and LSE for comparison. Writes the estimate figures (Figs 5.7-5.10),
the total coefficients (Fig 5.11), Table 5.1 with the thesis's numbers beside ours,
the start-sensitivity table and timings, as PNG, markdown, CSV and JSON.

MSE: window estimate minus the window-mean truth, per degree, over the windows from
ignition (5 s) on; totals as in `lse_pegasus.py`.

Run: `python experiments/oem_pegasus.py [--seed 1] [--out DIR]`.
"""

import argparse
import json
import pathlib
import time

import jax
import numpy as np

import diffpegasus as dp
from diffpegasus._report._plotting import plot_estimates


THESIS_TABLE_5_1 = {
    "CL": 3.44e-4,
    "CD": 6.56e-5,
    "CM": 1.31e-4,
    "CLa": 4.13e-6,
    "CLde": 6.61e-7,
    "CDa": 1.18e-6,
    "CDde": 1.93e-7,
    "CMa": 1.20e-6,
    "CMde": 6.71e-7,
}
IGNITION = 5.0


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/oem_pegasus")
    )
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    log = dp.flight_to_log(dp.simulate(dp.PegasusConfig(), jax.random.key(args.seed)))

    import lse_pegasus  # noqa: PLC0415 (same folder: reuse the totals' definition)

    runs = {
        "multiple / body / lse start": dict(
            shooting="multiple", axes="body", start="lse"
        ),
        "multiple / body / database start": dict(
            shooting="multiple", axes="body", start="database"
        ),
        "multiple / body / truth +/-10% start": dict(
            shooting="multiple", axes="body", start="truth10"
        ),
        "multiple / body / constant per window": dict(
            shooting="multiple", axes="body", start="lse", parameters="constant"
        ),
        "multiple / lift-drag / lse start": dict(
            shooting="multiple", axes="wind", start="lse"
        ),
        "single / body / lse start": dict(shooting="single", axes="body", start="lse"),
    }
    results, table = {}, {}
    t0 = time.perf_counter()
    lse = dp.estimate_lse(log)
    jax.block_until_ready(lse.values)
    timing = {"lse": time.perf_counter() - t0}
    results["lse"] = lse
    for name, kw in runs.items():
        t0 = time.perf_counter()
        est = dp.pegasus.estimate_oem(log, **kw)
        jax.block_until_ready(est.values)
        timing[name] = time.perf_counter() - t0
        results[name] = est
        print(
            f"{name}: {timing[name]:.1f} s (first call of a shape includes compilation)"
        )
    for name, est in results.items():
        totals, _ = lse_pegasus.total_coefficient_mse(log, est, IGNITION)
        table[name] = {
            **totals,
            **est.mse("deg", IGNITION),
            "windows_converged": int(np.sum(np.asarray(est.valid))),
        }

    main_run = "multiple / body / lse start"
    plot_estimates(results[main_run], args.out / "fig5_7_10_multiple_shooting.png")
    plot_estimates(
        results["single / body / lse start"], args.out / "fig5_3_5_single_shooting.png"
    )
    plot_estimates(
        results["multiple / lift-drag / lse start"],
        args.out / "fig5_1_2_lift_drag_axes.png",
    )
    _, model = lse_pegasus.total_coefficient_mse(log, results[main_run], IGNITION)
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    for ax, name in zip(axes, ("CL", "CD", "CM"), strict=True):
        ax.plot(log.t, log[f"true_{name}"], "k-", lw=1, label="truth")
        ax.plot(log.t, model[name], "-", lw=0.6, label="OEM model")
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    axes[0].legend()
    axes[-1].set_xlabel("time since drop, s")
    fig.suptitle("Total coefficients, multiple-shooting OEM (thesis Fig 5.11)")
    fig.tight_layout()
    fig.savefig(args.out / "fig5_11_totals.png", dpi=110)
    plt.close(fig)

    names = list(THESIS_TABLE_5_1)
    cols = [
        "lse",
        main_run,
        "multiple / body / constant per window",
        "single / body / lse start",
        "multiple / lift-drag / lse start",
    ]
    lines = [
        "| parameter | thesis Table 5.1 (OEM) | " + " | ".join(cols) + " |",
        "|---|---|" + "---|" * len(cols),
    ]
    for n in names:
        lines.append(
            f"| {n} | {THESIS_TABLE_5_1[n]:.3g} | "
            + " | ".join(f"{table[c][n]:.3g}" for c in cols)
            + " |"
        )
    starts = [
        "| start | " + " | ".join(dp.DERIVATIVE_NAMES) + " |",
        "|---|" + "---|" * 6,
    ]
    for c in [k for k in runs if k.startswith("multiple / body") and "start" in k]:
        starts.append(
            f"| {c.split(' / ')[2]} | "
            + " | ".join(f"{table[c][n]:.3g}" for n in dp.DERIVATIVE_NAMES)
            + " |"
        )
    md = (
        "MSE per degree, windows from ignition on.\n\n"
        + "\n".join(lines)
        + "\n\nMultiple shooting, body axes, by starting point:\n\n"
        + "\n".join(starts)
        + "\n"
    )
    (args.out / "table5_1.md").write_text(md)
    summary = {
        "seed": args.seed,
        "mse_per_deg": table,
        "seconds": timing,
        "thesis_table_5_1": THESIS_TABLE_5_1,
    }
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(md)


if __name__ == "__main__":
    main()
