"""One rocket flight's fit, cold (tracing and compilation included) and warm (the
same fit again in the same process: what a second command costs once the
persistent compilation cache holds the program; the continuation's two or three
fits included), with the machine's load average. Writes benchmarks/results/rocket_fit_time.json.

Run: `python benchmarks/rocket_fit_time.py FOLDER [FOLDER ...]`.
"""

import json
import os
import pathlib
import sys
import time


ROOT = pathlib.Path(__file__).resolve().parents[1]


def main():
    from diffpegasus._log._rocketlogs import read_rocket_log
    from diffpegasus.rocket import fit_rocket, prepare, read_rocket

    out = {"load_average": os.getloadavg()[0]}
    for folder in map(pathlib.Path, sys.argv[1:]):
        rocket = read_rocket(folder / "rocket.toml")
        log = read_rocket_log(folder / "rocket.toml")
        times = []
        for _ in range(2):
            t0 = time.perf_counter()
            problem = prepare(rocket, log) if not times else problem  # noqa: F821
            # the default effects (default_free: with the wind where an
            # accelerometer spans the ascent), as the command fits them
            result = fit_rocket(problem, throw=False)
            times.append(time.perf_counter() - t0)
        out[folder.name] = {
            "cold_s": times[0],
            "warm_s": times[1],
            "iterations": int(result.fit.iterations),
            "samples": len(result.record.t),
            "free": [
                n
                for n, f in zip(
                    result.fit.model.parameters, result.fit.model.free, strict=True
                )
                if f
            ],
            "load_average_after": os.getloadavg()[0],
        }
        print(folder.name, out[folder.name], flush=True)
    path = ROOT / "benchmarks" / "results" / "rocket_fit_time.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
