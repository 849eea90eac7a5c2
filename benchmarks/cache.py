"""Benchmark: the persistent compilation cache, as a user feels it.

Whole `diffpegasus` processes on one simulated 80.3 s Pegasus log (1 kHz), each
timed from start to exit:

- `estimate oem` and `compare`: cold (empty cache folder), warm (the same command
  again) and, in the same run, the straightforward alternative: `--no-cache` (every
  program compiled again, as before the cache);
- `estimate oem` warm on a second log (another seed and input, same length): the
  issue's "second run on another log of similar length";
- the same cold/warm pair with `EQX_ON_ERROR=nan`, which turns equinox's runtime
  checks (host callbacks, which JAX never writes to the cache) into NaN results: how
  much the output-error programs would gain once their jitted code has no
  callbacks.

Writes `benchmarks/results/cache.json`. Run: `python benchmarks/cache.py`.
"""

import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time


def run(args, env, cwd):
    t0 = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "diffpegasus", *args],
        env=env,
        cwd=cwd,
        capture_output=True,
        text=True,
    )
    seconds = time.perf_counter() - t0
    if done.returncode:
        raise RuntimeError(f"{args} failed:\n{done.stderr[-2000:]}")
    return seconds


def cache_files(folder):
    return sum(1 for p in pathlib.Path(folder).glob("*-cache"))


def main():
    work = pathlib.Path(tempfile.mkdtemp(prefix="diffpegasus-cache-bench-"))
    base = {k: v for k, v in os.environ.items() if k != "JAX_COMPILATION_CACHE_DIR"}
    base.pop("DIFFPEGASUS_NO_CACHE", None)
    off = dict(base, DIFFPEGASUS_NO_CACHE="1")
    for seed, name in ((0, "pulse"), (1, "3211")):
        run(
            ["simulate", f"--seed={seed}", f"--input={name}", f"--out=f{seed}.csv"]
            + ["--no-plot"],
            off,
            work,
        )
    result = {
        "what": "whole diffpegasus processes on an 80.3 s, 1 kHz simulated log",
        "cpu_count": os.cpu_count(),
        "load_average_at_start": os.getloadavg(),
    }
    commands = {
        "estimate_oem": ["estimate", "oem", "f0.csv", "--json"],
        "compare": ["compare", "f0.csv", "--json", "--out=report"],
    }
    for mode, extra in (("default", {}), ("eqx_on_error_nan", {"EQX_ON_ERROR": "nan"})):
        for name, args in commands.items():
            if mode != "default" and name != "estimate_oem":
                continue
            folder = work / f"cache-{mode}-{name}"
            env = dict(base, JAX_COMPILATION_CACHE_DIR=str(folder), **extra)
            r = {
                "cold_s": run(args, env, work),
                "cache_files_after_cold": cache_files(folder),
            }
            r["warm_s"] = run(args, env, work)
            if name == "estimate_oem":
                r["warm_other_log_s"] = run(
                    ["estimate", "oem", "f1.csv", "--json"], env, work
                )
            r["no_cache_s"] = run(args, dict(off, **extra), work)
            r["speedup_warm_vs_no_cache"] = r["no_cache_s"] / r["warm_s"]
            result[f"{name}_{mode}"] = r
            print(name, mode, json.dumps(r), flush=True)
    result["load_average_at_end"] = os.getloadavg()
    path = pathlib.Path(__file__).parent / "results" / "cache.json"
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
