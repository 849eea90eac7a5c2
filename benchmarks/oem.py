"""Benchmark: the output-error method on Pegasus flights.

- ours: multiple-shooting OEM (0.5 s windows, derivatives linear in time, nodes
  every 2 s, 200 Hz, exact Jacobians, structured Levenberg-Marquardt) on one flight,
  and on a batch of flights in one vmapped call, one slice per core; compile and run
  time separately;
- the straightforward alternative a user would write, in the same run:
  `scipy.optimize.least_squares` with finite-difference Jacobians, one window at a
  time (single shooting from the measured state, fixed weights), calling the same
  jitted model for the residuals; timed on a subset of windows and extrapolated to the
  flight. The thesis quotes about 20 min per flight (MATLAB).

Writes `benchmarks/results/oem.json`. Run: `python benchmarks/oem.py [--batch 4]`.
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
import numpy as np  # noqa: E402
import scipy.optimize  # noqa: E402

import diffpegasus as dp  # noqa: E402
from diffpegasus._estimate._engine import segment_outputs  # noqa: E402
from diffpegasus._estimate._pegasus_oem import measured_states  # noqa: E402


def timed(fn):
    t0 = time.perf_counter()
    out = jax.block_until_ready(fn())
    return out, time.perf_counter() - t0


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--batch", type=int, default=4)
    parser.add_argument("--scipy-windows", type=int, default=8)
    args = parser.parse_args()
    config = dp.PegasusConfig()
    logs = [
        dp.flight_to_log(dp.simulate(p.apply(config), jax.random.key(i)))
        for i, p in enumerate(
            jax.tree_util.tree_map(
                lambda x, i=i: x[i],
                dp.sample_perturbations(jax.random.key(9), args.batch),
            )
            for i in range(args.batch)
        )
    ]
    oem = dp.pegasus.estimate_oem
    _, first = timed(lambda: oem(logs[0], parameters="linear").values)
    _, single_run = timed(lambda: oem(logs[0], parameters="linear").values)

    setups = [dp.pegasus.oem_setup(log, parameters="linear")[0] for log in logs]
    stacked = jax.tree_util.tree_map(lambda *x: jnp.stack(x), *setups)

    def batch_fn(batch):
        return jax.vmap(lambda s: s.fit().params)(batch)

    # one slice of the batch per core (shard_map), as the Monte Carlo runs it
    _, batch_first = timed(lambda: dp.map_over_devices(batch_fn, stacked))
    _, batch_run = timed(lambda: dp.map_over_devices(batch_fn, stacked))
    thetas = [s.theta0 for s in setups]

    # The straightforward alternative, on a subset of windows after ignition: a
    # window of the fit's data layout is one segment of the engine's simulation.
    model, data = setups[0].model, setups[0].data
    length = setups[0].windows.window
    sigma = jnp.asarray(
        [0.05, 0.05, np.deg2rad(0.1), np.deg2rad(1.0), np.deg2rad(0.1), 0.5]
    )

    @jax.jit
    def residual(theta, w, x0):
        y, _ = segment_outputs(model, data, w, x0, theta, jnp.zeros(0))
        return ((data.measured[w] - y) / sigma[None, :]).reshape(-1)

    log0 = logs[0]
    meas_states = measured_states(log0)[::5]
    windows = list(range(20, 20 + args.scipy_windows))
    residual(thetas[0][20], 20, jnp.asarray(meas_states[20 * length]))  # compile once
    t0 = time.perf_counter()
    for w in windows:
        x0 = jnp.asarray(meas_states[w * length])
        scipy.optimize.least_squares(
            lambda th, w=w, x0=x0: np.asarray(residual(jnp.asarray(th), w, x0)),
            np.asarray(thetas[0][w]),
            jac="2-point",
            method="trf",
            xtol=1e-8,
            ftol=1e-8,
        )
    scipy_per_window = (time.perf_counter() - t0) / len(windows)
    n_windows = setups[0].windows.n_windows
    scipy_per_flight = scipy_per_window * n_windows
    result = {
        "what": "Pegasus OEM, 161 windows of 0.5 s, 200 Hz, multiple shooting every 2 s",
        "devices": len(jax.devices()),
        "jax": jax.__version__,
        "ours_one_flight": {"compile_plus_first_run_s": first, "run_s": single_run},
        "ours_batch": {
            "flights": args.batch,
            "compile_plus_first_run_s": batch_first,
            "run_s": batch_run,
            "run_s_per_flight": batch_run / args.batch,
        },
        "scipy_fd_per_window_loop": {
            "windows_timed": len(windows),
            "s_per_window": scipy_per_window,
            "s_per_flight_extrapolated": scipy_per_flight,
        },
        "speedup_vs_scipy_per_flight": scipy_per_flight / (batch_run / args.batch),
        "thesis_s_per_flight": 20 * 60,
        "speedup_vs_thesis": 1200 / (batch_run / args.batch),
        "note": "scipy solves each window alone (no nodes, no continuity), a smaller problem",
    }
    path = pathlib.Path(__file__).parent / "results" / "oem.json"
    path.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
