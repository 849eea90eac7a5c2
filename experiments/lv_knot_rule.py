"""The launch vehicle's baseline Mach resolution chosen from the log
(`PegasusEntry(knots=None)`, `choose_knots` with the moment judged through the
pitch rate integrated over each shooting segment) on flights of the independent
generator (`tests/independent_generator.py`), clean and planted, noisy and
noise-free, against the old rule (the moment judged on the CM reconstructed from
the pitch-acceleration channel).

    nice python experiments/lv_knot_rule.py [--flights 50:13 200:8 ...]
        [--out experiments/results/lv_knot_rule.json]
    nice python experiments/lv_knot_rule.py --span --flights 200:8 50:13 ...

`--span`: how much of a constant moment lies outside the baseline's span along
each flight: a constant CM regressed on the regressors (block means at 50 Hz) with
6 and 12 Mach functions, all terms, the alpha terms, the elevator terms, and the
alpha polynomial without Mach functions (rms of the residual, a fraction of the
constant).

A flight is `RATE:SEED[:EFFECT=VALUE][,nonoise]`.
"""

import argparse
import json
import pathlib
import sys
import tempfile

import numpy as np


HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

import independent_generator as gen  # noqa: E402


DEFAULT = [
    "50:13", "50:0", "50:1:moment_offset=0.006", "50:22", "50:22:moment_offset=0.006",
    "200:8", "200:2:actuator_delay=0.04", "1000:4", "1000:7:moment_offset=0.006",
    "50:13:nonoise", "200:8:nonoise", "1000:4:nonoise",
]  # fmt: skip


def parse(spec):
    parts = spec.split(":")
    rate, seed = float(parts[0]), int(parts[1])
    rest = ":".join(parts[2:])
    noise = "nonoise" not in rest
    effects = {}
    for item in rest.replace("nonoise", "").split(","):
        if "=" in item:
            k, v = item.rsplit("=", 1)
            effects[k] = float(v)
    return rate, seed, effects, noise


def choices(spec, folder):
    from diffpegasus._registry._pegasus import PegasusEntry

    rate, seed, effects, noise = parse(spec)
    csv = folder / (spec.replace(":", "_").replace("=", "").replace(",", "_") + ".csv")
    gen.write(csv, *gen.generate(seed, rate, 30.0, effects, noise))
    new, _ = PegasusEntry(knots=None).problem([csv])
    row = {"flight": spec, "pitch_rate_rule": new.notes["baseline"]}
    # the old rule: CM from the pitch-acceleration channel
    import diffpegasus._vehicle._mach_spline as ms

    real = ms.choose_knots

    def old(mach, alpha, de, coefficients, segment, *, pitch=None, **kw):
        return real(mach, alpha, de, coefficients, segment, **kw)

    entry = PegasusEntry(knots=None)
    ms.choose_knots = old
    try:
        before, _ = entry.problem([csv])
    finally:
        ms.choose_knots = real
    row["qdot_rule"] = before.notes["baseline"]
    return row


def span(spec):
    from diffpegasus._registry._pegasus import block_means
    from diffpegasus._vehicle._mach_spline import (
        mach_breakpoints,
        MachSplineAerodynamics,
    )

    rate, seed, effects, noise = parse(spec)
    ch, _ = gen.generate(seed, rate, 30.0, effects, noise)
    step = int(round(rate / 50.0))
    red = {k: block_means(v, step)[0] for k, v in ch.items()}
    mach, alpha, de = red["mach"], red["alpha"], red["de"]

    def outside(x):
        one = np.ones(len(x))
        return float(np.sqrt(np.mean((one - x @ np.linalg.lstsq(x, one)[0]) ** 2)))

    row = {
        "flight": spec,
        "alpha_deg": [float(np.degrees(alpha.min())), float(np.degrees(alpha.max()))],
        "alpha_polynomial": outside(np.column_stack([alpha, alpha**2, alpha**3])),
    }
    for k in (6, 12):
        part = MachSplineAerodynamics(knots=k)
        a = part.regressors(mach, alpha, de, mach_breakpoints(mach, k - 2))
        terms = [n.split(".")[1].split("[")[0] for n in part.coefficient_names()]
        terms = terms[: a.shape[1]]
        pick = {
            "all": list(range(a.shape[1])),
            "alpha": [i for i, t in enumerate(terms) if t in ("a1", "a2", "a3")],
            "elevator": [i for i, t in enumerate(terms) if t in ("de", "a1de")],
        }
        row[f"knots_{k}"] = {name: outside(a[:, c]) for name, c in pick.items()}
    return row


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--flights", nargs="+", default=DEFAULT)
    ap.add_argument("--out", type=pathlib.Path)
    ap.add_argument("--span", action="store_true")
    a = ap.parse_args()
    if a.span:
        rows = [span(f) for f in a.flights]
        for r in rows:
            print(json.dumps(r))
        if a.out:
            a.out.write_text(json.dumps(rows, indent=1))
        return
    folder = pathlib.Path(tempfile.mkdtemp(prefix="knot_rule_"))
    rows = []
    for spec in a.flights:
        r = choices(spec, folder)
        rows.append(r)
        b = r["pitch_rate_rule"]
        print(
            f"{spec:28s} pitch-rate rule {b['knots']:2d}   "
            f"qdot rule {r['qdot_rule']['knots']:2d}   n_eff "
            + " ".join(f"{v:.0f}" for v in b["effective_samples"])
            + "  p "
            + " ".join(f"{v:.2g}" for v in b["p_value"]),
            flush=True,
        )
    if a.out:
        a.out.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
