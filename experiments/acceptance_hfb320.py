"""The HFB-320 diagnosis on flights of the independent generator, as a user runs it.

24 flights of `tests/independent_generator.py::generate_hfb320` (numpy/scipy only:
true elevator steps between samples, DOP853, its own noise) at 10, 20, 50 and
100 Hz: clean; planted sensor biases, an actuator delay, alpha^2 lift; the
vehicle's pitch damping removed from the model (`--fix CMq=0`, the generator
keeps it); and gusts (the aircraft flown through Gauss-Markov gusts, V and alpha
air-relative). Each through

    diffpegasus diagnose LOG --vehicle hfb320 [--fix CMq=0] --json
    diffpegasus fit LOG --vehicle hfb320 --add TOP --json      (if TOP is an effect)

Right: nothing named on a clean flight; the planted effect (or one the report says
it cannot be told from) named and nothing else; `process_noise` named on a gusty
flight and nothing else. Every result is appended to the output as soon as it is
known; a rerun skips the flights already there.

    nice python experiments/acceptance_hfb320.py [--max N] [--seeds S,...] [--out FILE] [--table]
"""

import argparse
import json
import pathlib
import sys
import tempfile


HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE))

import independent_generator as gen  # noqa: E402
from acceptance import _cli, judge  # noqa: E402


OUT = HERE / "results" / "acceptance_hfb320.json"
PITCH = ("pitch_damping", "CMq=0")  # removed from the model, kept in the flight
GUSTS = "process_noise"

# (rate Hz, seed, planted, value): value SI (m/s^2, rad, rad/s, s; CLa2; gust sigma m/s)
FLIGHTS = [
    (10.0, 200, None, 0.0),
    (20.0, 201, None, 0.0),
    (50.0, 202, None, 0.0),
    (100.0, 203, None, 0.0),
    (20.0, 204, "sensor_bias:az", 0.1),
    (50.0, 205, "sensor_bias:q", 0.002),
    (10.0, 206, "sensor_bias:alpha", 0.005),
    (100.0, 207, "sensor_bias:ax", 0.1),
    (10.0, 208, "actuator_delay", 0.1),
    (20.0, 209, "actuator_delay", 0.08),
    (50.0, 210, "actuator_delay", 0.05),
    (100.0, 211, "actuator_delay", 0.03),
    (10.0, 212, PITCH[0], 0.0),
    (20.0, 213, PITCH[0], 0.0),
    (50.0, 214, PITCH[0], 0.0),
    (100.0, 215, PITCH[0], 0.0),
    (10.0, 216, "lift_alpha_squared", 10.0),
    (20.0, 217, "lift_alpha_squared", 10.0),
    (50.0, 218, "lift_alpha_squared", 10.0),
    (100.0, 219, "lift_alpha_squared", 10.0),
    (10.0, 220, GUSTS, 0.3),
    (20.0, 221, GUSTS, 1.0),
    (50.0, 222, GUSTS, 0.3),
    (100.0, 223, GUSTS, 1.0),
]


def _load():
    return json.loads(OUT.read_text()) if OUT.exists() else []


def _append(row):
    rows = _load() + [row]
    OUT.parent.mkdir(parents=True, exist_ok=True)
    tmp = OUT.with_suffix(".tmp")
    tmp.write_text(json.dumps(rows, indent=1))
    tmp.replace(OUT)
    print(json.dumps(row), flush=True)


