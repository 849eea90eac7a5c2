"""Turbulent Monte Carlo: filter error against output error on simulated flights.

HFB-320 vehicle (`simulate --vehicle hfb320`: 30 s at 10 Hz, 3-2-1-1 elevator, the
identified aerodynamics as truth, white sensor noise) flown through Dryden gusts
(`turbulence=SIGMA`, the realisation drawn from the seed), several seeds. Each
flight is fitted by output error (`dp.fit`) and by filter error
(`dp.fit_filter_error`, process noise on V, alpha, theta, q, diagonal R, started
from the output-error estimates and from the model's start values, the lower det(R)
kept, intensities from the data), the model being the
generator's (`hfb320_model()`), so any bias is the method's. Per parameter: the mean
error over the seeds in units of the standard error of that mean (scatter /
sqrt(n)), the scatter against the mean Cramér-Rao bound, and the RMSE of each
method. Without turbulence (`--sigma 0`) both methods should agree.

Optionally (`--pegasus`) the Pegasus first stage: 30 s from drop at 50 Hz of a
perturbed stage (lift 1.08, drag 0.95, moment 0.9) in Dryden gusts, the three
database scale factors fitted (the vehicle from parts, `dp.vehicle_model`).

Run: `python experiments/turbulence_montecarlo.py [--seeds 12] [--sigma 0.3]
[--pegasus]`; writes `experiments/results/turbulence_montecarlo*.json` and prints
the README table.
"""

import argparse
import json
import pathlib
import time

import jax
import numpy as np


jax.config.update("jax_enable_x64", True)

import diffpegasus as dp  # noqa: E402
from diffpegasus._registry._hfb320_simulator import simulate_log, simulated_record  # noqa: E402
from diffpegasus._vehicle._hfb320 import hfb320_model, IDENTIFIED  # noqa: E402


OUT = pathlib.Path(__file__).parent / "results"
STATES = ("V", "alpha", "theta", "q")
METHODS = ("oem", "oem_x0", "fem")


def hfb320_record(seed, sigma, duration=30.0):
    ch, meta = simulate_log(duration=duration, seed=seed, turbulence=sigma)
    return simulated_record(ch, name=f"seed{seed}"), meta


def pegasus_record(seed, sigma, duration=30.0):
    from diffpegasus._vehicle._effects import Turbulence

    stage = dp.Vehicle().perturbed(lift=1.08, drag=0.95, moment=0.9)
    effects = (Turbulence(sigma=sigma, seed=seed),) if sigma else ()
    config = dp.PegasusConfig(
        vehicle=stage, t_final=duration, sample_rate=50.0, effects=effects
    )
    log = dp.flight_to_log(dp.simulate(config, jax.random.key(seed)))
    ch = log.channels
    outputs = ("V", "alpha", "theta", "q", "qdot", "ax", "az", "h")
    states = ("V", "alpha", "theta", "q", "h")
    return dp.Record(
        np.asarray(ch["t"]),
        np.asarray(ch["de"])[:, None],
        np.column_stack([np.asarray(ch[n]) for n in outputs]),
        x0=np.array([ch[n][0] for n in states]),
        name=f"seed{seed}",
    )


def one(model, rec):
    t0 = time.perf_counter()
    oem = dp.fit(model, rec, throw=False)
    # two starts, the output-error estimates and the model's start values, the
    # lower det(R) kept (as the diagnosis does): from a wild output-error estimate
    # the filter-error fit can stop in a local optimum
    fits = [
        dp.fit_filter_error(model, rec, process_noise=STATES, start=s, throw=False)
        for s in ((oem.params, None) if oem.converged else (None,))
    ]
    fem = min(fits, key=lambda f: (not f.converged, f.cost))
    which = ["oem", "model"][fits.index(fem)] if oem.converged else "model"
    # output error with the initial state estimated too (the gust at t = 0 moves
    # the air-relative alpha and V away from the held x0)
    oem_x0 = dp.fit(model, rec, initial_state="estimated", throw=False)
    return {
        "oem_x0": {
            "converged": oem_x0.converged,
            "params": oem_x0.params.tolist(),
            "stderr": oem_x0.stderr.tolist(),
            "stderr_corrected": oem_x0.stderr_corrected.tolist(),
            "cost": float(oem_x0.cost),
        },
        "oem": {
            "converged": oem.converged,
            "params": oem.params.tolist(),
            "stderr": oem.stderr.tolist(),  # Cramér-Rao bound
            "stderr_corrected": oem.stderr_corrected.tolist(),  # Morelli-Klein
            "cost": float(oem.cost),
        },
        "fem": {
            "converged": fem.converged,
            "params": fem.params.tolist(),
            "stderr": fem.stderr.tolist(),
            "F": fem.F.tolist(),
            "F_stderr": fem.F_stderr.tolist(),
            "cost": float(fem.cost),
            "iterations": fem.iterations,
            "constraint_active": fem.constraint_active,
            "start": which,
            "costs_by_start": [float(f.cost) for f in fits],
        },
        "seconds": time.perf_counter() - t0,
    }


