"""Diagnose alone on RocketPy flights (no coverage fit): which effects are named,
every candidate's statistic against the log's threshold, per round.

`python experiments/rocket_diagnose_flights.py FOLDER [FOLDER ...] [--out FILE]`:
each FOLDER one flight as `scripts/make_rocket_fixtures.py` writes it (the committed
ones are under tests/data/rocket_sim; `--validation DIR` writes more). The JSON
(`--out`, e.g. benchmarks/results/rocket_diagnose_more.json) is what
scripts/rocket_sim_docs.py puts on the simulated-flights page.
"""

import json
import pathlib
import sys
import time
import tomllib


sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))


def planted(folder, rocket):
    """The flight's planted effects (its rocket file's `[truth]`), with the wind
    along the rail's heading (the part a zero-angle-of-attack flight shows)."""
    import numpy as np

    truth = dict(tomllib.loads((folder / "rocket.toml").read_text())["truth"])
    head = np.radians(rocket.heading)
    truth["wind_along_m_s"] = truth.get("wind_east_m_s", 0.0) * np.sin(
        head
    ) + truth.get("wind_north_m_s", 0.0) * np.cos(head)
    return truth


def main():
    from rocket_validation import sim_log

    import diffpegasus.rocket as dr

    args = sys.argv[1:]
    out_path = None
    if "--out" in args:
        i = args.index("--out")
        out_path = pathlib.Path(args[i + 1])
        del args[i : i + 2]
    out = {}
    for folder in map(pathlib.Path, args):
        rocket = dr.read_rocket(folder / "rocket.toml")
        truth = planted(folder, rocket)
        t0 = time.perf_counter()
        named, rows, _ = dr.diagnose(dr.prepare(rocket, sim_log(folder)))
        seconds = time.perf_counter() - t0
        print(f"{folder.name}: planted {truth}; named {named} ({seconds:.0f} s)")
        for r in rows:
            ((name, value),) = r["estimates"].items()
            print(
                f"  {r['round']} {'*' if r['significant'] else ' '} "
                f"{r['candidate']:<40} {r['statistic']:9.1f} / {r['threshold']:6.1f}"
                f"  det ratio {r['cost_ratio']:.3f}  {name} {value:+.4g}"
                f"  {r['cannot_be_told_from']}",
                flush=True,
            )
        out[folder.name] = {
            "named": named,
            "tests": rows,
            "planted_effects": truth,
            "seconds": seconds,
        }
        if out_path:
            out_path.write_text(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
