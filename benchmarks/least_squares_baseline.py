"""Benchmark: the output-error engine against `scipy.optimize.least_squares` with a
sparse finite-difference Jacobian on the same problems (same unknowns, same data,
same residuals, same optimum), and the arithmetic limit of one iteration.

Problems:

- `pegasus_windowed`: the per-window Pegasus OEM of `estimate oem` (0.5 s windows,
  derivatives linear in time, nodes every 2 s, 200 Hz, windows below 2 kPa not
  fitted), one simulated flight at a time: `dp.fit_windowed_oem` from `dp.oem_setup`;
- `pegasus_global`: the launch vehicle's discrepancy model of `compare`
  (`dp.vehicle_entry("pegasus").problem([log], candidates=True)` with `dp.fit`: 90
  aerodynamic parameters estimated, the candidate effects and the Mach breakpoints
  held, nodes every 1 s, 50 Hz) on the same flights;
- `hfb320`: the HFB-320 record with `dp.fit` (single shooting, 11 parameters).

scipy gets the engine's own jitted residual function (`residuals_at`: the same model,
RK4 and layout), the whitened output residuals and continuity defects as one vector,
only the free unknowns, a `jac_sparsity` pattern from the layout (a segment's rows
depend on its own local unknowns, a defect on two neighbouring nodes and the shared
parameters) and `method="trf", tr_solver="lsmr", x_scale="jac"` (what scipy offers for
sparse problems). R is relaxed as the engine does between steps, in an outer loop (R
fixed inside each `least_squares`, re-estimated after it) until det(R) changes by less
than the engine's `rtol`. The optimum is checked: det(R) of both, and the largest
parameter difference in units of the engine's standard errors.

Arithmetic limit: flops of one Jacobian (samples x (4 RK4 stages x the forward-mode
cost of the state equations with the segment's local tangents + the output
equations)), of the normal-equation assembly (`J^T J` per segment) and of the dense
Cholesky solve, counted by XLA's cost analysis of the unlooped model functions; over
the machine's dense matmul rate (measured here) they give the time one iteration
would take at peak, against the measured time per iteration.

Writes `benchmarks/results/least_squares_baseline.json`. Run: `python
benchmarks/least_squares_baseline.py [--flights 2]`.
"""

import argparse
import json
import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np
import scipy.optimize
import scipy.sparse
from scipy.optimize._numdiff import group_columns

import diffpegasus as dp
from diffpegasus._estimate import _engine
from diffpegasus._estimate._windowed_oem import _make_layout, windowed_start


HERE = pathlib.Path(__file__).resolve().parent
HFB = HERE.parents[1] / "shared/data/hfb320/hfb320_1_10.asc"
BUDGET = 400.0  # s per scipy fit; the ratio is then a lower bound


CPU = {}  # CPU seconds (this process, all threads) of the last timed() call


def timed(fn):
    t0, c0 = time.perf_counter(), time.process_time()
    out = jax.block_until_ready(fn())
    CPU["last"] = time.process_time() - c0
    return out, time.perf_counter() - t0


# ---------------------------------------------------------------- scipy's side


def sparsity(layout, nx, p, free):
    """`jac_sparsity` of the residual vector `[valid output rows, defects]` in the
    free unknowns, and the row mask of valid outputs."""
    local = np.asarray(layout.local_columns(nx, p))
    nodes = np.asarray(layout.node_columns(nx, p))
    valid = np.asarray(layout.valid)
    n_out = layout.measured.shape[-1]
    rows, cols = [], []
    row = 0
    for s in range(local.shape[0]):
        n = int(valid[s].sum()) * n_out
        r = row + np.arange(n)
        rows.append(np.repeat(r, local.shape[1]))
        cols.append(np.tile(local[s], n))
        row += n
    for s in range(local.shape[0] - 1):
        # a defect row depends on the segment's local unknowns and the next node
        c = np.concatenate([local[s], nodes[s + 1]])
        r = row + np.arange(nx)
        rows.append(np.repeat(r, len(c)))
        cols.append(np.tile(c, nx))
        row += nx
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    index = -np.ones(free.shape[0], int)
    index[free] = np.arange(free.sum())
    keep = index[cols] >= 0
    pattern = scipy.sparse.coo_matrix(
        (np.ones(keep.sum()), (rows[keep], index[cols[keep]])),
        shape=(row, int(free.sum())),
    ).tocsr()
    pattern.data[:] = 1.0
    return pattern


class _OutOfTime(Exception):
    pass


