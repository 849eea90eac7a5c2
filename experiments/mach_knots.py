"""How many Mach functions the launch vehicle's baseline needs on a log of the
independent Pegasus-like generator (`tests/independent_generator.py`): the
baseline fit and its diagnosis (score statistics against the threshold the log's
own residuals give) for each `--knots` (0: chosen from the log by
cross-validation across the shooting segments, `choose_knots`), and with
`--refit` the refit with the planted effect added.

    python experiments/mach_knots.py --seed 1 --rate 50 \
        --effect moment_offset --value 0.006 --knots 0 6 9 --placement quantile blend

One JSON line per knot count and placement: the count used, baseline det(R),
the threshold, the three largest statistics, the moment offset's and thrust
misalignment's statistic, score estimate and standard error, the effects
flagged, seconds (and with `--refit` the refitted effect).
"""

import argparse
import json
import pathlib
import sys
import tempfile
import time


HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

import independent_generator as gen  # noqa: E402


def main():
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--seed", type=int, default=5)
    p.add_argument("--rate", type=float, default=200.0)
    p.add_argument("--effect", default="thrust_misalignment")
    p.add_argument("--value", type=float, default=0.006)
    p.add_argument("--knots", type=int, nargs="+", default=[6, 9])
    p.add_argument("--placement", nargs="+", default=["quantile"])
    p.add_argument("--refit", action="store_true")
    args = p.parse_args()
    import jax

    jax.config.update("jax_enable_x64", True)
    import diffpegasus as dp
    from diffpegasus._registry._pegasus import PegasusEntry
    from diffpegasus.discrepancy import diagnose, fit_log

    folder = pathlib.Path(tempfile.mkdtemp(prefix="knots_"))
    effects = {args.effect: args.value} if args.value else None
    csv = gen.make_log(folder / "f.csv", args.seed, args.rate, 30.0, effects)
    log = dp.read_log(csv)
    for placement in args.placement:
        for k in args.knots:
            entry = PegasusEntry(knots=k or None, knot_placement=placement)
            t0 = time.time()
            base = fit_log(entry, log)
            result = diagnose(base)
            ranking = result["ranking"]
            row = {
                "seed": args.seed,
                "rate": args.rate,
                "effect": args.effect if args.value else None,
                "planted": args.value,
                "knots": k or "log",
                "placement": placement,
                "knots_used": base.spec.notes["baseline"]["knots"],
                "baseline_cost": base.cost,
                "converged": base.converged,
                "threshold": ranking[0]["threshold"],
                "top": [[r["effect"], r["statistic"]] for r in ranking[:3]],
                "significant": result["significant"],
            }
            for r in ranking:
                if r["effect"] in ("moment_offset", "thrust_misalignment"):
                    row[r["effect"]] = [r["statistic"], r["estimate"], r["stderr"]]
            if args.refit and args.value:
                after = fit_log(entry, log, (args.effect,), start=base)
                est = after.effect_estimates()[args.effect]
                row["refit"] = [est["estimate"], est["stderr"]]
            row["seconds"] = round(time.time() - t0, 1)
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
