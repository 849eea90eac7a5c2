"""Benchmark: the Monte Carlo campaign from the command line, in one process and in
two coordinated processes (`--processes 2`, JAX's multi-controller runtime on
127.0.0.1), as a user runs it.

Both are whole `diffpegasus montecarlo` processes, each with its own empty
persistent compilation cache (every program compiled, as on a fresh machine) and
its own results folder, timed from start to exit; the two campaigns' per-flight
MSE tables (`mse.csv`) are compared number by number. On one machine two processes
share its cores (one CPU device each instead of two in one process), so the
comparison says what the coordination costs or saves here; on several hosts each
process brings its own cores.

Writes `benchmarks/results/campaign_processes.json`. Run: `python
benchmarks/campaign_processes.py [--samples 100] [--methods lse,nn,oem]`.
"""

import argparse
import csv
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time


HERE = pathlib.Path(__file__).resolve().parent


def run(args, cache, out):
    env = dict(os.environ)
    env.pop("DIFFPEGASUS_NO_CACHE", None)
    env["JAX_COMPILATION_CACHE_DIR"] = str(cache)
    cmd = [sys.executable, "-m", "diffpegasus", "montecarlo", *args, f"--out={out}"]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if done.returncode:
        raise RuntimeError(f"{cmd} failed:\n{done.stderr[-3000:]}")
    return wall


def read_mse(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def compare(a, b):
    """Largest relative difference between two `mse.csv` tables (same rows)."""
    if len(a) != len(b):
        return float("inf")
    worst = 0.0
    for ra, rb in zip(a, b, strict=True):
        for k, va in ra.items():
            try:
                x, y = float(va), float(rb[k])
            except ValueError:
                if va != rb[k]:
                    return float("inf")
                continue
            if x != y:
                worst = max(worst, abs(x - y) / max(abs(x), abs(y), 1e-300))
    return worst


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--samples", type=int, default=100)
    parser.add_argument("--methods", default="lse,nn,oem")
    parser.add_argument(
        "--out", default=str(HERE / "results" / "campaign_processes.json")
    )
    args = parser.parse_args()
    common = [f"--samples={args.samples}", f"--methods={args.methods}"]
    with tempfile.TemporaryDirectory() as tmp:
        root = pathlib.Path(tmp)
        load0 = os.getloadavg()
        one = run(common, root / "cache1", root / "one")
        two = run([*common, "--processes=2"], root / "cache2", root / "two")
        diff = compare(
            read_mse(root / "one" / "mse.csv"), read_mse(root / "two" / "mse.csv")
        )
        result = {
            "what": "diffpegasus montecarlo, whole processes, cold cache each",
            "samples": args.samples,
            "methods": args.methods,
            "cpus": os.cpu_count(),
            "load_average_at_start": load0,
            "one_process_s": one,
            "two_processes_s": two,
            "ratio_two_over_one": two / one,
            "mse_max_relative_difference": diff,
            "load_average_at_end": os.getloadavg(),
        }
    pathlib.Path(args.out).write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