def scipy_fit(model, layout, z0, free, nx, p, rtol, max_outer=20, budget=BUDGET):
    """Relaxed det(R) by `least_squares` (trf, lsmr, sparse finite differences);
    stops after `budget` seconds (then `converged` is false and the cost is the one
    reached)."""
    free = np.asarray(free)
    valid = np.asarray(layout.valid)
    link = np.asarray(layout.link)
    z_fixed = np.asarray(z0, float).copy()

    @jax.jit
    def resid(z, w):
        e, d, _ = _engine.residuals_at(model, layout, z, nx, p)
        return e * w[None, None, :], d

    def full(y):
        z = z_fixed.copy()
        z[free] = y
        return z

    best = {}

    def vector(y, w):
        if time.perf_counter() - t0 > budget:
            raise _OutOfTime
        e, d = resid(jnp.asarray(full(y)), jnp.asarray(w))
        e, d = np.asarray(e), np.asarray(d)
        f = np.concatenate([e[valid].ravel(), d[link].ravel()])
        cost = float(f @ f)
        if cost < best.get("cost", np.inf):
            best.update(cost=cost, y=np.array(y))
        return f

    def variance(y):
        e, _ = resid(jnp.asarray(full(y)), jnp.ones(layout.measured.shape[-1]))
        e = np.asarray(e)[valid]
        return np.mean(e**2, axis=0)

    pattern = sparsity(layout, nx, p, free)
    groups = int(group_columns(pattern).max() + 1)
    y = np.asarray(z0)[free]
    t0 = time.perf_counter()
    vector(y, np.ones(layout.measured.shape[-1]))  # compile
    t0, c0 = time.perf_counter(), time.process_time()
    r = variance(y)
    cost = float(np.prod(r))
    nfev = njev = 0
    outer = 0
    converged = out_of_time = False
    for outer in range(1, max_outer + 1):  # noqa: B007 (reported)
        w = 1.0 / np.sqrt(r)
        best.clear()
        try:
            res = scipy.optimize.least_squares(
                vector,
                y,
                jac_sparsity=pattern,
                method="trf",
                tr_solver="lsmr",
                x_scale="jac",
                args=(w,),
            )
            y = res.x
            nfev += res.nfev
            njev += res.njev or 0
        except _OutOfTime:
            out_of_time = True
            y = best.get("y", y)
        r = variance(y)
        new = float(np.prod(r))
        print(
            f"   scipy outer {outer}: det(R) {new:.6e}, {time.perf_counter() - t0:.0f} s",
            flush=True,
        )
        done = abs(cost - new) <= rtol * abs(new)
        cost = new
        if done and not out_of_time:
            converged = True
        if done or out_of_time:
            break
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    # one residual evaluation, timed alone
    budget = np.inf
    t1 = time.perf_counter()
    for _ in range(5):
        vector(y, w)
    per_eval = (time.perf_counter() - t1) / 5
    return {
        "wall_s": wall,
        "cpu_s": cpu,
        "cost": cost,
        "z": full(y),
        "outer_iterations": outer,
        "converged": converged,
        "stopped_at_budget_s": wall if out_of_time else None,
        "nfev_total_completed_solves": int(nfev),
        "jacobians_completed_solves": int(njev),
        "fd_groups_per_jacobian": groups,
        "residual_eval_s": per_eval,
        "residual_rows": pattern.shape[0],
        "free_unknowns": pattern.shape[1],
        "jacobian_nonzeros": int(pattern.nnz),
    }


# ---------------------------------------------------------------- flop counts


def flops(fn, *args):
    return float(jax.jit(fn).lower(*args).compile().cost_analysis()["flops"])


def model_flops(f, g, x, u, th, k, theta_linear=False):
    """Flops of the state and output equations, plain and with `k` forward-mode
    tangents (`jax.jacfwd` in the local unknowns `[x, theta]`; `theta_linear`: the
    parameters interpolated between two knots, as the windowed fit does)."""
    nx, p = x.shape[0], th.shape[0]

    def pack(v):
        xx = v[:nx]
        tt = v[nx : nx + p]
        if theta_linear:
            tt = 0.5 * (tt + v[nx + p : nx + 2 * p])
        return xx, tt

    v = jnp.concatenate([x, th] + ([th] if theta_linear else []))
    pad = k - v.shape[0]
    v = jnp.concatenate([v, jnp.zeros(max(pad, 0))])

    def fv(v):
        xx, tt = pack(v)
        return f(0.0, xx, u, tt)

    def gv(v):
        xx, tt = pack(v)
        return g(0.0, xx, u, tt)

    return {
        "f": flops(fv, v),
        "g": flops(gv, v),
        "f_jacfwd": flops(jax.jacfwd(fv), v),
        "g_jacfwd": flops(jax.jacfwd(gv), v),
    }


