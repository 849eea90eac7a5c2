"""Every speed measurement a user feels, side by side in one run, with one summary.

Runs, one after another (each writes its own JSON in `benchmarks/results/`):
`demo_process.py` (demo cold/warm, `estimate oem` cold/warm/another log/`--no-cache`),
`cache.py` (`estimate oem` and `compare` cold/warm/`--no-cache`), `hfb320_process.py`
(the HFB-320 fit against the independent Gauss-Newton), `montecarlo.py` (the
100-flight campaign end to end, against flight-by-flight calls),
`campaign_processes.py` (the campaign from the command line in one and in two
processes), and the README's test command (`python -m pytest -n 2 -q`, wall time).
Then writes `benchmarks/results/all.json` with the headline numbers and the machine's
load before and after each step (the ratios are measured within each script's own
run, so they hold under load better than the absolute times).

Run on an idle machine: `python benchmarks/all.py [--skip tests,campaign_processes]`
(about 25 minutes on 2 cores with the tests).
"""

import argparse
import json
import os
import pathlib
import subprocess
import sys
import time


HERE = pathlib.Path(__file__).resolve().parent
RESULTS = HERE / "results"
STEPS = (
    "demo_process",
    "cache",
    "hfb320_process",
    "montecarlo",
    "campaign_processes",
    "tests",
)


def get(path, *keys):
    try:
        d = json.loads((RESULTS / f"{path}.json").read_text())
        for k in keys:
            d = d[k]
        return d
    except (OSError, KeyError, TypeError, ValueError):
        return None


def headline():
    return {
        "demo_cold_s": get("demo_process", "demo", "cold_s"),
        "demo_warm_s": get("demo_process", "demo", "warm_second_run_s"),
        "estimate_oem_cold_s": get("demo_process", "estimate_oem", "cold_s"),
        "estimate_oem_warm_s": get("demo_process", "estimate_oem", "warm_s"),
        "estimate_oem_warm_other_log_s": get(
            "demo_process", "estimate_oem", "warm_other_log_s"
        ),
        "compare_cold_s": get("cache", "compare_default", "cold_s"),
        "compare_warm_s": get("cache", "compare_default", "warm_s"),
        "hfb320_ratio_warm": get("hfb320_process", "warm_cache", "median_ratio"),
        "hfb320_ratio_cold": get("hfb320_process", "cold_cache", "median_ratio"),
        "campaign_100_s": get("montecarlo", "campaign_s", "total_all_stages"),
        "campaign_cli_one_process_s": get("campaign_processes", "one_process_s"),
        "campaign_cli_two_processes_s": get("campaign_processes", "two_processes_s"),
        "campaign_two_processes_mse_max_rel_diff": get(
            "campaign_processes", "mse_max_relative_difference"
        ),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--skip", default="", help="comma-separated steps to skip")
    args = parser.parse_args()
    skip = {s for s in args.skip.split(",") if s}
    steps = {}
    for name in STEPS:
        if name in skip:
            continue
        if name == "tests":
            cmd = [sys.executable, "-m", "pytest", "-n", "2", "-q"]
            cwd = HERE.parent
        else:
            cmd, cwd = [sys.executable, str(HERE / f"{name}.py")], HERE.parent
        load = os.getloadavg()
        t0 = time.perf_counter()
        done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
        steps[name] = {
            "wall_s": time.perf_counter() - t0,
            "returncode": done.returncode,
            "load_before": load,
            "load_after": os.getloadavg(),
            "tail": done.stdout.strip().splitlines()[-1:] if done.stdout else [],
        }
        print(name, json.dumps(steps[name]), flush=True)
    result = {"headline": headline(), "steps": steps}
    (RESULTS / "all.json").write_text(json.dumps(result, indent=2))
    print(json.dumps(result["headline"], indent=2))


if __name__ == "__main__":
    main()
