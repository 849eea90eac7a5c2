"""Acceptance-style run through the command line, as a user would.

Held-out launch-vehicle flights of the independent Pegasus-like generator
(`tests/independent_generator.py`, numpy/scipy only) at 50 Hz, 200 Hz and 1 kHz,
clean and with planted effects, and HFB-320 flights (the package's simulator with
`--hidden`, and the independent HFB-320 generator), each through

    diffpegasus diagnose LOG --vehicle V --json
    diffpegasus fit LOG --vehicle V --add EFFECT --json   (the top effect, if significant)

and the demo once (`diffpegasus demo --out DIR`). Flights run one after the other
and every result is appended to `experiments/results/acceptance.json` as soon as it
is known (a rerun skips the flights already there), so a partial run survives.

    nice python experiments/acceptance.py [--only pegasus|hfb320|demo] [--max N] [--out FILE]
"""

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time


HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
OUT = HERE / "results" / "acceptance.json"
sys.path.insert(0, str(ROOT / "tests"))

import independent_generator as gen  # noqa: E402


# (kind, rate Hz, seed, planted effect or None, value SI); run in this order
PEGASUS = [
    ("pegasus", 50.0, 1, "moment_offset", 0.006),
    ("pegasus", 50.0, 0, None, 0.0),
    ("pegasus", 200.0, 2, "actuator_delay", 0.04),
    ("pegasus", 50.0, 3, "sensor_bias:az", 0.3),
    ("pegasus", 1000.0, 4, None, 0.0),
    ("pegasus", 200.0, 5, "thrust_misalignment", 0.006),
    ("pegasus", 50.0, 6, "pitch_damping", -3.0),
    ("pegasus", 1000.0, 7, "moment_offset", 0.006),
    ("pegasus", 200.0, 8, None, 0.0),
    ("pegasus", 1000.0, 9, "sensor_bias:az", 0.3),
    ("pegasus", 50.0, 10, "thrust_misalignment", 0.006),
    ("pegasus", 200.0, 11, "pitch_damping", -3.0),
    ("pegasus", 1000.0, 12, "actuator_delay", 0.04),
    ("pegasus", 50.0, 13, None, 0.0),
]
HFB320 = [
    ("hfb320-independent", 20.0, 100, "sensor_bias:az", 0.1),
    ("hfb320-independent", 50.0, 1, None, 0.0),
    ("hfb320-package", 10.0, 3, "sensor_bias:az", 0.1),
]


def _cli(*args):
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "diffpegasus", *args],
        capture_output=True,
        text=True,
        env=env,
    )
    seconds = time.perf_counter() - t0
    out = None
    if proc.returncode == 0 and "--json" in args:
        out = json.loads(proc.stdout)
    return out, proc, seconds


def _load():
    return json.loads(OUT.read_text()) if OUT.exists() else []


def _append(row):
    rows = _load()
    rows.append(row)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    tmp = OUT.with_suffix(".tmp")
    tmp.write_text(json.dumps(rows, indent=1))
    tmp.replace(OUT)
    print(json.dumps(row), flush=True)


def _log(folder, kind, rate, seed, planted, value):
    stem = f"{kind}_{int(rate)}_{seed}_{planted or 'clean'}".replace(":", "_")
    csv = folder / f"{stem}.csv"
    effects = {planted: value} if planted else None
    if kind == "pegasus":
        gen.make_log(csv, seed, rate, 30.0, effects)
    elif kind == "hfb320-independent":
        gen.write(csv, *gen.generate_hfb320(seed, rate, effects=effects))
    else:
        hidden = ["--hidden", f"{planted}={value}"] if planted else []
        _, proc, _ = _cli(
            "simulate",
            "--vehicle",
            "hfb320",
            "--out",
            str(csv),
            "--seed",
            str(seed),
            "--sample-rate",
            str(rate),
            "--no-plot",
            *hidden,
        )
        if proc.returncode:
            raise RuntimeError(proc.stderr[-2000:])
    return csv


def _effect(row):
    # the engine names a row by parameter (`sensor_bias:az.bias`); the effect
    # is `effect` when present
    return row.get("effect") or row["parameter"].split(".")[0]


def judge(row, diag, proc, planted, alike=()):
    """Fill `row` from one `diagnose --json` report: the threshold, what was named,
    the top three, the planted effect's statistic, and whether the verdict is
    right (nothing named on a clean flight; else the planted effect, or one the
    report or `alike` says it cannot be told from, and nothing else). Returns the
    significant effects, or None when the command failed (`row` says why)."""
    if diag is None:
        row.update(error=proc.stderr.strip().splitlines()[-3:], right=False)
        return None
    ranking = diag["ranking"]
    significant = [_effect(r) for r in ranking if r["significant"]]
    rule = diag.get("rule", {})
    row.update(
        threshold=rule.get(
            "threshold", ranking[0].get("threshold") if ranking else None
        ),
        significant=significant,
        top=[
            {
                "effect": _effect(r),
                **{
                    k: r.get(k)
                    for k in (
                        "statistic",
                        "estimate",
                        "stderr",
                        "p_value",
                        "hard_to_tell_from",
                    )
                },
            }
            for r in ranking[:3]
        ],
    )
    mine = [r for r in ranking if planted and _effect(r) == planted]
    if mine:
        row["planted_statistic"] = mine[0]["statistic"]
        row["planted_score_estimate"] = [mine[0].get("estimate"), mine[0].get("stderr")]
    ok = {planted, *alike, *(mine[0].get("hard_to_tell_from") or [] if mine else [])}
    if planted is None:
        row["right"] = not significant
    else:
        row["right"] = bool(set(significant) & ok) and not (set(significant) - ok)
    return significant


