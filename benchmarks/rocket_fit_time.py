"""One rocket flight's fit, cold (tracing and compilation included) and warm (the
same fit again in the same process: what a second command costs once the
persistent compilation cache holds the program; the continuation's two or three
fits included), with the machine's load average. With `--attitude` each flight is
fitted twice in the same run, as the point mass and with the attitude (its gyro
column, where the log has one, fitted too), and the warm ratio written. The fit
alone is timed (`spread=False`); `--spread` times the command's default instead,
with each sensor's own fit for the drag band (two-sensor logs). Writes
benchmarks/results/rocket_fit_time.json (`--out` another name).

Run: `python benchmarks/rocket_fit_time.py [--attitude] [--spread] [--out NAME]
FOLDER ...`;
a FOLDER holds a `rocket.toml` with its `[log]` (a simulated flight's as
scripts/make_rocket_fixtures.py writes it).
"""

import json
import os
import pathlib
import sys
import time


ROOT = pathlib.Path(__file__).resolve().parents[1]


def timed(folder, attitude, spread=False):
    from diffpegasus._log._rocketlogs import read_rocket_log
    from diffpegasus.rocket import fit_rocket, prepare, read_rocket

    rocket = read_rocket(folder / "rocket.toml", attitude=attitude)
    log = read_rocket_log(folder / "rocket.toml")
    times = []
    for _ in range(2):
        t0 = time.perf_counter()
        problem = prepare(rocket, log) if not times else problem  # noqa: F821
        # the default effects (default_free: with the wind where an
        # accelerometer spans the ascent), as the command fits them; the fit
        # alone unless `spread` (each sensor's own fit for the band)
        result = fit_rocket(problem, throw=False, spread=spread)
        times.append(time.perf_counter() - t0)
    return {
        "cold_s": times[0],
        "warm_s": times[1],
        "iterations": int(result.fit.iterations),
        "tries": {k: list(v) for k, v in result.tries.items()},
        "samples": len(result.record.t),
        "outputs": list(result.outputs),
        "free": [
            n
            for n, f in zip(
                result.fit.model.parameters, result.fit.model.free, strict=True
            )
            if f
        ],
        "spread": spread,
        "load_average_after": os.getloadavg()[0],
    }


def main():
    args = sys.argv[1:]
    attitude = "--attitude" in args
    spread = "--spread" in args
    args = [a for a in args if a not in ("--attitude", "--spread")]
    name = "rocket_fit_time.json"
    if "--out" in args:
        i = args.index("--out")
        name = args[i + 1]
        del args[i : i + 2]
    out = {"load_average": os.getloadavg()[0]}
    for folder in map(pathlib.Path, args):
        row = timed(folder, False, spread)
        if attitude:
            row = {"point_mass": row, "attitude": timed(folder, True, spread)}
            row["warm_ratio"] = row["attitude"]["warm_s"] / row["point_mass"]["warm_s"]
            row["cold_ratio"] = row["attitude"]["cold_s"] / row["point_mass"]["cold_s"]
        out[folder.name] = row
        print(folder.name, json.dumps(row), flush=True)
    path = ROOT / "benchmarks" / "results" / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