def summary(names, truth, runs):
    """Per parameter and method: mean, scatter, mean CRB, bias in standard errors
    of the mean, RMSE, over the runs where that method converged (`n` per method)."""
    out = {"n_runs": len(runs), "n": {}, "parameters": {}}
    for m in METHODS:
        out["n"][m] = sum(r[m]["converged"] for r in runs)
    for i, name in enumerate(names):
        row = {"truth": truth[i]}
        for m in METHODS:
            ok = [r for r in runs if r[m]["converged"]]
            n = len(ok)
            est = np.array([r[m]["params"][i] for r in ok])
            crb = np.array([r[m]["stderr"][i] for r in ok])
            err = est - truth[i]
            scatter = float(np.std(est, ddof=1))
            row[m] = {
                "mean": float(est.mean()),
                "scatter": scatter,
                "crb": float(np.mean(crb)),
                "bias_in_se": float(err.mean() / (scatter / np.sqrt(n))),
                "rmse": float(np.sqrt(np.mean(err**2))),
            }
        row["rmse_ratio_oem_over_fem"] = row["oem"]["rmse"] / row["fem"]["rmse"]
        row["rmse_ratio_oem_x0_over_fem"] = row["oem_x0"]["rmse"] / row["fem"]["rmse"]
        out["parameters"][name] = row
    return out


def table(s):
    lines = [
        "| parameter | true | OEM bias/SE | OEM scatter / CRB | OEM (x0 est.) bias/SE | "
        "FEM mean | FEM bias/SE | FEM scatter / CRB | RMSE OEM / FEM | "
        "RMSE OEM (x0 est.) / FEM |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in s["parameters"].items():
        o, x, f = r["oem"], r["oem_x0"], r["fem"]
        lines.append(
            f"| {name} | {r['truth']:.4g} | {o['bias_in_se']:+.1f} | "
            f"{o['scatter']:.2g} / {o['crb']:.2g} | {x['bias_in_se']:+.1f} | "
            f"{f['mean']:.4g} | {f['bias_in_se']:+.1f} | "
            f"{f['scatter']:.2g} / {f['crb']:.2g} | "
            f"{r['rmse_ratio_oem_over_fem']:.2f} | {r['rmse_ratio_oem_x0_over_fem']:.2f} |"
        )
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=12)
    ap.add_argument("--sigma", type=float, default=0.3)
    ap.add_argument("--pegasus", action="store_true")
    ap.add_argument(
        "--table", type=pathlib.Path, help="only print the table of a results JSON"
    )
    args = ap.parse_args()
    if args.table:
        d = json.loads(args.table.read_text())
        names = list(d["parameters"])
        truth = [d["parameters"][k]["truth"] for k in names]
        s = summary(names, truth, d["runs"])
        s.update(vehicle=d["vehicle"], sigma=d["sigma"], runs=d["runs"])
        args.table.write_text(json.dumps(s, indent=1))
        print(
            f"{d['vehicle']}, sigma {d['sigma']} m/s, converged {s['n']} of {s['n_runs']}"
        )
        print(table(s))
        return
    OUT.mkdir(exist_ok=True)
    if args.pegasus:
        from diffpegasus._vehicle._pegasus._parts import pegasus_vehicle

        model = dp.vehicle_model(
            pegasus_vehicle(dp.Vehicle()),
            outputs=("V", "alpha", "theta", "q", "qdot", "ax", "az", "h"),
        )
        truth = [1.08, 0.95, 0.9]
        make = pegasus_record
        label = "pegasus"
    else:
        model = hfb320_model()
        truth = [IDENTIFIED[k] for k in model.parameters]
        make = lambda s, sig: hfb320_record(s, sig)[0]  # noqa: E731
        label = "hfb320"
    runs = []
    for seed in range(args.seeds):
        rec = make(seed, args.sigma)
        r = one(model, rec)
        r["seed"] = seed
        runs.append(r)
        print(
            f"seed {seed}: OEM {r['oem']['converged']} FEM {r['fem']['converged']} "
            f"({r['fem']['iterations']} it) F {np.round(r['fem']['F'], 5)} "
            f"{r['seconds']:.1f} s",
            flush=True,
        )
    s = summary(model.parameters, truth, runs)
    s.update(vehicle=label, sigma=args.sigma, runs=runs)
    suffix = f"_{label}_sigma{args.sigma:g}"
    (OUT / f"turbulence_montecarlo{suffix}.json").write_text(json.dumps(s, indent=1))
    print(f"\n{label}, sigma {args.sigma} m/s, converged {s['n']} of {s['n_runs']}")
    print(table(s))
    f = np.array([r["fem"]["F"] for r in runs if r["fem"]["converged"]])
    print(
        "FEM intensities, mean (scatter):",
        dict(
            zip(
                STATES,
                [
                    f"{m:.3g} ({d:.2g})"
                    for m, d in zip(f.mean(0), f.std(0, ddof=1), strict=True)
                ],
                strict=True,
            )
        ),
    )


if __name__ == "__main__":
    main()
