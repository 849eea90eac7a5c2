"""One recursive update: the jit-compiled `update` (and `estimates`) against a plain
NumPy recursive least squares (covariance form, the textbook's few lines), on one
core, for the launch vehicle's regression (3 equations, 9 parameters) and a
short-period model's (3 equations, 5 parameters).

Each update is timed as a flight computer would call it: one sample at a time from
Python, the result blocked on; process CPU time (best of three), since wall time on a
shared machine measures the other processes. Compile time (wall) is reported
separately. Writes
`benchmarks/results/recursive.json`.

Run: `python benchmarks/recursive.py` (pins JAX and BLAS to one thread).
"""

import os


os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false")
for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import json  # noqa: E402
import pathlib  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import diffpegasus as dp  # noqa: E402


jax.config.update("jax_enable_x64", True)


def numpy_rls(theta, p, h, y, lam):
    """Textbook RLS with forgetting, one vector sample: rows one at a time."""
    p = p / lam
    for j in range(h.shape[0]):
        ph = p @ h[j]
        gain = ph / (1.0 + h[j] @ ph)
        theta = theta + gain * (y[j] - h[j] @ theta)
        p = p - np.outer(gain, ph)
    return theta, p


def time_calls(fn, n):
    """Best of three of the process CPU time per call (the machine may be shared:
    wall time then measures the other processes)."""
    best = np.inf
    for _ in range(3):
        start = time.process_time()
        for _ in range(n):
            fn()
        best = min(best, (time.process_time() - start) / n)
    return best


def case(q, p, levels, n=2000):
    rng = np.random.default_rng(0)
    h = rng.normal(size=(q, p))
    y = rng.normal(size=q)
    o = np.zeros(q)
    out = {"equations": q, "parameters": p}
    estimators = {
        "rls": dp.RecursiveLeastSquares(
            forgetting=0.999, derivative=(False,) * q, dt=0.01, levels=levels
        ),
        "rft": dp.RecursiveFourier(
            frequencies=tuple(np.arange(0.1, 1.51, 0.04).tolist()),
            forgetting=0.999,
            derivative=(False,) * q,
            dt=0.01,
        ),
    }
    hj, yj, oj = jnp.asarray(h), jnp.asarray(y), jnp.asarray(o)
    for name, est in estimators.items():
        state = est.init(jnp.zeros(p))
        # the state is donated: updated in place, as a flight computer would
        update = jax.jit(est.update, donate_argnums=0)
        estimates = jax.jit(est.estimates)
        start = time.perf_counter()
        state = jax.block_until_ready(update(state, hj, yj, oj))
        jax.block_until_ready(estimates(state))
        compile_s = time.perf_counter() - start
        holder = [state]

        def one(update=update, holder=holder):
            holder[0] = jax.block_until_ready(update(holder[0], hj, yj, oj))

        def both(update=update, estimates=estimates, holder=holder):
            holder[0] = update(holder[0], hj, yj, oj)
            jax.block_until_ready(estimates(holder[0]))

        out[name] = {
            "compile_s": compile_s,
            "update_ms": 1e3 * time_calls(one, n),
            "update_and_estimates_ms": 1e3 * time_calls(both, n),
        }
    theta, pm = np.zeros(p), np.eye(p) * 1e6
    holder = [(theta, pm)]

    def np_one():
        holder[0] = numpy_rls(*holder[0], h, y, 0.999)

    out["numpy_rls_update_ms"] = 1e3 * time_calls(np_one, n)
    out["rls_update_over_numpy"] = out["rls"]["update_ms"] / out["numpy_rls_update_ms"]
    return out


def main():
    results = {
        "jax": jax.__version__,
        "machine": platform.machine(),
        "load_average_1min": os.getloadavg()[0],
        "launch_vehicle": case(3, 9, levels=12),
        "short_period": case(3, 5, levels=12),
    }
    out = pathlib.Path(__file__).resolve().parent / "results" / "recursive.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(results, indent=2))
    print(json.dumps(results))


if __name__ == "__main__":
    main()
