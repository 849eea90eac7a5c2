"""Gradient-optimal elevator input for the output-error method (beyond the thesis).

On a 5 s segment of the nominal Pegasus flight (20-25 s, Mach ~2), the Cramér-Rao
criterion of the six derivatives is minimised over a 8-harmonic multisine's
amplitudes and phases (started from the Schroeder-phased one), through the
differentiable OEM model, under the same limits as the hand-picked inputs (the
thesis's pulse and sine, a 3-2-1-1 and a Schroeder multisine, each scaled into the
limits): peak 2 deg, 40 deg/s, alpha excursion 2 deg. Then a small Monte Carlo: 40
noisy realisations of the design model's outputs per input, each fitted by the OEM
(single shooting over the segment, started 10% off), gives the realised errors,
compared with the predicted ones. Writes PNG + JSON to `--out`.

Run: `python experiments/optimal_input.py [--criterion D] [--runs 40] [--out DIR]`.
"""

import argparse
import json
import pathlib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import diffpegasus as dp
import diffpegasus._design._optimal as design_mod
from diffpegasus._cli._campaign import _design_report
from diffpegasus._report._plotting import plot_design


def realised_errors(design, excitation, runs, key):
    """RMS over `runs` noisy realisations of the OEM estimate minus the truth, in
    the reported (lift/drag) form, `(6,)` 1/rad; and how many fits converged."""
    e = design_mod._values(design, excitation)
    inputs = design.problem.inputs.at[:, design.column].add(e)
    problem = eqx.tree_at(lambda q: q.inputs, design.problem, inputs)
    clean = design_mod.simulate_outputs(design, excitation)
    noise = jax.random.normal(key, (runs, *clean.shape)) * jnp.sqrt(design.noise)

    def fit(measured):
        p = eqx.tree_at(lambda q: q.measured, problem, measured)
        res = dp.fit_global_oem(p, design.theta * 1.1, design.x0[None])
        return design.transform(res.params), res.converged

    est, ok = jax.jit(jax.vmap(fit))(clean[None] + noise)
    err = np.asarray(est - design.transform(design.theta))[np.asarray(ok)]
    return np.sqrt(np.mean(err**2, axis=0)), int(np.sum(np.asarray(ok)))


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--criterion", default="D", choices=("D", "A"))
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--steps", type=int, default=150)
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/optimal_input")
    )
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    segment = (20.0, 25.0)
    design = design_mod.pegasus_design(segment)
    limits = design_mod.Limits(
        float(np.deg2rad(2.0)), float(np.deg2rad(40.0)), float(np.deg2rad(2.0))
    )
    result = design_mod.run_design(
        design, limits, kind=args.criterion, steps=args.steps
    )
    plot_design(design, result, args.out)
    report = _design_report(result, args.criterion, limits, segment)
    hand = result["best_hand_picked"]
    mc = {}
    for name in (hand, "optimised"):
        rms, n_ok = realised_errors(
            design, result["inputs"][name], args.runs, jax.random.key(7)
        )
        mc[name] = {
            "realised_rms_per_deg": dict(
                zip(dp.DERIVATIVE_NAMES, (rms * np.pi / 180).tolist(), strict=True)
            ),
            "converged_runs": n_ok,
        }
    predicted = {
        n: np.asarray(result["rows"][hand]["stderr"])[j]
        / np.asarray(result["rows"]["optimised"]["stderr"])[j]
        for j, n in enumerate(dp.DERIVATIVE_NAMES)
    }
    realised = {
        n: mc[hand]["realised_rms_per_deg"][n]
        / mc["optimised"]["realised_rms_per_deg"][n]
        for n in dp.DERIVATIVE_NAMES
    }
    report["monte_carlo"] = {
        "runs": args.runs,
        "per_input": mc,
        "error_ratio_hand_picked_over_optimised": {
            "predicted": {k: float(v) for k, v in predicted.items()},
            "realised": realised,
        },
    }
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4.5))
    x = np.arange(6)
    ax.bar(x - 0.2, list(predicted.values()), 0.4, label="predicted (Cramér-Rao)")
    ax.bar(x + 0.2, list(realised.values()), 0.4, label=f"realised ({args.runs} runs)")
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_xticks(x, dp.DERIVATIVE_NAMES)
    ax.set_ylabel(f"error of {hand} / error of optimised")
    ax.legend()
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    fig.savefig(args.out / "design_monte_carlo.png", dpi=110)
    plt.close(fig)
    (args.out / "design.json").write_text(json.dumps(report, indent=2))
    print(json.dumps(report["monte_carlo"], indent=2))
    print(json.dumps({k: v["criterion"] for k, v in report["inputs"].items()}))


if __name__ == "__main__":
    main()
