"""The README's discrepancy table, measured on the current code.

Each effect of the SPEC's library planted alone in a 30 s Pegasus flight logged at
50 Hz (default noise, seed 5), plus clean flights of seeds 3, 4, 6: the baseline
fit, the diagnosis (ranked first, significant, score statistic, predicted fall of
det(R)), and the refit with the planted effect added (estimate, coloured-residual
standard error, det(R) after / before). Writes
`experiments/results/discrepancy_table.json` and prints the markdown table.

Run: `python experiments/discrepancy_table.py` (about 20 min on 2 idle cores).
"""

import json
import pathlib
import time

import jax

import diffpegasus as dp
from diffpegasus.discrepancy import diagnose, fit_log, vehicle_entry


PLANTED = [
    ("pitch_damping", -10.0),
    ("lift_offset", 0.02),
    ("drag_offset", 0.05),
    ("moment_offset", 0.01),
    ("thrust_misalignment", 0.02),
    ("accelerometer_offset", 0.5),
    ("actuator_delay", 0.02),
    ("vertical_wind", 5.0),
    ("sensor_bias:az", 0.2),
    ("sensor_bias:alpha", 0.005),
    ("sensor_bias:theta", 0.005),
]
OUT = pathlib.Path(__file__).parent / "results" / "discrepancy_table.json"


def flight(hidden, seed):
    effects = tuple(dp.parse_assignment(h) for h in hidden)
    config = dp.PegasusConfig(t_final=30.0, sample_rate=50.0, effects=effects)
    return dp.flight_to_log(dp.simulate(config, jax.random.key(seed)))


def row(hidden, seed, settings, planted=None):
    log = flight(hidden, seed)
    t0 = time.perf_counter()
    base = fit_log(settings, log)
    result = diagnose(base)
    top = result["ranking"][0]
    out = {
        "planted": list(hidden),
        "seed": seed,
        "first": top["effect"],
        "tied_with_first": [c["effect"] for c in top["hard_to_tell_from"]],
        "significant": result["significant"],
        "top_statistic": top["statistic"],
        "top_fall": top["cost_reduction"],
        "largest_physical_statistic": max(
            r["statistic"] for r in result["ranking"] if not r["resolution_limit"]
        ),
    }
    if planted is not None:
        name, value = planted
        mine = next(r for r in result["ranking"] if r["effect"] == name)
        after = fit_log(settings, log, (name,), start=base)
        est = after.effect_estimates()[name]
        out.update(
            truth=value,
            planted_fall=mine["cost_reduction"],
            planted_statistic=mine["statistic"],
            estimate=est["estimate"],
            stderr=est["stderr"],
            cost_ratio=float(after.cost / base.cost),
        )
    out["seconds"] = time.perf_counter() - t0
    return out


def main():
    settings = vehicle_entry("pegasus")  # the launch vehicle's registry entry
    rows = json.loads(OUT.read_text()) if OUT.exists() else []
    done = {(tuple(r["planted"]), r["seed"]) for r in rows}
    jobs = [((), s, None) for s in (3, 4, 6)] + [
        ((f"{n}={v}",), 5, (n, v)) for n, v in PLANTED
    ]
    OUT.parent.mkdir(exist_ok=True)
    for hidden, seed, planted in jobs:
        if (tuple(hidden), seed) in done:
            continue
        rows.append(row(hidden, seed, settings, planted))
        OUT.write_text(json.dumps(rows, indent=1))  # finished rows survive a stop
        print(rows[-1], flush=True)
    print(
        "| planted | ranked first | significant | predicted fall | refit (truth) "
        "| det(R) after / before |"
    )
    print("|---|---|---|---|---|---|")
    for r in rows:
        if not r["planted"]:
            print(
                f"| none, seed {r['seed']} | {r['first']} | "
                f"{', '.join(r['significant']) or 'nothing'} | "
                f"{r['top_fall']:.1%} (statistic {r['largest_physical_statistic']:.1f})"
                " | | |"
            )
            continue
        tie = (
            f" (tied: {', '.join(r['tied_with_first'])})"
            if r["tied_with_first"]
            else ""
        )
        print(
            f"| `{r['planted'][0]}` | `{r['first']}`{tie} | "
            f"{'yes' if r['planted'][0].split('=')[0] in r['significant'] else 'no'} | "
            f"{r['planted_fall']:.0%} | {r['estimate']:.4g} +/- {r['stderr']:.2g} "
            f"({r['truth']:g}) | {r['cost_ratio']:.3g} |"
        )


if __name__ == "__main__":
    main()