def flight(folder, rate, seed, planted, value):
    effects, gust, fix = None, 0.0, []
    if planted == GUSTS:
        gust = value
    elif planted == PITCH[0]:
        fix = ["--fix", PITCH[1]]
    elif planted:
        effects = {planted: value}
    csv = folder / f"hfb320_{int(rate)}_{seed}_{planted or 'clean'}.csv".replace(
        ":", "_"
    )
    gen.write(csv, *gen.generate_hfb320(seed, rate, effects=effects, gust_sigma=gust))
    diag, proc, seconds = _cli(
        "diagnose", str(csv), "--vehicle", "hfb320", *fix, "--json"
    )
    row = {
        "rate": rate,
        "seed": seed,
        "planted": planted,
        "value": value,
        "diagnose_seconds": round(seconds, 1),
    }
    # the look-alike a short-period record cannot split
    alike = ("alpha_dot_damping",) if planted == PITCH[0] else ()
    significant = judge(row, diag, proc, planted, alike)
    pn = next(
        (r for r in (diag or {}).get("ranking", []) if r["effect"] == GUSTS), None
    )
    if pn is not None:
        ev = pn.get("turbulence_evidence") or {}
        row["process_noise"] = {
            "likelihood_ratio": pn["statistic"],
            "likelihood_ratio_passes": pn.get("likelihood_ratio_passes"),
            "check": [ev.get("statistic"), ev.get("output"), ev.get("threshold")],
            "input_timing": pn.get("input_timing"),
        }
    if significant is None:
        return row
    top = significant[0] if significant else None
    if top and top != GUSTS:
        fit, proc, fsec = _cli(
            "fit", str(csv), "--vehicle", "hfb320", *fix, "--add", top, "--json"
        )
        row["fit_seconds"] = round(fsec, 1)
        if fit is None:
            row["fit_error"] = proc.stderr.strip().splitlines()[-3:]
        else:
            se = fit.get("stderr", {})
            est = {k: v for k, v in fit["estimates"].items() if k.startswith(top + ".")}
            row["refit"] = {k: [v, se.get(k)] for k, v in est.items()}
    return row


def table():
    lines = [
        "| rate Hz | planted | named (significant) | top statistic / threshold "
        "| refit +/- se | right | diagnose s |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in _load():
        if "error" in r:
            lines.append(
                f"| {r['rate']:g} | {r['planted']} | error: {r['error'][-1]} | | | no | |"
            )
            continue
        top = r["top"][0] if r["top"] else {}
        refit = ""
        for k, (v, se) in (r.get("refit") or {}).items():
            refit = f"{k.split('.')[-1]} {v:.4g} +/- {se:.2g}" if se else f"{v:.4g}"
        planted = r["planted"] or "clean"
        if r["planted"] == GUSTS:
            planted = f"gusts {r['value']:g} m/s"
        elif r["planted"] == PITCH[0]:
            planted = "pitch damping removed (CMq=0)"
        elif r["planted"]:
            planted += f" {r['value']:g}"
        lines.append(
            f"| {r['rate']:g} | {planted} | {', '.join(r['significant']) or 'none'} "
            f"| {top.get('effect', '')} {top.get('statistic', float('nan')):.1f} / "
            f"{r['threshold'] if r['threshold'] is None else format(r['threshold'], '.1f')} "
            f"| {refit} | {'yes' if r['right'] else 'no'} | {r['diagnose_seconds']} |"
        )
    right = sum(r["right"] for r in _load())
    lines.append(f"\n{right} of {len(_load())} right")
    return "\n".join(lines)


def main():
    global OUT
    p = argparse.ArgumentParser()
    p.add_argument("--table", action="store_true", help="print the table and exit")
    p.add_argument("--max", type=int, default=None, help="flights at most this run")
    p.add_argument("--out", type=pathlib.Path, default=None)
    p.add_argument("--seeds", default=None, help="only these seeds, e.g. 221,201")
    args = p.parse_args()
    if args.out is not None:
        OUT = args.out.resolve()
    if args.table:
        print(table())
        return
    done = {(r["rate"], r["seed"], r["planted"]) for r in _load()}
    folder = pathlib.Path(tempfile.mkdtemp(prefix="acceptance_hfb320_"))
    count = 0
    seeds = None if args.seeds is None else [int(x) for x in args.seeds.split(",")]
    jobs = (
        FLIGHTS if seeds is None else [j for s in seeds for j in FLIGHTS if j[1] == s]
    )
    for job in jobs:
        if job[:3] in done:
            continue
        if args.max is not None and count >= args.max:
            break
        _append(flight(folder, *job))
        count += 1


if __name__ == "__main__":
    main()