def flight(folder, kind, rate, seed, planted, value):
    vehicle = "pegasus" if kind == "pegasus" else "hfb320"
    csv = _log(folder, kind, rate, seed, planted, value)
    diag, proc, seconds = _cli("diagnose", str(csv), "--vehicle", vehicle, "--json")
    row = {
        "kind": kind,
        "rate": rate,
        "seed": seed,
        "planted": planted,
        "value": value,
        "diagnose_seconds": round(seconds, 1),
    }
    significant = judge(row, diag, proc, planted)
    if significant is None:
        return row
    row.update(
        converged=diag["fit"]["converged"],
        iterations=diag["fit"].get("iterations"),
    )
    if significant:
        top = significant[0]
        # process noise is not an effect to add: its refit is the filter-error fit
        refit = ("--method", "fem") if top == "process_noise" else ("--add", top)
        fit, proc, fsec = _cli("fit", str(csv), "--vehicle", vehicle, *refit, "--json")
        row["fit_seconds"] = round(fsec, 1)
        if fit is None:
            row["fit_error"] = proc.stderr.strip().splitlines()[-3:]
        else:
            est = {k: v for k, v in fit["estimates"].items() if k.startswith(top + ".")}
            se = fit.get("stderr", {})
            row["refit"] = {k: [v, se.get(k)] for k, v in est.items()}
            if planted == top and len(est) == 1:
                ((k, v),) = est.items()
                if se.get(k):
                    row["refit_z"] = (v - value) / se[k]
    return row


def demo():
    out = pathlib.Path(tempfile.mkdtemp(prefix="demo_validate_"))
    _, proc, seconds = _cli("demo", "--out", str(out))
    return {
        "kind": "demo",
        "seconds": round(seconds, 1),
        "returncode": proc.returncode,
        "stdout": proc.stdout.strip().splitlines()[-40:],
        "stderr_tail": proc.stderr.strip().splitlines()[-3:],
    }


def table():
    """The markdown table of the results so far."""
    lines = [
        "| vehicle (log) | rate Hz | planted | found (significant) | top statistic / threshold "
        "| planted statistic | refit (or score) estimate +/- se | right | diagnose s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in _load():
        if r["kind"] == "demo":
            continue
        if "error" in r:
            lines.append(
                f"| {r['kind']} | {r['rate']:g} | {r['planted']} | error: "
                f"{r['error'][-1]} | | | | no | {r['diagnose_seconds']} |"
            )
            continue
        top = r["top"][0] if r["top"] else {}
        est = ""
        if r.get("refit"):
            ((k, (v, se)),) = list(r["refit"].items())[:1]
            est = f"refit {v:.4g} +/- {se:.2g}" if se else f"refit {v:.4g}"
            if "refit_z" in r:
                est += f" ({r['refit_z']:+.1f} se from {r['value']:g})"
        elif r.get("planted_score_estimate"):
            v, se = r["planted_score_estimate"]
            est = f"score {v:.4g} +/- {se:.2g} (planted {r['value']:g})"
        pstat = r.get("planted_statistic")
        lines.append(
            f"| {r['kind']} | {r['rate']:g} | {r['planted'] or 'clean'}"
            f"{'' if not r['planted'] else ' ' + format(r['value'], 'g')} "
            f"| {', '.join(r['significant']) or 'none'} "
            f"| {top.get('effect', '')} {top.get('statistic', float('nan')):.1f} / {r['threshold']:.1f} "
            f"| {'' if pstat is None else format(pstat, '.1f')} | {est} "
            f"| {'yes' if r['right'] else 'no'} | {r['diagnose_seconds']} |"
        )
    return "\n".join(lines)


def main():
    global OUT
    p = argparse.ArgumentParser()
    p.add_argument("--table", action="store_true", help="print the table and exit")
    p.add_argument("--only", choices=["pegasus", "hfb320", "demo"], default=None)
    p.add_argument("--max", type=int, default=None, help="flights at most this run")
    p.add_argument(
        "--flights",
        nargs="+",
        default=None,
        metavar="RATE:SEED",
        help="only these launch-vehicle flights (e.g. 50:13 200:8), in this order",
    )
    p.add_argument(
        "--out", type=pathlib.Path, default=None, help=f"results (default {OUT})"
    )
    args = p.parse_args()
    if args.out is not None:
        OUT = args.out.resolve()
    if args.table:
        print(table())
        return
    done = {
        (r["kind"], r.get("rate"), r.get("seed"), r.get("planted")) for r in _load()
    }
    jobs = []
    if args.only in (None, "hfb320"):
        jobs += HFB320
    if args.only in (None, "pegasus"):
        if args.flights:
            by = {f"{r:g}:{s}": job for job in PEGASUS for _, r, s, *_ in [job]}
            jobs += [by[f] for f in args.flights]
        else:
            jobs += PEGASUS
    folder = pathlib.Path(tempfile.mkdtemp(prefix="acceptance_"))
    count = 0
    for job in jobs:
        if job[:4] in done:
            continue
        if args.max is not None and count >= args.max:
            break
        _append(flight(folder, *job))
        count += 1
    if args.only in (None, "demo") and ("demo", None, None, None) not in done:
        _append(demo())


if __name__ == "__main__":
    main()
