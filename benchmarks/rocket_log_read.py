"""Reading a one-million-row rocket flight log: time and peak memory of
`read_rocket_log` (parse, clean, unit checks, events) against the straightforward
alternative, the csv module turning the same columns into floats (no cleaning, no
checks), each in a fresh process. Wall and CPU seconds both: on a shared machine
the CPU seconds are what the read costs; the package's import is timed apart.

Two synthetic flights of 1,000,000 rows each, written once into a temporary folder:
an AltOS export (the 69 columns of a TeleMetrum file, 4 kHz, 250 s, about 350 MB)
and a three-column altimeter CSV (time, altitude in ft, acceleration in g, 4 kHz);
and two variants exporters write: the AltOS export with every row ending in its
separator, the altimeter CSV with every cell quoted.

    python benchmarks/rocket_log_read.py   # writes benchmarks/results/rocket_log_read.json
"""

import json
import os
import pathlib
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np


ROWS = 1_000_000
RATE = 4000.0
HERE = pathlib.Path(__file__).resolve().parent
G0 = 9.80665


# the columns of a TeleMetrum's AltOS CSV export (version 6)
ALTOS_COLUMNS = (
    "#version serial flight call time state state_name acceleration pressure altitude "
    "height speed temperature drogue_voltage main_voltage battery_voltage connected "
    "locked nsat latitude longitude altitude year month day hour minute second "
    "pad_dist pad_range pad_az pad_el pdop hdop vdop"
).split() + [f"sat{k:02d}" for k in range(1, 33)]


def trajectory(t):
    """A plain flight: 4 s boost at 8 g, coast, drogue at apogee (25 m/s), main at
    300 m (6 m/s); altitude (m), axial specific force (m/s^2, gravity included)."""
    h = np.zeros_like(t)
    a = np.where(t < 0, G0, 0.0)
    boost = (t >= 0) & (t < 4)
    a[boost] = 8 * G0 + G0
    h[boost] = 0.5 * 8 * G0 * t[boost] ** 2
    v4, h4 = 8 * G0 * 4, 0.5 * 8 * G0 * 16
    coast = t >= 4
    tc = t[coast] - 4
    t_up = v4 / (1.3 * G0)
    up = np.minimum(tc, t_up)
    h[coast] = h4 + v4 * up - 0.5 * 1.3 * G0 * up**2
    a[coast] = np.where(tc < t_up, -0.3 * G0, G0)
    apo = h4 + v4 * t_up - 0.5 * 1.3 * G0 * t_up**2
    down = np.maximum(tc - t_up, 0.0)
    fall = np.minimum(down * 25.0, apo - 300.0)
    t_main = (apo - 300.0) / 25.0
    fall2 = np.clip((down - t_main) * 6.0, 0.0, 300.0)
    h[coast] = np.where(down > 0, apo - fall - fall2, h[coast])
    return h, a


