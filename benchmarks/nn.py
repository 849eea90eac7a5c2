"""Benchmark: neural model plus least squares.

Training time (Levenberg-Marquardt on three simulated flights, subsampled 10x), then
inference plus windowed least squares on 100 flights in one vmapped call against a
Python loop over the flights (ratio). The thesis quotes about 1 h of training and
6.75 s per flight. Writes `benchmarks/results/nn.json`.

Run: `python benchmarks/nn.py [--flights 100] [--max-epochs 1000]`.
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
import jax.numpy as jnp  # noqa: E402

import diffpegasus as dp  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--flights", type=int, default=100)
    parser.add_argument("--max-epochs", type=int, default=1000)
    parser.add_argument("--loop-subset", type=int, default=10)
    args = parser.parse_args()
    train_logs = [
        dp.flight_to_log(
            dp.simulate(
                dp.PegasusConfig(elevator=dp.elevator_command(n)), jax.random.key(s)
            )
        )
        for n, s in (("pulse", 11), ("3211", 12), ("multisine", 13))
    ]
    t0 = time.perf_counter()
    net, hist = dp.train_network(
        train_logs, jax.random.key(0), max_epochs=args.max_epochs
    )
    jax.block_until_ready(net)
    train_s = time.perf_counter() - t0

    n = args.flights
    flights = dp.simulate_batch(
        dp.PegasusConfig(),
        dp.shard_batch(jax.random.split(jax.random.key(1), n)),
        dp.shard_batch(dp.sample_perturbations(jax.random.key(0), n)),
    )
    channels = jax.block_until_ready(dict(flights.channels))
    layout = dp.WindowLayout.make(channels["az"].shape[1], 1000.0, 0.5)
    deg = 180.0 / jnp.pi

    def one(c):
        coeffs = net.coefficients(c)
        a = layout.split(jnp.stack([c["alpha"], c["de"]], axis=-1))
        theta = dp.windowed_least_squares(
            a, layout.split(coeffs), layout.mask(), column_scale=jnp.array([deg, deg])
        )[0]
        return theta

    batched = jax.jit(jax.vmap(one))
    t0 = time.perf_counter()
    jax.block_until_ready(batched(channels))
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    jax.block_until_ready(batched(channels))
    run = time.perf_counter() - t0
    single = jax.jit(one)
    m = min(args.loop_subset, n)
    subset = [{k: v[i] for k, v in channels.items()} for i in range(m)]
    jax.block_until_ready(single(subset[0]))
    t0 = time.perf_counter()
    for c in subset:
        jax.block_until_ready(single(c))
    loop_per_flight = (time.perf_counter() - t0) / m
    result = {
        "training": {
            "flights": 3,
            "epochs": int(hist.epochs),
            "seconds": train_s,
            "seconds_per_epoch": train_s / max(int(hist.epochs), 1),
        },
        "inference_plus_lse": {
            "flights": n,
            "compile_plus_first_run_s": first,
            "run_s": run,
            "run_s_per_flight": run / n,
        },
        "loop_of_single_flights_s_per_flight": loop_per_flight,
        "speedup_batched_vs_loop": loop_per_flight * n / run,
        "thesis": {"training_s": 3600, "s_per_flight": 6.75},
        "speedup_vs_thesis_per_flight": 6.75 / (run / n),
        "devices": len(jax.devices()),
        "jax": jax.__version__,
    }
    path = pathlib.Path(__file__).parent / "results" / "nn.json"
    path.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
