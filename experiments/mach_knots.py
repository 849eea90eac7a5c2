"""How many Mach functions the launch vehicle's baseline needs on a log of the
independent Pegasus-like generator (`tests/independent_generator.py`): the
baseline fit, then the refit with the planted effect added, for each `--knots`.

    python experiments/mach_knots.py --seed 5 --rate 200 \
        --effect thrust_misalignment --value 0.006 --knots 6 9

One JSON line per knot count: baseline det(R), the refitted effect with its
standard error (coloured-residual and Cramér-Rao), seconds.
"""

import argparse
import json
import pathlib
import sys
import tempfile
import time

import equinox as eqx


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
    args = p.parse_args()
    import jax

    jax.config.update("jax_enable_x64", True)
    import diffpegasus as dp
    from diffpegasus.discrepancy import fit_log, vehicle_entry

    folder = pathlib.Path(tempfile.mkdtemp(prefix="knots_"))
    effects = {args.effect: args.value} if args.value else None
    csv = gen.make_log(folder / "f.csv", args.seed, args.rate, 30.0, effects)
    log = dp.read_log(csv)
    for k in args.knots:
        entry = eqx.tree_at(lambda e: e.knots, vehicle_entry("pegasus"), k)
        t0 = time.time()
        base = fit_log(entry, log)
        after = fit_log(entry, log, (args.effect,), start=base)
        est = after.effect_estimates()[args.effect]
        row = {
            "seed": args.seed,
            "rate": args.rate,
            "effect": args.effect,
            "planted": args.value,
            "knots": k,
            "baseline_cost": base.cost,
            "converged": base.converged and after.converged,
            "estimate": est["estimate"],
            "stderr": est["stderr"],
            "stderr_crb": est["stderr_crb"],
            "seconds": round(time.time() - t0, 1),
        }
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