def arithmetic(mf, samples, k, nx, n_out, segments, n_unknowns, gflops):
    """Flops of one iteration's pieces and the time they take at `gflops`."""
    rk4 = 4 * 2 * nx * (k + 1) * 2  # the stage combinations, value and tangents
    jac = samples * (4 * mf["f_jacfwd"] + mf["g_jacfwd"] + rk4)
    sim = samples * (4 * mf["f"] + mf["g"] + 4 * 2 * nx * 2)
    assembly = 2.0 * samples * n_out * k * k + 2.0 * segments * nx * (k + nx) ** 2
    cholesky = n_unknowns**3 / 3 + 2 * n_unknowns**2
    total = jac + assembly + cholesky
    return {
        "gflops_used": gflops,
        "flops_simulation": sim,
        "flops_jacobian": jac,
        "flops_normal_assembly": assembly,
        "flops_cholesky": cholesky,
        "flops_iteration": total + sim,  # one trial simulation per iteration at least
        "s_at_peak_jacobian": jac / gflops / 1e9,
        "s_at_peak_assembly": assembly / gflops / 1e9,
        "s_at_peak_cholesky": cholesky / gflops / 1e9,
        "s_at_peak_iteration": (total + sim) / gflops / 1e9,
    }


def matmul_gflops():
    a = np.random.default_rng(0).normal(size=(1500, 1500))
    a @ a
    t0 = time.perf_counter()
    for _ in range(5):
        a @ a
    return 5 * 2 * 1500**3 / (time.perf_counter() - t0) / 1e9


# ---------------------------------------------------------------- problems


def flights(n):
    config = dp.PegasusConfig()
    perts = dp.sample_perturbations(jax.random.key(9), n)
    out = []
    for i in range(n):
        p = jax.tree_util.tree_map(lambda x, i=i: x[i], perts)
        out.append(dp.flight_to_log(dp.simulate(p.apply(config), jax.random.key(i))))
    return out


def compare(name, ours, sc, se, ours_params, scipy_params):
    diff = np.abs(np.asarray(ours_params) - np.asarray(scipy_params))
    ok = np.isfinite(se) & (se > 0)
    return {
        "problem": name,
        "ours_solve_s": ours["solve_s"],
        "ours_iterations": ours["iterations"],
        "ours_s_per_iteration": ours["solve_s"] / max(ours["iterations"], 1),
        "ours_cost": ours["cost"],
        "ours_solve_cpu_s": ours["cpu_s"],
        "scipy": {k: v for k, v in sc.items() if k != "z"},
        "ratio_scipy_over_ours": sc["wall_s"] / ours["solve_s"],
        "cpu_ratio_scipy_over_ours": sc["cpu_s"] / ours["cpu_s"],
        "cost_ratio_scipy_over_ours": sc["cost"] / ours["cost"],
        "max_param_diff_in_stderr": float(np.max(diff[ok] / se[ok])),
    }


def windowed(logs, gflops):
    rows = []
    for i, log in enumerate(logs):
        setup = dp.oem_setup(log, parameters="linear")[0]
        windows, model = setup.windows, setup.model

        def ours_fit(setup=setup):
            return setup.fit()

        compile_s = None
        if i == 0:
            _, compile_s = timed(ours_fit)
        fit, solve_s = timed(ours_fit)
        solve_cpu = CPU["last"]
        print(f"windowed flight {i}: ours {solve_s:.2f} s", flush=True)
        p = setup.theta0.shape[1]
        held = jnp.zeros(setup.theta0.shape, bool)
        layout = _make_layout(
            model, setup.data, windows, setup.active, held, (False,) * p
        )
        nx = layout.nx
        cols = layout.knot_cols()
        z0 = windowed_start(model, windows, setup.theta0, setup.nodes0, True)
        free = np.asarray(layout.free_columns(None, nx, p))
        sc = scipy_fit(model, layout, z0, free, nx, p, rtol=1e-5, budget=BUDGET)
        # window means of the scipy knots, as the fit reports them
        zk = sc["z"][cols[: windows.n_windows + 1]]
        sc_params = 0.5 * (zk[:-1] + zk[1:])
        active = np.asarray(setup.active)
        row = compare(
            f"flight {i}",
            {"solve_s": solve_s, "cpu_s": solve_cpu,
             "iterations": int(fit.iterations), "cost": float(fit.cost)},
            sc, np.asarray(fit.stderr)[active], np.asarray(fit.params)[active],
            sc_params[active],
        )  # fmt: skip
        row["ours_compile_plus_first_s"] = compile_s
        samples = int(np.asarray(layout.valid).size)
        k = int(layout.local_cols().shape[1])
        u = setup.data.inputs[0][100]
        mf = model_flops(
            model.f, model.g, setup.nodes0[5], u, setup.theta0[20], k, True
        )
        row["arithmetic"] = arithmetic(
            mf, samples, k, nx, len(model.outputs), windows.segments,
            int(free.sum()), gflops,
        )  # fmt: skip
        row["arithmetic"]["model_flops"] = mf
        rows.append(row)
        print(json.dumps(row, indent=1), flush=True)
    return rows


