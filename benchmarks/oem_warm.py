"""Benchmark: one warm `estimate_oem` and one warm windowed fit on a second log.

Prints compile (first call, wall) and warm times (wall and this process's CPU, the
least of three). Run it with the package of two versions on `PYTHONPATH`, one after
the other and alternately, to compare them on a busy machine (CPU seconds are
steadier than wall seconds there):

    python benchmarks/oem_warm.py [--t-final 20] [--parameters hybrid]

Appends one JSON line to `benchmarks/results/oem_warm.jsonl`.
"""

import argparse
import json
import pathlib
import time

import jax
import numpy as np

import diffpegasus as dp


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--t-final", type=float, default=20.0)
    parser.add_argument("--parameters", default="hybrid")
    parser.add_argument("--tag", default="")
    args = parser.parse_args()
    pg = dp.pegasus
    logs = [
        pg.flight_to_log(
            pg.simulate(pg.PegasusConfig(t_final=args.t_final), jax.random.key(s))
        )
        for s in (1, 2)
    ]
    t0 = time.perf_counter()
    np.asarray(pg.estimate_oem(logs[0], parameters=args.parameters).values)
    first = time.perf_counter() - t0
    setup = pg.oem_setup(logs[1], parameters=args.parameters)[0]
    fit = jax.block_until_ready(setup.fit())
    wall, cpu = {"estimate_oem": [], "fit": []}, {"estimate_oem": [], "fit": []}
    for _ in range(3):
        for name, fn in (
            (
                "estimate_oem",
                lambda: pg.estimate_oem(logs[1], parameters=args.parameters).values,
            ),
            ("fit", lambda: setup.fit().params),
        ):
            c0, t0 = time.process_time(), time.perf_counter()
            jax.block_until_ready(fn())
            wall[name].append(time.perf_counter() - t0)
            cpu[name].append(time.process_time() - c0)
    result = {
        "tag": args.tag,
        "t_final_s": args.t_final,
        "parameters": args.parameters,
        "compile_plus_first_s": first,
        "iterations": int(fit.iterations),
        **{f"{k}_warm_s": min(v) for k, v in wall.items()},
        **{f"{k}_warm_cpu_s": min(v) for k, v in cpu.items()},
    }
    path = pathlib.Path(__file__).parent / "results" / "oem_warm.jsonl"
    with open(path, "a") as f:
        f.write(json.dumps(result) + "\n")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