def write_logs(folder: pathlib.Path) -> tuple[pathlib.Path, ...]:
    rng = np.random.default_rng(0)
    t = -1.0 + np.arange(ROWS) / RATE
    h, a = trajectory(t)
    h_noisy = h + rng.normal(0, 0.5, ROWS)
    a_noisy = a + rng.normal(0, 0.3, ROWS)
    p = 101325.0 * (1 - 2.25577e-5 * h_noisy) ** 5.25588
    header = ",".join(ALTOS_COLUMNS)
    tail = (
        ", 33.9, 0.00, 0.00, 3.87, 1, 1, 11,  32.9395046,-106.9114515,  1390.0, "
        "2022,  6, 24, 15, 17, 16,        0,        0,   0,   0,   1.4,"
        "2147483647.0,2147483647.0" + ",  0" * 32
    )
    altos = folder / "altos.csv"
    with open(altos, "w") as f:
        f.write(header + "\n")
        for k in range(0, ROWS, 100_000):
            sl = slice(k, k + 100_000)
            lines = [
                f"6, 5115, 1,VA3NPN, {ti:9.4f}, 3,   boost, {ai - G0:7.2f}, "
                f"{pi:9.2f}, {hi + 1320:8.2f}, {hi:8.2f}, {0.0:7.2f}{tail}\n"
                for ti, ai, pi, hi in zip(
                    t[sl], a_noisy[sl], p[sl], h_noisy[sl], strict=False
                )
            ]
            f.writelines(lines)
    alt = folder / "altimeter.csv"
    with open(alt, "w") as f:
        f.write("time (s),altitude (ft),acceleration (g)\n")
        for k in range(0, ROWS, 100_000):
            sl = slice(k, k + 100_000)
            f.writelines(
                f"{ti:.5f},{hi / 0.3048:.2f},{ai / G0:.4f}\n"
                for ti, hi, ai in zip(t[sl], h_noisy[sl], a_noisy[sl], strict=False)
            )
    # two common exports that a separator count could send down a slow path: every
    # row ending with its separator, and every cell quoted
    trailing = folder / "altos_trailing_separator.csv"
    with open(altos) as f, open(trailing, "w") as g:
        g.writelines(line[:-1] + ",\n" for line in f)
    quoted = folder / "altimeter_quoted.csv"
    with open(alt) as f, open(quoted, "w") as g:
        g.writelines(
            ",".join(f'"{c}"' for c in line[:-1].split(",")) + "\n" for line in f
        )
    return altos, alt, trailing, quoted


CHILD = r"""
import json, resource, sys, time
mode, path = sys.argv[1], sys.argv[2]
start = time.perf_counter()
if mode == "diffpegasus":
    from diffpegasus._log._rocketlogs import read_rocket_log
    imported = time.perf_counter()
    cpu0 = time.process_time()
    log = read_rocket_log(path)
    out = {"channels": len(log.channels), "events": sorted(log.events),
           "apogee_m": log.events["apogee"].value, "rows": len(log.channels["altitude"])}
else:
    import csv
    with open(path, newline="") as f:
        rows = csv.reader(f)
        names = [n.strip().lstrip("#") for n in next(rows)]
        want = [names.index(n) for n in names if n in
                ("time", "acceleration", "pressure", "height", "speed",
                 "time (s)", "altitude (ft)", "acceleration (g)")]
        cols = [[] for _ in want]
        for r in rows:
            for c, j in zip(cols, want):
                c.append(float(r[j]))
    out = {"rows": len(cols[0])}
if mode == "diffpegasus":
    out["import_seconds"] = imported - start
    out["cpu_seconds"] = time.process_time() - cpu0
    start = imported
else:
    out["cpu_seconds"] = time.process_time()
out["seconds"] = time.perf_counter() - start
out["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps(out))
"""


def run(mode: str, path: pathlib.Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(HERE.parent / "src")}
    done = subprocess.run(
        [sys.executable, "-c", CHILD, mode, str(path)],
        capture_output=True,
        text=True,
        env=env,
        check=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    results = {
        "what": "read a 1,000,000-row rocket flight log (fresh process each)",
        "rows": ROWS,
        "machine": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "load_1min": os.getloadavg()[0],
        "files": {},
    }
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        files = write_logs(pathlib.Path(tmp))
        results["write_seconds"] = time.perf_counter() - start
        for path in files:
            ours = run("diffpegasus", path)
            base = run("csv", path)
            results["files"][path.name] = {
                "megabytes": path.stat().st_size / 1e6,
                "read_rocket_log": ours,
                "csv_module_floats_only": base,
                "time_ratio": ours["seconds"] / base["seconds"],
            }
            print(path.name, json.dumps(results["files"][path.name]))
    out = HERE / "results" / "rocket_log_read.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(results, indent=2) + "\n")
    print("wrote", out)


if __name__ == "__main__":
    main()
