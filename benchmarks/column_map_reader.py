"""Benchmark: a large CSV read through a column map (2 million rows, ~110 MB).

Compares, in the same run and each in a fresh process (peak memory is the process's
maximum resident set), three ways of getting the mapped columns of one file:

- `load_record`: the package's path (header, map resolution, the block C parser on
  the mapped columns only, the value and plausibility checks, the `Record`);
- `table`: the reader alone (`open_table(path).read(columns)`);
- `csv_module`: the straightforward alternative, the reader the package had before:
  Python's `csv` module, a list of rows, `float()` per cell;
- `numpy_loadtxt`: NumPy's C `loadtxt` with `usecols`.

Also the cost of the interpreter with NumPy and the package imported (`baseline`).
Writes `benchmarks/results/column_map_reader.json`.

Run: `python benchmarks/column_map_reader.py [--rows 2000000]`.
"""

import argparse
import json
import os
import pathlib
import platform
import resource
import subprocess
import sys
import tempfile
import time


COLUMNS = ["TIME", "DELV", "TAS", "ALF", "THE", "Q", "AX", "AZ"]
MAP = {
    "t": "TIME",
    "de": "DELV",
    "V": "TAS",
    "alpha": "ALF",
    "theta": "THE",
    "q": "Q",
    "ax": "AX",
    "az": "AZ",
}


def write_file(path: pathlib.Path, rows: int) -> None:
    """A level flight with a small pitch oscillation, consistent enough to pass the
    plausibility checks, written with 6 significant digits (time with 10)."""
    import numpy as np

    t = np.arange(rows) * 0.01
    rng = np.random.default_rng(0)
    omega = 2 * np.pi * 0.2
    theta = 0.05 + 0.01 * np.sin(omega * t)
    q = 0.01 * omega * np.cos(omega * t)
    alpha = 0.05 + rng.normal(0, 1e-4, rows)
    v = 110.0 + rng.normal(0, 0.05, rows)
    # body-axis kinematics at constant u = V cos(alpha), w = V sin(alpha)
    u, w_ = v * np.cos(alpha), v * np.sin(alpha)
    ax = 9.80665 * np.sin(theta) + q * w_ + rng.normal(0, 0.01, rows)
    az = -9.80665 * np.cos(theta) - q * u + rng.normal(0, 0.01, rows)
    data = np.column_stack([t, 0.01 * np.sin(omega * t), v, alpha, theta, q, ax, az])
    with open(path, "w") as f:
        f.write(",".join(COLUMNS) + "\n")
        np.savetxt(f, data, fmt=["%.10g"] + ["%.6g"] * 7, delimiter=",")


def run_one(method: str, path: str) -> dict:
    import numpy as np

    import diffpegasus as dp

    model = dp.Model(
        states=(),
        inputs=("de",),
        outputs=("V", "alpha", "theta", "q", "ax", "az"),
        parameters={"k": 0.0},
        rates=lambda t, x, u, p: x,
        observe=lambda t, x, u, p: x,
    )  # (imports JAX before the clock starts, in every run alike)
    t0, c0 = time.perf_counter(), time.process_time()
    if method == "load_record":
        rec = dp.load_record(model, path, MAP)
        n = len(rec.t)
    elif method == "table":
        from diffpegasus._log._table import open_table

        data = open_table(path).read(list(MAP.values()))
        n = len(data["TIME"])
    elif method == "csv_module":
        import csv

        with open(path, newline="") as f:
            rows = list(csv.reader(f))
        names = rows[0]
        out = {n_: [] for n_ in names}
        for row in rows[1:]:
            for name, cell in zip(names, row, strict=True):
                out[name].append(float(cell))
        data = {k: np.asarray(v) for k, v in out.items()}
        n = len(data["TIME"])
    elif method == "numpy_loadtxt":
        data = np.loadtxt(path, delimiter=",", skiprows=1, usecols=range(8), ndmin=2)
        n = len(data)
    elif method == "baseline":
        n = 0
    else:
        raise ValueError(method)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # Linux: KiB
    # wall time depends on how busy the machine is; CPU time much less
    return {"seconds": seconds, "cpu_seconds": cpu, "peak_bytes": peak, "rows": n}


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rows", type=int, default=2_000_000)
    parser.add_argument("--skip-slow", action="store_true", help="no csv_module run")
    parser.add_argument("--one", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(run_one(*args.one)))
        return
    with tempfile.TemporaryDirectory() as d:
        path = pathlib.Path(d) / "big.csv"
        write_file(path, args.rows)
        size = path.stat().st_size
        methods = ["baseline", "load_record", "table", "numpy_loadtxt"]
        if not args.skip_slow:
            methods.append("csv_module")
        runs = {}
        for m in methods:
            out = subprocess.run(
                [sys.executable, __file__, "--one", m, str(path)],
                capture_output=True,
                text=True,
            )
            if out.returncode != 0:
                raise SystemExit(f"{m} failed: {out.stderr.strip()[-500:]}")
            runs[m] = json.loads(out.stdout.strip().splitlines()[-1])
            print(m, runs[m], file=sys.stderr)
    base = runs["baseline"]["peak_bytes"]
    for r in runs.values():
        r["peak_above_baseline_bytes"] = r["peak_bytes"] - base
    result = {
        "what": f"{args.rows} rows x {len(COLUMNS)} columns, {size / 1e6:.0f} MB CSV, "
        "all columns mapped",
        "file_bytes": size,
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "load_average_1_5_15_min_at_end": os.getloadavg(),
        "python": platform.python_version(),
        "runs": runs,
        "speedup_vs_csv_module": (
            runs["csv_module"]["seconds"] / runs["load_record"]["seconds"]
            if "csv_module" in runs
            else None
        ),
        "cpu_speedup_vs_csv_module": (
            runs["csv_module"]["cpu_seconds"] / runs["load_record"]["cpu_seconds"]
            if "csv_module" in runs
            else None
        ),
        "target": "2 million rows under 5 s and under 1 GB peak",
        "meets_target": runs["load_record"]["seconds"] < 5.0
        and runs["load_record"]["peak_bytes"] < 1e9,
        "meets_target_in_cpu_time": runs["load_record"]["cpu_seconds"] < 5.0
        and runs["load_record"]["peak_bytes"] < 1e9,
    }
    out = pathlib.Path(__file__).parent / "results" / "column_map_reader.json"
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
