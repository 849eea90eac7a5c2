"""Thesis section 3.3: which elevator inputs make windowed least squares work?

The linear short-period model (alpha, q; Z_q = M_q = 0) at constant Mach 2 and with
Mach rising linearly from 2 to 4 over 50 s, 5 ms steps, 1 s windows, regressing CZ and
CM on [1, alpha, de] with the thesis's rank rule (A and A^T A full rank, tolerance
1e-2, angles in degrees). Inputs: sine (2 Hz, -3 deg), ramp (0.05 deg/s), step (5 deg),
pulse (8 s period, 5 deg, -1 deg bias).

Regenerates the content of thesis Figs 3.1-3.7 as PNGs (ranks over time, estimates
against the true values, and the pulse under the relaxed rule A full rank only) and
writes `summary.json`. Run: `python experiments/input_design.py [--out DIR]`.
"""

import argparse
import json
import pathlib

import jax.numpy as jnp
import matplotlib


matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import diffpegasus as dp  # noqa: E402
from diffpegasus._vehicle._short_period import ShortPeriodModel, simulate_short_period  # noqa: E402


INPUTS = {
    "sine": dp.Sine(amplitude=-3.0, frequency=2.0, start=0.0),
    "ramp": dp.Ramp(rate=0.05, start=0.0),
    "step": dp.Step(amplitude=5.0, start=-1.0),
    "pulse": dp.PulseTrain(amplitude=5.0, period=8.0, width=4.0, bias=-1.0, start=0.0),
}
NAMES = ("CZa", "CZde", "CMa", "CMde")


def study(model, elevator, relaxed=False):
    d = simulate_short_period(model, elevator)
    layout = dp.WindowLayout.make(len(d["t"]), 200.0, 1.0)
    cz = d["az"] * model.mass / (d["qbar"] * model.s_ref)
    cm = d["qdot"] * model.iyy / (d["qbar"] * model.s_ref * model.c_ref)
    a = layout.split(jnp.stack([jnp.ones_like(d["alpha"]), d["alpha"], d["de"]], -1))
    y = layout.split(jnp.stack([cz, cm], -1))
    deg = 180 / np.pi
    theta, _, rank_a, rank_ata, ok = dp.windowed_least_squares(
        a,
        y,
        layout.mask(),
        column_scale=jnp.array([1.0, deg, deg]),
        require_full_normal_rank=not relaxed,
    )
    est = np.stack([theta[:, 1, 0], theta[:, 2, 0], theta[:, 1, 1], theta[:, 2, 1]], -1)
    truth = np.stack(
        [np.asarray(layout.window_mean(d[f"true_{k}"])) for k in NAMES], -1
    )
    start, end = layout.times(0.0)
    return {
        "t": end,
        "estimates": est / deg,
        "truth": truth / deg,  # per degree
        "rank_A": np.asarray(rank_a),
        "rank_ATA": np.asarray(rank_ata),
        "ok": np.asarray(ok),
    }


def summarise(r):
    ok = r["ok"]
    rel = np.abs(r["estimates"] - r["truth"]) / np.abs(r["truth"])
    return {
        "windows": int(len(ok)),
        "windows_full_rank_A": int(np.sum(r["rank_A"] == 3)),
        "windows_full_rank_ATA": int(np.sum(r["rank_ATA"] == 3)),
        "windows_estimated": int(ok.sum()),
        "identifiable": bool(ok.any()),
        "max_relative_error_estimated_windows": float(rel[ok].max())
        if ok.any()
        else None,
    }


def plot_ranks(results, path):
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for name, r in results.items():
        axes[0].step(r["t"], r["rank_A"], where="post", label=name)
        axes[1].step(r["t"], r["rank_ATA"], where="post", label=name)
    axes[0].set_ylabel("rank of A")
    axes[1].set_ylabel("rank of A^T A")
    axes[1].set_xlabel("time, s")
    for ax in axes:
        ax.set_yticks([1, 2, 3])
        ax.grid(alpha=0.3)
    axes[0].legend(ncol=4)
    fig.suptitle("Ranks per 1 s window, varying Mach (thesis Fig 3.1)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_estimates(results, names, path, title):
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
    for j, ax in enumerate(axes.flat):
        for label, r in results.items():
            (line,) = ax.plot(r["t"], r["truth"][:, j], "-", lw=1.5, alpha=0.5)
            ax.plot(
                r["t"],
                r["estimates"][:, j],
                "o--",
                ms=3,
                lw=0.8,
                color=line.get_color(),
                label=f"{label}: estimate (solid: truth)",
            )
        ax.set_ylabel(f"{names[j]}, 1/deg")
        ax.grid(alpha=0.3)
    axes.flat[0].legend(fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("time, s")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/input_design")
    )
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    constant = ShortPeriodModel(mach_start=2.0, mach_end=2.0)
    varying = ShortPeriodModel(mach_start=2.0, mach_end=4.0)
    results = {
        f"{mach}/{name}": study(model, inp)
        for mach, model in (("constant", constant), ("varying", varying))
        for name, inp in INPUTS.items()
    }
    results["varying/pulse (relaxed rule)"] = study(
        varying, INPUTS["pulse"], relaxed=True
    )
    plot_ranks(
        {
            k.split("/")[1]: v
            for k, v in results.items()
            if k.startswith("varying/") and "relaxed" not in k
        },
        args.out / "fig3_1_ranks.png",
    )
    sine = {
        "constant Mach": results["constant/sine"],
        "varying Mach": results["varying/sine"],
    }
    plot_estimates(
        sine,
        NAMES,
        args.out / "fig3_2_3_sine.png",
        "Sine input, constant and varying Mach (thesis Figs 3.2-3.3)",
    )
    others = {n: results[f"varying/{n}"] for n in ("ramp", "step", "pulse")}
    plot_estimates(
        others,
        NAMES,
        args.out / "fig3_4_5_ramp_step_pulse.png",
        "Ramp, step, pulse, varying Mach (thesis Figs 3.4-3.5; NaN = never estimated)",
    )
    plot_estimates(
        {"pulse, rank(A) = 3 only": results["varying/pulse (relaxed rule)"]},
        NAMES,
        args.out / "fig3_6_7_pulse_relaxed.png",
        "Pulse with the relaxed rank rule (thesis Figs 3.6-3.7)",
    )
    summary = {k: summarise(v) for k, v in results.items()}
    summary["conclusion"] = {
        "identifiable": sorted(
            {k.split("/")[1] for k, v in summary.items() if v["identifiable"]}
        ),
        "rank_deficient": sorted(
            {k.split("/")[1] for k, v in summary.items() if not v["identifiable"]}
        ),
        "thesis": "sine and pulse identifiable; ramp and step rank-deficient",
    }
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary["conclusion"]))
    for k, v in summary.items():
        if k != "conclusion":
            print(
                f"{k:32s} A full {v['windows_full_rank_A']:2d}/50, A^TA full "
                f"{v['windows_full_rank_ATA']:2d}/50, estimated {v['windows_estimated']:2d}, "
                f"max rel. error {v['max_relative_error_estimated_windows']}"
            )


if __name__ == "__main__":
    main()