def global_fit(logs, gflops):
    entry = dp.vehicle_entry("pegasus")
    rows = []
    for i, log in enumerate(logs):
        spec, records = entry.problem([log], candidates=True)  # what `compare` fits
        model = spec.model
        options = dict(shooting=spec.shooting, initial_state=spec.initial_state)
        compile_s = None

        def run(model=model, records=records, options=options):
            return dp.fit(model, records, **options)

        if i == 0:
            _, compile_s = timed(lambda run=run: run().params)
        res, solve_s = timed(run)
        solve_cpu = CPU["last"]
        print(f"global flight {i}: ours {solve_s:.2f} s", flush=True)
        first = dp.fit(model, records, max_iter=0, throw=False, **options)
        lay = first.layout
        nx, p = len(model.states), len(model.parameters)
        free = np.asarray(lay.free_columns(jnp.asarray(model.free), nx, p))
        sc = scipy_fit(
            model, lay, jnp.asarray(first.z), free, nx, p, rtol=1e-5, budget=BUDGET
        )
        ns = lay.n_segments * nx
        aero = np.flatnonzero(model.free)
        row = compare(
            f"flight {i}",
            {"solve_s": solve_s, "cpu_s": solve_cpu,
             "iterations": int(res.iterations), "cost": float(res.cost)},
            sc, np.asarray(res.stderr)[aero], np.asarray(res.params)[aero],
            sc["z"][ns : ns + p][aero],
        )  # fmt: skip
        row["ours_compile_plus_first_s"] = compile_s
        samples = int(np.asarray(lay.valid).size)
        k = int(lay.local_columns(nx, p).shape[1])
        rec = records[0]
        mf = model_flops(
            model.f, model.g, jnp.asarray(first.nodes[3]), jnp.asarray(rec.inputs[100]),
            jnp.asarray(model.start), k,
        )  # fmt: skip
        row["arithmetic"] = arithmetic(
            mf, samples, k, nx, len(model.outputs), lay.n_segments, int(free.sum()),
            gflops,
        )  # fmt: skip
        row["arithmetic"]["model_flops"] = mf
        rows.append(row)
        print(json.dumps(row, indent=1), flush=True)
    return rows


def hfb320(gflops):
    spec = dp.vehicle_spec("hfb320")
    rec = dp.load_record(spec.model, HFB, spec.columns, x0=spec.x0)
    model = spec.model
    first = dp.fit(model, rec, max_iter=0, throw=False)
    _, compile_s = timed(lambda: dp.fit(model, rec).params)
    times, cpus = [], []
    for _ in range(3):
        fit, t = timed(lambda: dp.fit(model, rec))
        times.append(t)
        cpus.append(CPU["last"])
    nx, p = len(model.states), len(model.parameters)
    lay = first.layout
    free = np.asarray(lay.free_columns(jnp.asarray(model.free), nx, p))
    sc = scipy_fit(
        model, lay, jnp.asarray(first.z), free, nx, p, rtol=1e-5, budget=BUDGET
    )
    ns = lay.n_segments * nx
    row = compare(
        "hfb320_1_10",
        {"solve_s": float(np.median(times)), "cpu_s": float(np.median(cpus)),
         "iterations": int(fit.iterations), "cost": float(fit.cost)},
        sc, np.asarray(fit.stderr), np.asarray(fit.params), sc["z"][ns : ns + p],
    )  # fmt: skip
    row["ours_compile_plus_first_s"] = compile_s
    return row


def main():
    global BUDGET
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--flights", type=int, default=2)
    parser.add_argument("--skip", nargs="*", default=[])
    parser.add_argument("--budget", type=float, default=BUDGET)
    parser.add_argument(
        "--update", action="store_true", help="keep the other problems' results"
    )
    args = parser.parse_args()
    BUDGET = args.budget
    gflops = matmul_gflops()
    result = {
        "what": "the engine against scipy.optimize.least_squares (trf, lsmr, sparse "
        "finite-difference Jacobian by jac_sparsity) on the same output-error "
        "problems; ratio = scipy wall / ours (solve only, compiled)",
        "jax": jax.__version__,
        "devices": len(jax.devices()),
        "matmul_gflops_measured": gflops,
    }
    if "hfb320" not in args.skip:
        result["hfb320"] = hfb320(gflops)
        print(json.dumps(result["hfb320"], indent=1), flush=True)
    logs = flights(args.flights) if args.flights else []
    if "windowed" not in args.skip:
        result["pegasus_windowed"] = windowed(logs, gflops)
    if "global" not in args.skip:
        result["pegasus_global"] = global_fit(logs, gflops)
    out = HERE / "results" / "least_squares_baseline.json"
    if args.update and out.exists():
        old = json.loads(out.read_text())
        old.update({k: v for k, v in result.items() if v != []})
        result = old
    out.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
