"""Issue 15 on the engine (`dp.fit`, `dp.diagnose_model`, `diagnose --vehicle`):
false alarms of the decision rule and coverage of the standard errors on simulated
HFB-320 flights.

Per seed, one clean 30 s flight at 10 Hz (`simulate --vehicle hfb320`: the
identified aerodynamics, 3-2-1-1 elevator, RK4 at a tenth of the log step, white
noise), written and read back as a log; optionally the same from the independent
generator's HFB-320 (`tests/independent_generator.py`: numpy/scipy, true steps
between samples, its own noise). For every flight:

- `diagnose --vehicle hfb320` (the library effects held at zero, scored, decided
  by the shared rule): whether anything is significant, the largest statistics;
- `fit --vehicle hfb320`: whether the truth lies within +/- 2 Cramér-Rao and
  coloured-residual-corrected standard errors, per parameter.

Run: `python experiments/trust_hfb320.py [--seeds 30] [--generator package|independent]
[--rate 10] [--actuator TAU] [--add EFFECT] [--out results/trust_hfb320]`; writes one JSON line per flight (resumable) and a
summary.
"""

import argparse
import json
import pathlib
import sys

import numpy as np

from diffpegasus._cli._runners import run_model_diagnose
from diffpegasus._log._format import FlightLog, write_log
from diffpegasus._registry import vehicle_spec
from diffpegasus._registry._hfb320_simulator import simulate_log
from diffpegasus._vehicle._hfb320 import IDENTIFIED


HERE = pathlib.Path(__file__).resolve().parent


def flight(
    seed: int, generator: str, folder: pathlib.Path, rate: float, actuator=None
) -> pathlib.Path:
    path = folder / f"{generator}_{int(rate)}_{seed}.csv"
    if generator == "package":
        channels, meta = simulate_log(duration=30.0, rate=rate, seed=seed)
        return write_log(path, FlightLog(channels=channels, metadata=meta))
    sys.path.insert(0, str(HERE.parent / "tests"))
    import independent_generator as gen  # noqa: PLC0415

    channels, meta = gen.generate_hfb320(seed, rate, actuator=actuator)
    return gen.write(path, channels, meta)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", type=int, default=30)
    parser.add_argument("--first", type=int, default=0)
    parser.add_argument("--generator", default="package")
    parser.add_argument("--rate", type=float, default=10.0)
    parser.add_argument(
        "--actuator",
        type=float,
        default=None,
        help="independent generator: surface lag time constant, s (default: true steps)",
    )
    parser.add_argument(
        "--add",
        action="append",
        default=[],
        help="library effect estimated with the fit (e.g. actuator_delay: the "
        "input's timing as a nuisance parameter); repeatable",
    )
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/trust_hfb320")
    )
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    tag = "" if args.actuator is None else f"_lag{args.actuator:g}"
    tag += "".join(f"_add_{a}" for a in args.add)
    lines = args.out / f"{args.generator}_{int(args.rate)}{tag}.jsonl"
    done = set()
    if lines.exists():
        done = {json.loads(x)["seed"] for x in lines.read_text().splitlines() if x}
    from diffpegasus._cli._runners import _fit_spec

    for seed in range(args.first, args.first + args.seeds):
        if seed in done:
            continue
        path = flight(seed, args.generator, args.out, args.rate, args.actuator)
        spec = vehicle_spec("hfb320", candidates=True)
        report = run_model_diagnose(spec, [path])
        _, result = _fit_spec(
            vehicle_spec("hfb320", add=tuple(args.add)),
            [path],
            None,
            (),
            None,
            None,
            None,
        )
        names = list(result.model.parameters)
        row = {
            "seed": seed,
            "converged_diagnose": bool(report["fit"]["converged"]),
            "significant": report["significant"],
            "message": report["message"],
            "ranking": [
                {
                    k: r[k]
                    for k in (
                        "effect",
                        "statistic",
                        "p_value",
                        "estimate",
                        "cost_reduction",
                        "significant",
                        "resolution_limit",
                    )
                }
                for r in report["ranking"]
            ],
            "converged_fit": bool(result.converged),
            "estimates": {n: float(result.params[i]) for i, n in enumerate(names)},
            "stderr": {n: float(result.stderr[i]) for i, n in enumerate(names)},
            "stderr_corrected": {
                n: float(result.stderr_corrected[i]) for i, n in enumerate(names)
            },
        }
        with open(lines, "a") as f:
            f.write(json.dumps(row) + "\n")
        top = max(row["ranking"], key=lambda r: r["statistic"])
        print(
            f"seed {seed}: significant {row['significant']}, largest statistic "
            f"{top['statistic']:.1f} ({top['effect']})",
            flush=True,
        )
    summarise(lines)


def summarise(lines: pathlib.Path) -> dict:
    rows = [json.loads(x) for x in lines.read_text().splitlines() if x]
    flagged = sum(bool(r["significant"]) for r in rows)
    stats = sorted(
        (max(x["statistic"] for x in r["ranking"]) for r in rows), reverse=True
    )
    names = [n for n in IDENTIFIED if n in rows[0]["estimates"]]
    cover = {}
    for kind in ("stderr", "stderr_corrected"):
        cover[kind] = {
            n: float(
                np.mean(
                    [
                        abs(r["estimates"][n] - IDENTIFIED[n]) <= 2 * r[kind][n]
                        for r in rows
                    ]
                )
            )
            for n in names
        }
    z = {
        n: float(
            np.std([(r["estimates"][n] - IDENTIFIED[n]) / r["stderr"][n] for r in rows])
        )
        for n in names
    }
    summary = {
        "flights": len(rows),
        "flagged": flagged,
        "largest_statistics": stats[:5],
        "coverage_2sigma": cover,
        "std_of_z_crb": z,
    }
    (lines.with_suffix(".summary.json")).write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary, indent=2))
    return summary


if __name__ == "__main__":
    main()
