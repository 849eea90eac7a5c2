"""Benchmark: the HFB-320 fit as a user feels it, a whole process, against the
straightforward independent JAX Gauss-Newton (`hfb320_gauss_newton.py`, no code
shared with the package) reaching the same optimum.

- ours: `diffpegasus fit hfb320_1_10.asc --vehicle hfb320 --json`;
- baseline: `python benchmarks/hfb320_gauss_newton.py hfb320_1_10.asc`.

Both as fresh processes, 3 pairs in alternating order, with the persistent
compilation cache cold (a new empty folder for every process) and warm (each
program's own folder, filled by one run before the pairs; the baseline gets the same
cache settings the package uses, `JAX_COMPILATION_CACHE_DIR` and a 0.1 s threshold).
The ratio is ours / baseline per pair, reported as the median, of wall time and of
CPU time (user + system: on a shared, loaded machine wall time also counts waiting
for a core); det(R) of both is checked to agree to 1e-6.

Then where our time goes: one warm run in-process with JAX's monitoring events
(import, tracing, lowering to MLIR, XLA compilation, persistent-cache reads, the
rest: execution, Python, output) and `python -X importtime` (the slowest imports).

Writes `benchmarks/results/hfb320_process.json`. Run: `python
benchmarks/hfb320_process.py [--pairs 3]`.
"""

import argparse
import json
import os
import pathlib
import resource
import statistics
import subprocess
import sys
import tempfile
import time


HERE = pathlib.Path(__file__).resolve().parent
DATA = HERE.parents[1] / "shared/data/hfb320/hfb320_1_10.asc"
OURS = [sys.executable, "-m", "diffpegasus", "fit", str(DATA), "--vehicle", "hfb320"]
OURS += ["--json"]
BASELINE = [sys.executable, str(HERE / "hfb320_gauss_newton.py"), str(DATA)]
REFERENCE_COST = 3.016139e-24  # FVSysID


def run(cmd, cache_dir):
    env = dict(os.environ)
    for k in ("DIFFPEGASUS_NO_CACHE", "JAX_COMPILATION_CACHE_DIR"):
        env.pop(k, None)
    env["JAX_COMPILATION_CACHE_DIR"] = str(cache_dir)
    env["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"] = "0.1"
    env["JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES"] = "0"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode:
        raise RuntimeError(f"{cmd} failed:\n{out.stderr[-3000:]}")
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("{")][-1]
    res = json.loads(line)
    # CPU seconds (user + system) of the process: on a shared, loaded machine the
    # wall time also counts the waiting for a core
    res["cpu_s"] = (after.ru_utime - before.ru_utime) + (
        after.ru_stime - before.ru_stime
    )
    return wall, res


def pairs(n, cold, root):
    rows = []
    warm_dirs = {"ours": root / "warm_ours", "baseline": root / "warm_baseline"}
    if not cold:
        for name, cmd in (("ours", OURS), ("baseline", BASELINE)):
            run(cmd, warm_dirs[name])  # fill the cache
    for i in range(n):
        order = [("ours", OURS), ("baseline", BASELINE)]
        if i % 2:
            order.reverse()
        row = {"first": order[0][0]}
        for name, cmd in order:
            cache = root / f"cold_{name}_{i}" if cold else warm_dirs[name]
            wall, res = run(cmd, cache)
            row[name] = {"wall_s": wall, "cpu_s": res["cpu_s"], "cost": res["cost"]}
            row[name]["iterations"] = res["iterations"]
        row["ratio"] = row["ours"]["wall_s"] / row["baseline"]["wall_s"]
        row["cpu_ratio"] = row["ours"]["cpu_s"] / row["baseline"]["cpu_s"]
        agree = abs(row["ours"]["cost"] / row["baseline"]["cost"] - 1)
        row["cost_rel_diff"] = agree
        if agree > 1e-6:
            raise RuntimeError(f"different optima: {row}")
        rows.append(row)
        print(json.dumps(row), flush=True)
    return {
        "pairs": rows,
        "median_ratio": statistics.median(r["ratio"] for r in rows),
        "median_cpu_ratio": statistics.median(r["cpu_ratio"] for r in rows),
        "median_ours_s": statistics.median(r["ours"]["wall_s"] for r in rows),
        "median_baseline_s": statistics.median(r["baseline"]["wall_s"] for r in rows),
    }


