"""Benchmark: windowed least squares on 100 Pegasus flights (80.3 s at 1 kHz, 0.5 s
windows), batched and jitted, against a straightforward per-window numpy loop on the
same data (timed on a subset of flights and extrapolated). Compile and run time are
reported separately. The thesis quotes about 3.5 s per flight (6 min per 100) in MATLAB.
Writes `benchmarks/results/lse.json`.

Run: `python benchmarks/lse.py [--flights 100] [--loop-subset 10]`.
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


def numpy_lse(c, per, s_ref=13.5, c_ref=2.48, tol=1e-2):
    """What a user would write by hand: reconstruct, then loop over windows."""
    qs = c["qbar"] * s_ref
    fz = c["mass"] * c["az"]
    cx = (c["mass"] * c["ax"] - c["thrust"]) / qs
    cz = fz / qs
    cm = (c["Iyy"] * c["qdot"] + c["Iyy_dot"] * c["q"] - (c["xcp"] - c["xcg"]) * fz) / (
        qs * c_ref
    )
    sa, ca = np.sin(c["alpha"]), np.cos(c["alpha"])
    cl, cd = cx * sa - cz * ca, -cx * ca - cz * sa
    n = len(cl) // per
    out = np.full((n, 6), np.nan)
    prev = np.full(6, np.nan)
    for k in range(n):
        s = slice(k * per, (k + 1) * per)
        a = np.column_stack([c["alpha"][s], c["de"][s]])
        ad = np.rad2deg(a)
        if (
            np.linalg.matrix_rank(ad, tol) == 2
            and np.linalg.matrix_rank(ad.T @ ad, tol) == 2
        ):
            theta = np.linalg.lstsq(
                a, np.column_stack([cl[s], cd[s], cm[s]]), rcond=None
            )[0]
            prev = theta.T.reshape(6)
        out[k] = prev
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--flights", type=int, default=100)
    parser.add_argument("--loop-subset", type=int, default=10)
    args = parser.parse_args()
    n = args.flights
    config = dp.PegasusConfig()
    flights = dp.simulate_batch(
        config,
        dp.shard_batch(jax.random.split(jax.random.key(1), n)),
        dp.shard_batch(dp.sample_perturbations(jax.random.key(0), n)),
    )
    channels = jax.block_until_ready(dict(flights.channels))
    layout = dp.WindowLayout.make(channels["az"].shape[1], 1000.0, 0.5)

    t0 = time.perf_counter()
    jax.block_until_ready(dp.lse_batch(channels, layout))
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    out = jax.block_until_ready(dp.lse_batch(channels, layout))
    run = time.perf_counter() - t0

    m = min(args.loop_subset, n)
    host = {k: np.asarray(v[:m]) for k, v in channels.items()}
    t0 = time.perf_counter()
    loop = [
        numpy_lse({k: v[i] for k, v in host.items()}, layout.per_window)
        for i in range(m)
    ]
    loop_per_flight = (time.perf_counter() - t0) / m
    full = layout.count if layout.last == layout.per_window else layout.count - 1
    agree = max(
        float(np.nanmax(np.abs(np.asarray(out["values"][i, :full]) - loop[i][:full])))
        for i in range(m)
    )
    result = {
        "what": f"LSE on {n} flights x {layout.count} windows of 0.5 s at 1 kHz",
        "devices": len(jax.devices()),
        "jax": jax.__version__,
        "batched": {
            "compile_plus_first_run_s": first,
            "compile_s_estimate": first - run,
            "run_s": run,
            "run_s_per_flight": run / n,
        },
        "numpy_per_window_loop": {
            "flights_timed": m,
            "run_s_per_flight": loop_per_flight,
            "run_s_extrapolated": loop_per_flight * n,
        },
        "speedup_batched_vs_loop": loop_per_flight * n / run,
        "max_abs_difference_between_the_two_per_rad": agree,
        "thesis_s_per_flight": 3.5,
        "speedup_vs_thesis": 3.5 * n / run,
    }
    path = pathlib.Path(__file__).parent / "results" / "lse.json"
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
