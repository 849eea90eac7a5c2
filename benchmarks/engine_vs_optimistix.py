"""The engine's own Levenberg-Marquardt loop against the same structured step run
as an optimistix solver (`dp.OutputError(solver=dp.BlockLevenbergMarquardt())`:
`optx.least_squares` takes one step per relaxation of R), and, on the HFB-320
record, against optimistix's stock `LevenbergMarquardt` on the flat residual
vector (R fixed in each solve, the relaxation of det(R) as an outer loop).

Cases:

- `hfb320_single_shooting`: the real HFB-320 record (601 samples, 11 parameters);
- `hfb320_multiple_shooting_2s`: the same, a node every 2 s (30 segments, 131
  unknowns);
- `pegasus_sized_multiple_shooting`: a simulated HFB-320 flight of Pegasus's size
  (80 s at 100 Hz, 8001 samples; a node every 1 s: 80 segments, 331 unknowns).

Compile (first call) and solve (median of 5 calls, the two solvers interleaved so
that the machine's load falls on both alike) are reported separately, with
iterations, det(R) and the largest estimate difference in standard errors.
Writes `benchmarks/results/engine_vs_optimistix.json`.

    python benchmarks/engine_vs_optimistix.py [--quick] [--only CASE]

(`--quick`: without the stock LevenbergMarquardt; `--only CASE`: that case again,
the others kept from the JSON.)
"""

import json
import os
import pathlib
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

import diffpegasus as dp
from diffpegasus._estimate import _engine


# the record beside the repository (as the other HFB-320 benchmarks), or $HFB320_DATA
DATA = pathlib.Path(
    os.environ.get("HFB320_DATA")
    or pathlib.Path(__file__).resolve().parents[2]
    / "shared/data/hfb320/hfb320_1_10.asc"
)
REPEATS = 5


def _cases():
    spec = dp.vehicle_spec("hfb320")
    rec = dp.load_record(spec.model, DATA, spec.columns, x0=spec.x0)
    yield "hfb320_single_shooting", spec.model, rec, dp.SingleShooting()
    # one solve at the penalty's tolerance (settle=None): the comparison is of the
    # two solvers' iterations, which the tightenings would only repeat
    yield (
        "hfb320_multiple_shooting_2s",
        spec.model,
        rec,
        dp.MultipleShooting(interval=2.0, settle=None),
    )
    # the record is simulated when the case runs (None here)
    yield (
        "pegasus_sized_multiple_shooting",
        spec.model,
        None,
        dp.MultipleShooting(interval=1.0, settle=None),
    )


def _pegasus_sized_record():
    from diffpegasus._registry._hfb320_simulator import simulate_log, simulated_record

    channels, _ = simulate_log(duration=80.0, rate=100.0, seed=7)
    return simulated_record(channels, name="pegasus-sized")


def _timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def _cpu_timed(fn):
    """CPU seconds of the process (all threads) spent in `fn`: on a machine shared
    with other work, less noisy than the wall clock."""
    t0 = time.process_time()
    fn()
    return time.process_time() - t0


def _stock_levenberg_marquardt(model, rec, shooting, max_outer=30, rtol=1e-7):
    """optimistix's LevenbergMarquardt on the flat whitened residuals, R fixed per
    solve, det(R) relaxed in an outer loop (the earlier measurement)."""
    first = dp.fit(model, rec, shooting=shooting, max_iter=0, throw=False)
    lay = first.layout
    nx, p = len(model.states), len(model.parameters)
    free = lay.free_columns(jnp.asarray(model.free), nx, p)
    z0 = jnp.asarray(first.z)
    fixed_part = jnp.where(free, 0.0, z0)
    idx = jnp.flatnonzero(free)
    structure = model.structure()

    def residual(y, r):
        z = fixed_part.at[idx].set(y)
        e, d, _ = _engine.residuals_at(structure, lay, z, nx, p)
        return jnp.concatenate([(e / jnp.sqrt(r)).reshape(-1), d.reshape(-1)])

    solver = optx.LevenbergMarquardt(rtol=1e-8, atol=1e-10)

    @jax.jit
    def outer(y0):
        def body(c):
            y, r, cost_prev, it, _, steps = c
            sol = optx.least_squares(
                residual, solver, y, args=r, max_steps=100, throw=False
            )
            z = fixed_part.at[idx].set(sol.value)
            e, _, _ = _engine.residuals_at(structure, lay, z, nx, p)
            r_new = _engine.channel_variance(lay, e)
            cost = jnp.prod(r_new)
            done = jnp.abs(cost - cost_prev) <= rtol * cost
            return sol.value, r_new, cost, it + 1, done, steps + sol.stats["num_steps"]

        e, _, _ = _engine.residuals_at(structure, lay, z0, nx, p)
        r0 = _engine.channel_variance(lay, e)
        init = (y0, r0, jnp.prod(r0), 0, False, 0)
        return jax.lax.while_loop(lambda c: (c[3] < max_outer) & ~c[4], body, init)

    y0 = z0[idx]
    out, cold = _timed(lambda: jax.block_until_ready(outer(y0)))
    times = [_timed(lambda: jax.block_until_ready(outer(y0)))[1] for _ in range(2)]
    return {
        "first_call_s": cold,
        "solve_s": float(np.median(times)),
        "outer_iterations": int(out[3]),
        "inner_steps": int(out[5]),
        "cost": float(out[2]),
    }