def phases_in_process(out_path):
    """Run the command in this process with JAX's monitoring listeners; write the
    time per phase to `out_path`."""
    t_start = time.perf_counter()
    from jax._src import monitoring

    spans: dict[str, list] = {}
    counts: dict[str, int] = {}
    durations: dict[str, float] = {}

    def on_span(event, start, end, **kw):
        spans.setdefault(event, []).append((start, end))

    def on_duration(event, d, **kw):
        durations[event] = durations.get(event, 0.0) + d
        counts[event] = counts.get(event, 0) + 1

    monitoring.register_event_time_span_listener(on_span)
    monitoring.register_event_duration_secs_listener(on_duration)
    t_import = time.perf_counter()
    import diffpegasus  # noqa: F401

    import_s = time.perf_counter() - t_import
    import runpy

    sys.argv = ["diffpegasus", *OURS[3:]]
    t_run = time.perf_counter()
    try:
        runpy.run_module("diffpegasus", run_name="__main__", alter_sys=True)
    except SystemExit:
        pass
    run_s = time.perf_counter() - t_run

    def union(event):
        iv = sorted(spans.get(event, []))
        total, end = 0.0, -1e300
        for a, b in iv:
            if b <= end:
                continue
            total += b - max(a, end)
            end = b
        return total

    trace = union("/jax/core/compile/jaxpr_trace_duration")
    lower = union("/jax/core/compile/jaxpr_to_mlir_module_duration")
    backend = union("/jax/core/compile/backend_compile_duration")
    cache_read = durations.get("/jax/compilation_cache/cache_retrieval_time_sec", 0.0)
    result = {
        "total_in_process_s": time.perf_counter() - t_start,
        "import_diffpegasus_s": import_s,
        "command_s": run_s,
        "tracing_s": trace,
        "lowering_s": lower,
        "xla_compile_s": backend - cache_read,
        "cache_read_s": cache_read,
        "programs_compiled_or_loaded": len(
            spans.get("/jax/core/compile/backend_compile_duration", [])
        ),
        "programs_traced": len(spans.get("/jax/core/compile/jaxpr_trace_duration", [])),
        "rest_s": run_s - trace - lower - backend,
    }
    pathlib.Path(out_path).write_text(json.dumps(result))


def phases(root):
    out = root / "phases.json"
    env = dict(os.environ)
    env["JAX_COMPILATION_CACHE_DIR"] = str(root / "warm_ours")
    t0 = time.perf_counter()
    subprocess.run(
        [sys.executable, __file__, "--phases-out", str(out)],
        env=env,
        check=True,
        capture_output=True,
    )
    result = json.loads(out.read_text())
    result["process_wall_s"] = time.perf_counter() - t0
    # the slowest imports (cumulative, top-level packages)
    imp = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", "import diffpegasus._cli"],
        capture_output=True,
        text=True,
        env={**env, "PYTHONWARNINGS": "ignore"},
    ).stderr
    cumulative = {}
    for ln in imp.splitlines():
        if not ln.startswith("import time:") or "|" not in ln:
            continue
        _, cum, name = ln.split("|")
        try:
            us = int(cum)
        except ValueError:
            continue
        name = name.strip()
        if "." not in name and name in (
            "jax", "jaxlib", "equinox", "diffrax", "optimistix", "lineax", "optax",
            "scipy", "matplotlib", "typer", "tqdm", "numpy", "diffpegasus",
        ):  # fmt: skip
            cumulative[name] = max(cumulative.get(name, 0), us) / 1e6
    result["import_cumulative_s"] = cumulative
    return result


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--pairs", type=int, default=3)
    parser.add_argument("--phases-out")
    parser.add_argument("--skip-cold", action="store_true")
    parser.add_argument(
        "--out", default=str(HERE / "results" / "hfb320_process.json"), help="JSON"
    )
    args = parser.parse_args()
    if args.phases_out:
        phases_in_process(args.phases_out)
        return
    import jax

    with tempfile.TemporaryDirectory() as tmp:
        root = pathlib.Path(tmp)
        result = {
            "what": "diffpegasus fit hfb320_1_10.asc --vehicle hfb320 --json, whole "
            "process, against an independent JAX Gauss-Newton (same optimum)",
            "jax": jax.__version__,
            "cpus": os.cpu_count(),
            "load_average_at_start": os.getloadavg(),
        }
        if not args.skip_cold:
            result["cold_cache"] = pairs(args.pairs, True, root)
        result["warm_cache"] = pairs(args.pairs, False, root)
        result["phases_warm"] = phases(root)
        result["load_average_at_end"] = os.getloadavg()
    result["reference_cost_fvsysid"] = REFERENCE_COST
    path = pathlib.Path(args.out)
    path.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
