"""Benchmark: the Monte Carlo campaign (thesis chapter 6) against flight-by-flight runs.

- ours: the full campaign (100 flights drop to burnout at 1 kHz, LSE, NN+LSE, OEM),
  chunked, each chunk simulated and estimated in vmapped calls sharded over the
  cores; wall time per stage and the compile estimate from the campaign's own
  timings (a finished campaign folder is reused: the run resumes and computes
  nothing);
- the straightforward alternative, in the same run: the same jitted methods called
  one flight at a time (no vmap, no sharding) on a subset of the flights,
  extrapolated to 100; and the thesis's reported times.

Writes `benchmarks/results/montecarlo.json`. Run:
`python benchmarks/montecarlo.py [--out results/montecarlo] [--subset 3]`.
"""

import os


os.environ.setdefault(
    "XLA_FLAGS", f"--xla_force_host_platform_device_count={os.cpu_count()}"
)

import argparse  # noqa: E402
import json  # noqa: E402
import pathlib  # noqa: E402
import time  # noqa: E402

import jax  # noqa: E402
import numpy as np  # noqa: E402

import diffpegasus as dp  # noqa: E402
from diffpegasus._campaign import _montecarlo as mc  # noqa: E402


def timed(fn):
    t0 = time.perf_counter()
    out = jax.block_until_ready(fn())
    return out, time.perf_counter() - t0


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/montecarlo")
    )
    parser.add_argument("--subset", type=int, default=3)
    args = parser.parse_args()
    campaign = mc.Campaign()
    t0 = time.perf_counter()
    summary = mc.run_campaign(campaign, args.out)
    this_call = time.perf_counter() - t0
    times = summary["times"]

    # flight by flight: the same methods, jitted, one flight per call
    keys, pert = mc.draws(campaign)
    config = campaign.config
    one_flight = jax.jit(lambda k, p: dp.simulate(p.apply(config), k))
    net = dp.load_network(args.out / "network.eqx")
    layout = dp.WindowLayout.make(len(config.times), campaign.sample_rate, 0.5)
    s_ref, c_ref = config.vehicle.s_ref, config.vehicle.c_ref

    @jax.jit
    def lse_one(ch):
        return dp.lse_arrays(ch, layout, s_ref=s_ref, c_ref=c_ref)["values"]

    @jax.jit
    def nn_one(ch):
        return mc._nn_chunk(net, jax.tree_util.tree_map(lambda x: x[None], ch), layout)[
            0
        ]

    @jax.jit
    def oem_one(setup):
        return setup.fit().params

    loop = {"simulate": [], "lse": [], "nn": [], "oem": []}
    for i in range(args.subset + 1):  # the first flight compiles; not counted
        p = jax.tree_util.tree_map(lambda x, i=i: x[i], pert)
        flight, t_sim = timed(lambda p=p, i=i: one_flight(keys[i], p))
        ch = dict(flight.channels)
        lse, t_lse = timed(lambda ch=ch: lse_one(ch))
        _, t_nn = timed(lambda ch=ch: nn_one(ch))
        setup, _ = dp.oem_setup(dp.flight_to_log(flight), lse=np.asarray(lse))
        _, t_oem = timed(lambda s=setup: oem_one(s))
        if i > 0:
            for k, v in zip(loop, (t_sim, t_lse, t_nn, t_oem), strict=True):
                loop[k].append(v)
    per_flight = {k: float(np.mean(v)) for k, v in loop.items()}
    batched_total = {
        k: times["total_s"][k] - times["compile_s_estimate"].get(k, 0.0)
        for k in per_flight
    }
    whole = float(sum(times["total_s"].values()))
    result = {
        "what": "100 flights x 80.3 s at 1 kHz; LSE, NN+LSE (LM-trained), OEM "
        "(multiple shooting, hybrid windowed derivatives, 200 Hz)",
        "devices": len(jax.devices()),
        "cpu_count": os.cpu_count(),
        "campaign_s": {
            "total_all_stages": whole,
            "per_stage": times["total_s"],
            "compile_estimate": times["compile_s_estimate"],
            "this_call": this_call,
        },
        "flight_by_flight_s_per_flight": per_flight,
        "flight_by_flight_extrapolated_100_s": {
            k: 100 * v for k, v in per_flight.items()
        },
        "speedup_batched_vs_flight_by_flight": {
            k: 100 * per_flight[k] / batched_total[k] for k in per_flight
        },
        "thesis_s_per_100_flights": mc.THESIS_SECONDS,
        "speedup_vs_thesis": {
            "lse": mc.THESIS_SECONDS["lse"] / times["total_s"]["lse"],
            "nn_incl_training": (
                mc.THESIS_SECONDS["nn"] + mc.THESIS_SECONDS["nn_training"]
            )
            / (times["total_s"]["nn"] + times["total_s"]["nn_training"]),
            "oem": mc.THESIS_SECONDS["oem"] / times["total_s"]["oem"],
        },
        "targets": {
            "whole_campaign_s": 1200,
            "oem_s": 600,
            "whole_met": whole <= 1200,
            "oem_met": times["total_s"]["oem"] <= 600,
        },
        "oem_coverage_2sigma": summary.get("oem_coverage_2sigma"),
        "means": summary["means"],
    }
    path = pathlib.Path(__file__).parent / "results" / "montecarlo.json"
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
