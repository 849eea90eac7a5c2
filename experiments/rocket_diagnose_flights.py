"""Diagnose alone on RocketPy flights (no coverage fit): which effects are named,
every candidate's statistic against the log's threshold, per round.

`python experiments/rocket_diagnose_flights.py FOLDER [FOLDER ...] [--out FILE]`:
each FOLDER one flight as `scripts/make_rocket_fixtures.py` writes it (the committed
ones are under tests/data/rocket_sim; `--validation DIR` writes more).
"""

import json
import pathlib
import sys
import time
import tomllib

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))


def main():
    import diffpegasus.rocket as dr
    from rocket_validation import sim_log

    args = sys.argv[1:]
    out_path = None
    if "--out" in args:
        i = args.index("--out")
        out_path = pathlib.Path(args[i + 1])
        del args[i : i + 2]
    out = {}
    for folder in map(pathlib.Path, args):
        truth = tomllib.loads((folder / "rocket.toml").read_text())["truth"]
        rocket = dr.read_rocket(folder / "rocket.toml")
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
        out[folder.name] = {"named": named, "rows": rows, "seconds": seconds}
        if out_path:
            out_path.write_text(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
