"""Benchmark: the demo and `estimate oem` as a user feels them, whole processes with
the persistent compilation cache cold (an empty folder) and warm (the same folder
again).

- `diffpegasus demo --out DIR` twice (the issue's target: the second run under a
  minute on 2 cores); per step of the second run, from its printed lines' times;
- `diffpegasus estimate oem LOG` cold, warm, and warm on another log of the same
  length (another seed and input; the issue's target: under 10 s), on simulated
  80.3 s, 1 kHz Pegasus logs; `--no-cache` beside them, the straightforward
  alternative (every program compiled again).

Writes `benchmarks/results/demo_process.json`. Run: `python
benchmarks/demo_process.py [--skip-demo] [--skip-oem]`.
"""

import argparse
import json
import os
import pathlib
import resource
import subprocess
import sys
import tempfile
import time


HERE = pathlib.Path(__file__).resolve().parent


def run(args, env, cwd):
    """Wall time of one `diffpegasus` process, and its stdout lines with the
    seconds since start at which each arrived."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-m", "diffpegasus", *args],
        env=env,
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    lines = []
    for line in proc.stdout:
        lines.append((round(time.perf_counter() - t0, 2), line.rstrip()))
    err = proc.stderr.read()
    proc.wait()
    seconds = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode:
        raise RuntimeError(f"{args} failed:\n{err[-2000:]}")
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    lines.append((None, f"cpu_s {cpu:.2f}"))
    return seconds, lines


def _cpu(lines):
    return float(lines[-1][1].split()[1])


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--skip-demo", action="store_true")
    parser.add_argument("--skip-oem", action="store_true")
    args = parser.parse_args()
    work = pathlib.Path(tempfile.mkdtemp(prefix="diffpegasus-demo-bench-"))
    base = {k: v for k, v in os.environ.items() if k != "JAX_COMPILATION_CACHE_DIR"}
    base.pop("DIFFPEGASUS_NO_CACHE", None)
    result = {
        "what": "whole diffpegasus processes, persistent compilation cache cold "
        "(empty folder) and warm (same folder again)",
        "cpus": os.cpu_count(),
        "load_average_at_start": os.getloadavg(),
    }
    if not args.skip_demo:
        env = dict(base, JAX_COMPILATION_CACHE_DIR=str(work / "cache_demo"))
        cold, cold_lines = run(["demo", "--out", str(work / "demo1")], env, work)
        warm, lines = run(["demo", "--out", str(work / "demo2")], env, work)
        result["demo"] = {
            "cold_s": cold,
            "cold_cpu_s": _cpu(cold_lines),
            "warm_cpu_s": _cpu(lines),
            "warm_second_run_s": warm,
            "warm_lines": lines,
            "target_warm_s": 60,
        }
        print(json.dumps(result["demo"], indent=1), flush=True)
    if not args.skip_oem:
        off = dict(base, DIFFPEGASUS_NO_CACHE="1")
        for seed, name in ((0, "pulse"), (1, "3211")):
            run(
                ["simulate", f"--seed={seed}", f"--input={name}"]
                + [f"--out=f{seed}.csv", "--no-plot"],
                off,
                work,
            )
        env = dict(base, JAX_COMPILATION_CACHE_DIR=str(work / "cache_oem"))
        oem = {}
        outs = {}
        for key, log, e in (
            ("cold_s", "f0.csv", env),
            ("warm_s", "f0.csv", env),
            ("warm_other_log_s", "f1.csv", env),
            ("no_cache_s", "f0.csv", off),
        ):
            oem[key], outs[key] = run(["estimate", "oem", log, "--json"], e, work)
            oem[key.replace("_s", "_cpu_s")] = _cpu(outs[key])
        oem["same_output_warm_vs_cold"] = [x[1] for x in outs["cold_s"][:-1]] == [
            x[1] for x in outs["warm_s"][:-1]
        ]
        oem["target_warm_other_log_s"] = 10
        result["estimate_oem"] = oem
        print(json.dumps(oem, indent=1), flush=True)
    result["load_average_at_end"] = os.getloadavg()
    out = HERE / "results" / "demo_process.json"
    out.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
