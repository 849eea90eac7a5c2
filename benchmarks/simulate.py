"""Benchmark: 100 Pegasus flights, drop to burnout (80.3 s) at 1 kHz, in one call.

Compares, in the same run, the batched and sharded `simulate_batch` against the
straightforward alternative: a Python loop of single-flight `simulate` calls (timed on
a subset and extrapolated to the full batch). Compile and run time are reported
separately. Writes `benchmarks/results/simulate.json`.

Run: `python benchmarks/simulate.py [--flights 100] [--loop-subset 10]`.
"""

import os


os.environ.setdefault(
    "XLA_FLAGS", f"--xla_force_host_platform_device_count={os.cpu_count()}"
)

import argparse  # noqa: E402
import json  # noqa: E402
import pathlib  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import jax  # noqa: E402

import diffpegasus as dp  # noqa: E402


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    jax.block_until_ready(out)
    return out, time.perf_counter() - t0


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--flights", type=int, default=100)
    parser.add_argument("--loop-subset", type=int, default=10)
    args = parser.parse_args()
    n = args.flights
    config = dp.PegasusConfig()
    perturbations = dp.shard_batch(dp.sample_perturbations(jax.random.key(0), n))
    keys = dp.shard_batch(jax.random.split(jax.random.key(1), n))

    _, batch_first = timed(lambda: dp.simulate_batch(config, keys, perturbations))
    flights, batch_run = timed(lambda: dp.simulate_batch(config, keys, perturbations))
    samples = flights.channels["az"].shape

    m = min(args.loop_subset, n)
    singles = [
        jax.tree_util.tree_map(lambda x, i=i: x[i], perturbations) for i in range(m)
    ]
    _, loop_first = timed(lambda: dp.simulate(singles[0].apply(config), keys[0]))
    _, loop_run = timed(
        lambda: [dp.simulate(p.apply(config), keys[i]) for i, p in enumerate(singles)]
    )
    loop_per_flight = loop_run / m
    result = {
        "what": f"{n} flights x 80.3 s at 1 kHz ({samples[1]} samples each)",
        "devices": len(jax.devices()),
        "cpu_count": os.cpu_count(),
        "machine": platform.processor() or platform.machine(),
        "jax": jax.__version__,
        "batched": {
            "compile_plus_first_run_s": batch_first,
            "compile_s_estimate": batch_first - batch_run,
            "run_s": batch_run,
            "run_s_per_flight": batch_run / n,
        },
        "python_loop": {
            "flights_timed": m,
            "compile_plus_first_run_s": loop_first,
            "run_s_per_flight": loop_per_flight,
            "run_s_extrapolated": loop_per_flight * n,
        },
        "speedup_batched_vs_loop": loop_per_flight * n / batch_run,
        "target": "batch of 100 in <= 20 s after compile on 2 cores",
        "meets_target": batch_run <= 20.0 if n == 100 else None,
    }
    out = pathlib.Path(__file__).parent / "results" / "simulate.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
