"""Calibrating the diagnosis's process-noise candidate on simulated HFB-320 flights.

Three kinds of 30 s flights (`simulate --vehicle hfb320`, 10 Hz), several seeds
each, diagnosed with the vehicle's 12 library candidates plus process noise on V,
alpha, theta, q (`dp.diagnose_model(..., process_noise=...)`):

- clean: no turbulence (false alarms of `process_noise`);
- turbulent: Dryden gusts of 0.3 m/s (is `process_noise` first, with the
  turbulence verdict?);
- deterministic: the model's pitch damping CMq held at zero, light gusts (0.1 m/s
  by default): does the missing damping (`pitch_damping` / `alpha_dot_damping`,
  which this manoeuvre cannot tell apart) still rank first?

Per flight it records the likelihood ratio of process noise, the largest score
statistic of a deterministic candidate at the filter-error fit, the top of the
ranking and the verdict. Run: `python experiments/turbulence_diagnosis.py [--seeds
12] [--light 0.1]`; writes `experiments/results/turbulence_diagnosis.json`.
"""

import argparse
import json
import pathlib
import time

import jax
import numpy as np


jax.config.update("jax_enable_x64", True)

import diffpegasus as dp  # noqa: E402
from diffpegasus._registry import vehicle_spec  # noqa: E402
from diffpegasus._registry._hfb320_simulator import simulate_log, simulated_record  # noqa: E402


OUT = pathlib.Path(__file__).parent / "results"
STATES = ("V", "alpha", "theta", "q")


def record(seed, sigma, duration=30.0):
    ch, _ = simulate_log(duration=duration, seed=seed, turbulence=sigma)
    return simulated_record(ch, name=f"seed{seed}")


def diagnose(model, candidates, rec):
    t0 = time.perf_counter()
    _, ranking = dp.diagnose_model(
        model, rec, candidates, process_noise=STATES, throw=False
    )
    pn = next(r for r in ranking if r["effect"] == "process_noise")
    det = [r for r in ranking if r["effect"] != "process_noise"]
    under = [
        r["statistic_under_process_noise"]
        for r in det
        if r.get("statistic_under_process_noise") is not None
    ]
    strongest = max(det, key=lambda r: r.get("statistic_under_process_noise") or 0.0)
    return {
        "top": ranking[0]["effect"],
        "top_parameter": ranking[0]["parameter"],
        "significant": [r["effect"] for r in ranking if r["significant"]],
        "process_noise_lr": pn["statistic"],
        "process_noise_significant": pn["significant"],
        "process_noise_fall": pn["cost_reduction"],
        "intensities": pn["intensities"],
        "max_statistic_under_process_noise": max(under) if under else None,
        "strongest_under_process_noise": strongest["effect"],
        "top_output_error": max(det, key=lambda r: r["cost_reduction"])["effect"],
        "hard_to_tell_from": pn["hard_to_tell_from"],
        "under_process_noise": {
            r["parameter"]: r.get("statistic_under_process_noise") for r in det
        },
        "verdict": pn.get("verdict"),
        "seconds": time.perf_counter() - t0,
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=12)
    ap.add_argument("--sigma", type=float, default=0.3)
    ap.add_argument("--light", type=float, default=0.1)
    ap.add_argument("--kinds", default="clean,turbulent,deterministic")
    ap.add_argument("--first-seed", type=int, default=100)
    args = ap.parse_args()
    spec = vehicle_spec("hfb320", candidates=True)
    held = spec.model.replace(
        start={"CMq": 0.0}, fixed=tuple(spec.model.fixed) + ("CMq",)
    )
    kinds = {
        "clean": (spec.model, 0.0),
        "turbulent": (spec.model, args.sigma),
        "deterministic": (held, args.light),
    }
    results = {}
    for kind in args.kinds.split(","):
        model, sigma = kinds[kind]
        key = kind if kind != "deterministic" else f"deterministic_sigma{sigma:g}"
        results[key] = {"sigma": sigma, "flights": []}
        for seed in range(args.seeds):
            seed = args.first_seed + seed
            r = diagnose(model, spec.candidates, record(seed, sigma))
            r["seed"] = seed
            results[key]["flights"].append(r)
            print(
                f"{kind} seed {seed}: top {r['top']}, LR {r['process_noise_lr']:.0f} "
                f"({'significant' if r['process_noise_significant'] else 'not significant'}),"
                f" strongest under process noise {r['strongest_under_process_noise']} "
                f"{r['max_statistic_under_process_noise'] or 0:.1f}, {r['seconds']:.0f} s",
                flush=True,
            )
    OUT.mkdir(exist_ok=True)
    path = OUT / "turbulence_diagnosis.json"
    old = json.loads(path.read_text()) if path.exists() else {}
    old.update(results)
    path.write_text(json.dumps(old, indent=1))
    for kind, res in results.items():
        fl = res["flights"]
        tops = [f["top"] for f in fl]
        print(
            f"{kind} (sigma {res['sigma']}): top {dict(zip(*np.unique(tops, return_counts=True), strict=True))}"
            f"; process noise significant {sum(f['process_noise_significant'] for f in fl)}"
            f"/{len(fl)}; LR {min(f['process_noise_lr'] for f in fl):.0f}-"
            f"{max(f['process_noise_lr'] for f in fl):.0f}; largest score under process "
            f"noise {max((f['max_statistic_under_process_noise'] or 0) for f in fl):.1f}"
        )


if __name__ == "__main__":
    main()