def main(quick: bool = False, only: str | None = None):
    out = pathlib.Path(__file__).parent / "results" / "engine_vs_optimistix.json"
    if only is not None and out.exists():
        # one case again, the others kept from the last run
        previous = json.loads(out.read_text())
    else:
        previous = {}
    results = {
        **previous,
        "jax": jax.__version__,
        "optimistix": optx.__version__ if hasattr(optx, "__version__") else "",
        "load_average_at_start": list(np.round(os.getloadavg(), 2)),
    }
    for name, model, rec, shooting in _cases():
        if only is not None and name != only:
            continue
        rec = _pegasus_sized_record() if rec is None else rec
        methods = {
            "engine": dp.OutputError(shooting=shooting),
            "optimistix_block": dp.OutputError(
                shooting=shooting, solver=dp.BlockLevenbergMarquardt()
            ),
        }
        row, fits = {}, {}
        times, cpu = {k: [] for k in methods}, {k: [] for k in methods}
        for key, method in methods.items():
            fits[key], cold = _timed(
                lambda m=method, mo=model, r=rec: dp.estimate(mo, r, m)
            )
            row[key] = {"first_call_s": cold}
        for _ in range(REPEATS):
            for key, method in methods.items():
                cpu[key].append(
                    _cpu_timed(lambda m=method, mo=model, r=rec: dp.estimate(mo, r, m))
                )
                times[key].append(
                    _timed(lambda m=method, mo=model, r=rec: dp.estimate(mo, r, m))[1]
                )
        for key in methods:
            f = fits[key]
            row[key].update(
                solve_s=float(np.median(times[key])),
                solve_s_all=times[key],
                solve_cpu_s=float(np.median(cpu[key])),
                iterations=f.iterations,
                cost=f.cost,
                converged=f.converged,
            )
        a, b = fits["engine"], fits["optimistix_block"]
        row["solve_time_ratio_optimistix_block_over_engine"] = (
            row["optimistix_block"]["solve_s"] / row["engine"]["solve_s"]
        )
        row["solve_cpu_ratio_optimistix_block_over_engine"] = (
            row["optimistix_block"]["solve_cpu_s"] / row["engine"]["solve_cpu_s"]
        )
        row["first_call_ratio_optimistix_block_over_engine"] = (
            row["optimistix_block"]["first_call_s"] / row["engine"]["first_call_s"]
        )
        row["cost_ratio_optimistix_block_over_engine"] = b.cost / a.cost
        row["largest_estimate_difference_in_stderr"] = float(
            np.max(np.abs(a.params - b.params) / a.stderr)
        )
        row["unknowns"] = int(a.z.shape[0])
        row["samples"] = len(rec.t)
        if name == "hfb320_single_shooting" and not quick:
            row["optimistix_stock_lm"] = _stock_levenberg_marquardt(
                model, rec, shooting
            )
            row["solve_time_ratio_stock_lm_over_engine"] = (
                row["optimistix_stock_lm"]["solve_s"] / row["engine"]["solve_s"]
            )
        results[name] = row
        print(name, json.dumps(row, indent=1), flush=True)
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    args = sys.argv[1:]
    main(
        quick="--quick" in args,
        only=args[args.index("--only") + 1] if "--only" in args else None,
    )
