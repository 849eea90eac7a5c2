"""The engine's structured Levenberg-Marquardt against optimistix's on the same
output-error problems, in one run: the HFB-320 record (single shooting, 11
parameters) and the same record with multiple shooting (a node every 2 s: 30
segments, 131 unknowns).

optimistix gets the flat whitened residual vector (R fixed inside each solve, the
standard relaxation of det(R) as an outer loop, as `fit` does between steps) and
linearises it whole; the engine differentiates each segment in its own unknowns only.
Writes `benchmarks/results/engine_vs_optimistix.json`: wall times (compile and solve
separately, median of 3 solves), iterations and det(R) of both.
"""

import json
import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

import diffpegasus as dp
from diffpegasus._estimate import _engine


DATA = (
    pathlib.Path(__file__).resolve().parents[2] / "shared/data/hfb320/hfb320_1_10.asc"
)


def _setup(shooting):
    spec = dp.vehicle_spec("hfb320")
    rec = dp.load_record(spec.model, DATA, spec.columns, x0=spec.x0)
    first = dp.fit(spec.model, rec, shooting=shooting, max_iter=0, throw=False)
    return spec.model, rec, first


def _engine_run(model, rec, shooting):
    t0 = time.perf_counter()
    res = dp.fit(model, rec, shooting=shooting)
    cold = time.perf_counter() - t0
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        res = dp.fit(model, rec, shooting=shooting)
        times.append(time.perf_counter() - t0)
    return {
        "first_call_s": cold,
        "solve_s": float(np.median(times)),
        "iterations": res.iterations,
        "cost": res.cost,
    }


def _optimistix_run(model, first, max_outer=30, rtol=1e-7):
    lay = first.layout
    nx, p = len(model.states), len(model.parameters)
    free = lay.free_columns(jnp.asarray(model.free), nx, p)
    z0 = jnp.asarray(first.z)
    fixed_part = jnp.where(free, 0.0, z0)
    idx = jnp.flatnonzero(free)

    def residual(y, r):
        z = fixed_part.at[idx].set(y)
        e, d, _ = _engine.residuals_at(model, lay, z, nx, p)
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
            e, _, _ = _engine.residuals_at(model, lay, z, nx, p)
            r_new = _engine.channel_variance(lay, e)
            cost = jnp.prod(r_new)
            done = jnp.abs(cost - cost_prev) <= rtol * cost
            return sol.value, r_new, cost, it + 1, done, steps + sol.stats["num_steps"]

        e, _, _ = _engine.residuals_at(model, lay, z0, nx, p)
        r0 = _engine.channel_variance(lay, e)
        init = (y0, r0, jnp.prod(r0), 0, False, 0)
        return jax.lax.while_loop(lambda c: (c[3] < max_outer) & ~c[4], body, init)

    y0 = z0[idx]
    t0 = time.perf_counter()
    out = jax.block_until_ready(outer(y0))
    cold = time.perf_counter() - t0
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        out = jax.block_until_ready(outer(y0))
        times.append(time.perf_counter() - t0)
    return {
        "first_call_s": cold,
        "solve_s": float(np.median(times)),
        "outer_iterations": int(out[3]),
        "inner_steps": int(out[5]),
        "cost": float(out[2]),
    }


def main():
    results = {}
    for name, shooting in (
        ("hfb320_single_shooting", dp.SingleShooting()),
        ("hfb320_multiple_shooting_2s", dp.MultipleShooting(interval=2.0)),
    ):
        model, rec, first = _setup(shooting)
        eng = _engine_run(model, rec, shooting)
        opt = _optimistix_run(model, first)
        results[name] = {
            "engine": eng,
            "optimistix": opt,
            "solve_time_ratio_optimistix_over_engine": opt["solve_s"] / eng["solve_s"],
            "cost_ratio_optimistix_over_engine": opt["cost"] / eng["cost"],
        }
        print(name, json.dumps(results[name], indent=1))
    out = pathlib.Path(__file__).parent / "results" / "engine_vs_optimistix.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
