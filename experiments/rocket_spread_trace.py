"""Why a flight's band with the sensors' spread misses the planted curve: which
knots each sensor determines on its own, how far from its share, and what a
sensor says at the knots it is held on when it is made to fit them.

Run: `python experiments/rocket_spread_trace.py FOLDER JSON [--free-all CHANNEL]`:
FOLDER a simulated flight (rocket.toml with [truth], log.csv), JSON a
`benchmarks/rocket_validation.py` run holding it (single shooting starts from its
estimates, the optimum that run kept). Prints, knot by knot: the planted CD, the
joint estimate and its standard error, each channel's marginal standard error from
its own information at the joint optimum (the knots it determines free) and the
ratio to its share (`determined` holds a knot above 1), each channel's own
estimate and the structural term. With `--free-all CHANNEL` the channel's own fit
estimates every knot it carries information on (the rule overridden), and the
structural term it would give is printed beside.
"""

import json
import pathlib
import sys

import numpy as np

import diffpegasus.rocket as dr
from diffpegasus._log._rocketlogs import read_rocket_log
from diffpegasus._rocket import _spread


def main():
    folder, run = pathlib.Path(sys.argv[1]), sys.argv[2]
    channel = (
        sys.argv[sys.argv.index("--free-all") + 1] if "--free-all" in sys.argv else None
    )
    rocket = dr.read_rocket(folder / "rocket.toml")
    log = read_rocket_log(folder / "log.csv")
    problem = dr.prepare(rocket, log)
    kept = json.loads(pathlib.Path(run).read_text())[folder.name]
    warm = {n: v for n, (v, _) in kept["estimates"].items()}
    single = float(problem.record.t[-1] - problem.record.t[0]) + 1.0
    seen = {}
    rule = _spread.determined

    def recording(info):
        seen["info"] = np.asarray(info)
        seen["mask"] = rule(info)
        return seen["mask"]

    _spread.determined = recording
    result = dr.fit_rocket(
        problem, start=warm, shooting_interval=single, throw=False, spread=True
    )
    fit = result.fit
    names = list(fit.model.parameters)
    free = [n for n, f in zip(names, fit.free, strict=True) if f]
    knots = list(result.knots.names)
    at = [free.index(k) for k in knots]
    info, mask = seen["info"], seen["mask"]
    channels = info.shape[0]
    joint = _spread._marginal(info.sum(0), np.ones(len(free), bool))
    mach_true, cd_true = rocket.team_drag_off
    scale = float(fit.params[names.index("cd_scale")])
    print(
        "converged",
        bool(fit.converged),
        "cost",
        float(fit.cost),
        "outputs",
        result.outputs,
        "held by each channel (not knots):",
        {
            o: [free[i] for i in np.flatnonzero(~mask[c]) if free[i] not in knots]
            for c, o in enumerate(result.outputs)
        },
    )
    head = "mach  planted  joint  sd_joint"
    for o in result.outputs:
        head += f" | {o}: sd_alone ratio own"
    print(head + " | tau")
    spread = result.spread
    for j, (k, i) in enumerate(zip(knots, at, strict=True)):
        m = result.knots.mach[j]
        line = (
            f"{m:.3f} {np.interp(m, mach_true, cd_true):.4f} "
            f"{fit.params[names.index(k)] * scale:.4f} {np.sqrt(joint[i]) * scale:.4f}"
        )
        for c in range(channels):
            alone = _spread._marginal(info[c], mask[c])
            sd = np.sqrt(alone[i]) * scale if mask[c][i] else float("nan")
            ratio = alone[i] / (channels * joint[i]) if mask[c][i] else float("nan")
            # held: the ratio it had with every knot it carries information on free
            if not mask[c][i]:
                d = np.sqrt(np.clip(np.diag(info[c]), 0, None))
                keep = mask[c] | (d > 1e-8 * d.max())
                ratio = _spread._marginal(info[c], keep)[i] / (channels * joint[i])
            line += f" | {sd:.4f} {ratio:.2f} {spread.knots[c, j]:.4f}"
        print(line + f" | {spread.tau[j]:.4f}")
    if channel is None:
        return
    c = list(result.outputs).index(channel)

    def forced(info):
        out = rule(info)
        d = np.sqrt(np.clip(np.diag(info[c]), 0, None))
        out[c] = out[c] | np.isin(np.arange(len(free)), at) & (d > 1e-8 * d.max())
        return out

    _spread.determined = forced
    other = _spread.structural_spread(result)
    print(f"{channel} fitting every knot: converged", other.converged.tolist())
    for j in range(len(knots)):
        sd = np.sqrt(other.covariances[c, j, j])
        print(
            f"{result.knots.mach[j]:.3f} own {other.knots[c, j]:.4f} +/- {sd:.4f}"
            f" tau {other.tau[j]:.4f}"
        )


if __name__ == "__main__":
    main()
