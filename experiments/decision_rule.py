"""The decision rule calibrated on the log, measured on flights of the independent
generators (`tests/independent_generator.py`: numpy/scipy only, its own
atmosphere, tables, motor, integrator, true steps between samples).

Parts (`--part`):

- `pegasus`: Pegasus-like flights, 30 s from drop, at `--rates` (Hz), clean
  (`--clean` seeds) and with each planted effect of `PLANTED` (`--planted` seeds):
  the discrepancy workflow's baseline fit (run to convergence) and
  `diagnose`: the threshold from the log, the order of its null's
  autoregression, what is significant, the largest statistics, the planted effect's statistic and p-value.
- `hfb320`: HFB-320 flights at `--rates` (Hz), clean and with a planted az bias,
  through `diagnose --vehicle hfb320` (the engine's path, the same rule).
- `refit`: is the efficient score on resampled residuals at the fitted Jacobian
  what a refit gives? On one HFB-320 flight, `--replicates` data sets = the fitted
  model's outputs + block-resampled residuals: each refitted (baseline unknowns
  free, candidates held) and scored, against the same residuals through the fitted
  Jacobian without refitting.

- `colour`: false alarms on a linear problem with a known null, by the
  residuals' colour (AR(1) 0, 0.5, 0.9), with and without the bootstrap's
  replicates refitted (`--replicates` data sets each).

Each part appends one JSON line per flight to `experiments/results/decision_rule/
<part>.jsonl` (resumable) and writes `<part>.summary.json`.

Run: `python experiments/decision_rule.py --part pegasus --rates 50 200
--clean 6 --planted 2` (about 2 min a flight on a loaded 2-core machine);
`--part hfb320 --rates 10 50 --clean 12 --planted 6`; `--part refit`.
"""

import argparse
import json
import pathlib
import sys
import tempfile
import time

import numpy as np


HERE = pathlib.Path(__file__).resolve().parent
OUT = HERE / "results" / "decision_rule"
sys.path.insert(0, str(HERE.parent / "tests"))

import independent_generator as gen  # noqa: E402


PLANTED = [
    ("moment_offset", 0.006),
    ("thrust_misalignment", 0.006),
    ("actuator_delay", 0.04),
    ("sensor_bias:az", 0.3),
    ("pitch_damping", -3.0),
]


def _lines(path):
    if not path.exists():
        return []
    return [json.loads(x) for x in path.read_text().splitlines() if x]


def _row(result, planted, extra):
    ranking = result["ranking"]
    by_stat = sorted(ranking, key=lambda r: -r["statistic"])
    row = {
        **extra,
        "threshold": result["rule"]["threshold"],
        "false_alarm_level": result["rule"]["false_alarm_level"],
        "null_order": result["rule"]["null_order"],
        "significant": result["significant"],
        "largest": [
            {k: r[k] for k in ("effect", "statistic", "p_value", "estimate")}
            for r in by_stat[:4]
        ],
    }
    if planted is not None:
        mine = [r for r in ranking if r["effect"] == planted]
        if mine:
            row["planted_statistic"] = mine[0]["statistic"]
            row["planted_p"] = mine[0]["p_value"]
            row["planted_estimate"] = mine[0]["estimate"]
            close = [
                c if isinstance(c, str) else c["effect"]
                for c in mine[0]["hard_to_tell_from"]
            ]
            row["planted_alike"] = close
    return row


def judge(row, planted):
    """Right: a clean flight flags nothing; a planted one flags the planted effect
    (or one the data cannot tell from it) and nothing unrelated."""
    sig = set(row["significant"])
    if planted is None:
        return not sig
    ok = {planted, *row.get("planted_alike", [])}
    return bool(sig & ok) and not (sig - ok)


def pegasus(args):
    import diffpegasus as dp
    from diffpegasus.discrepancy import diagnose, fit, Settings

    path = OUT / "pegasus.jsonl"
    done = {(r["rate"], r["seed"], r["planted"]) for r in _lines(path)}
    settings = Settings()
    jobs = []
    for rate in args.rates:
        jobs += [(rate, s, None, 0.0) for s in range(args.clean)]
        for name, value in PLANTED:
            jobs += [(rate, s, name, value) for s in range(args.planted)]
    folder = pathlib.Path(tempfile.mkdtemp(prefix="rule_"))
    for rate, seed, name, value in jobs:
        if (rate, seed, name) in done:
            continue
        csv = gen.make_log(
            folder / f"f_{seed}_{int(rate)}.csv",
            seed,
            rate,
            30.0,
            {name: value} if name else None,
        )
        log = dp.read_log(csv)
        t0 = time.perf_counter()
        base = fit(log, (), settings)
        result = diagnose(base, settings)
        row = _row(
            result,
            name,
            {
                "rate": rate,
                "seed": seed,
                "planted": name,
                "value": value,
                "converged": bool(base.result.converged),
                "iterations": int(base.result.iterations),
                "defect": float(base.result.defect),
                "seconds": time.perf_counter() - t0,
            },
        )
        row["right"] = judge(row, name) and row["converged"]
        with open(path, "a") as f:
            f.write(json.dumps(row) + "\n")
        print(json.dumps(row), flush=True)
    summarise(path)


def hfb320(args):
    from diffpegasus._cli._runners import run_model_diagnose
    from diffpegasus._registry import vehicle_spec

    path = OUT / "hfb320.jsonl"
    done = {(r["rate"], r["seed"], r["planted"]) for r in _lines(path)}
    folder = pathlib.Path(tempfile.mkdtemp(prefix="rule_hfb_"))
    jobs = []
    for rate in args.rates:
        jobs += [(rate, s, None, 0.0) for s in range(args.clean)]
        jobs += [(rate, 100 + s, "sensor_bias:az", 0.1) for s in range(args.planted)]
    for rate, seed, name, value in jobs:
        if (rate, seed, name) in done:
            continue
        channels, meta = gen.generate_hfb320(
            seed, rate, effects={name: value} if name else None
        )
        csv = gen.write(folder / f"h_{seed}_{int(rate)}.csv", channels, meta)
        t0 = time.perf_counter()
        report = run_model_diagnose(vehicle_spec("hfb320", candidates=True), [csv])
        # the engine names rows by parameter: the planted bias is sensor_bias:az.bias
        report["ranking"] = [dict(r, effect=r["parameter"]) for r in report["ranking"]]
        report["significant"] = [
            r["effect"] for r in report["ranking"] if r["significant"]
        ]
        row = _row(
            report,
            None if name is None else "sensor_bias:az.bias",
            {
                "rate": rate,
                "seed": seed,
                "planted": name,
                "value": value,
                "converged": bool(report["fit"]["converged"]),
                "seconds": time.perf_counter() - t0,
                "resolution_limits": [
                    r["effect"] for r in report["ranking"] if r["resolution_limit"]
                ],
            },
        )
        row["right"] = judge(row, None if name is None else "sensor_bias:az.bias")
        with open(path, "a") as f:
            f.write(json.dumps(row) + "\n")
        print(json.dumps(row), flush=True)
    summarise(path)


def refit(args):
    """Refit versus the efficient score at the fitted Jacobian, per replicate."""
    import jax
    import jax.numpy as jnp

    from diffpegasus._cli._runners import _fit_spec
    from diffpegasus._diagnose._calibration import _spectra, _statistics, block_length
    from diffpegasus._estimate._fit import fit as engine_fit
    from diffpegasus._estimate._model import Record
    from diffpegasus._estimate._score import score
    from diffpegasus._registry import vehicle_spec

    folder = pathlib.Path(tempfile.mkdtemp(prefix="rule_refit_"))
    channels, meta = gen.generate_hfb320(args.seed, args.rates[0])
    csv = gen.write(folder / "h.csv", channels, meta)
    spec = vehicle_spec("hfb320", candidates=True)
    spec, result = _fit_spec(spec, [csv], None, (), None, None, None)
    model = result.model
    names = list(model.parameters)
    idx = np.array([names.index(c) for c in spec.candidates])
    nx, p = len(model.states), len(names)

    def test_at(res):
        return score(
            res.model.structure(),
            res.layout,
            jnp.asarray(res.z),
            jnp.asarray(res.R),
            jnp.asarray(res.free),
            jnp.asarray(idx),
            nx=nx,
            p=p,
        )

    st = test_at(result)
    valid = np.asarray(st.valid, bool)
    rows = np.asarray(st.rows)[valid]
    ew = np.asarray(st.residuals)[valid]
    offset = np.asarray(st.slope) - np.einsum("nok,no->k", rows, ew)
    sp = _spectra(jnp.asarray(rows), jnp.asarray(st.curvature), jnp.asarray(offset))
    basis = np.asarray(st.basis)[valid]
    basis = basis[..., np.any(basis != 0.0, axis=(0, 1))]
    sp_refit = _spectra(
        jnp.asarray(rows),
        jnp.asarray(st.curvature),
        jnp.asarray(offset),
        jnp.asarray(basis),
    )
    block = block_length(ew)
    w = np.sqrt(np.asarray(result.R))  # whitened -> SI
    record = result.records[0]
    fitted = np.asarray(record.measured) - ew * w[None, :]
    rng = np.random.default_rng(args.seed)
    n = ew.shape[0]
    pairs = []
    for i in range(args.replicates):
        starts = rng.integers(0, n, n)
        t = np.arange(n)
        index = (starts[t // block] + t % block) % n
        e_star = ew[index]
        without = np.asarray(_statistics(sp, jnp.asarray(e_star)))
        # the same residuals first refitted to first order (what `diagnose` does)
        projected = np.asarray(_statistics(sp_refit, jnp.asarray(e_star), refit=True))
        data = Record(
            record.t, record.inputs, fitted + e_star * w[None, :], x0=record.x0
        )
        again = engine_fit(
            model,
            [data],
            shooting=spec.shooting,
            initial_state=spec.initial_state,
            biases=spec.biases,
            throw=False,
        )
        with_refit = np.asarray(test_at(again).statistic)
        pairs.append(
            {
                "without": without.tolist(),
                "projected": projected.tolist(),
                "refit": with_refit.tolist(),
            }
        )
        print(
            i,
            round(float(without.max()), 2),
            round(float(projected.max()), 2),
            round(float(with_refit.max()), 2),
            flush=True,
        )
    a = np.array([x["without"] for x in pairs])
    c = np.array([x["projected"] for x in pairs])
    b = np.array([x["refit"] for x in pairs])
    summary = {
        "seed": args.seed,
        "rate": args.rates[0],
        "replicates": args.replicates,
        "block_samples": block,
        "candidates": list(spec.candidates),
        "max_without": a.max(axis=1).tolist(),
        "max_projected": c.max(axis=1).tolist(),
        "max_refit": b.max(axis=1).tolist(),
        "mean_max": {
            "without": float(a.max(axis=1).mean()),
            "projected": float(c.max(axis=1).mean()),
            "refit": float(b.max(axis=1).mean()),
        },
        "p90_max": {
            "without": float(np.quantile(a.max(axis=1), 0.9)),
            "projected": float(np.quantile(c.max(axis=1), 0.9)),
            "refit": float(np.quantile(b.max(axis=1), 0.9)),
        },
        "median_relative_difference_projected": float(
            np.median(np.abs(c - b) / (b + 1e-9))
        ),
        "correlation_of_maxima_projected": float(
            np.corrcoef(c.max(axis=1), b.max(axis=1))[0, 1]
        ),
        "median_relative_difference": float(np.median(np.abs(a - b) / (b + 1e-9))),
        "correlation_of_maxima": float(np.corrcoef(a.max(axis=1), b.max(axis=1))[0, 1]),
        "pairs": pairs,
    }
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "refit.summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps({k: v for k, v in summary.items() if k != "pairs"}, indent=2))
    del jax


def summarise(path):
    rows = _lines(path)
    table = {}
    for r in rows:
        key = f"{r['planted'] or 'clean'} @ {r['rate']:g} Hz"
        t = table.setdefault(
            key, {"flights": 0, "right": 0, "thresholds": [], "planted_statistics": []}
        )
        t["flights"] += 1
        t["right"] += bool(r["right"])
        t["thresholds"].append(round(r["threshold"], 1))
        if "planted_statistic" in r:
            t["planted_statistics"].append(round(r["planted_statistic"], 1))
        if r["planted"] is None:
            t.setdefault("largest_clean_statistics", []).append(
                round(r["largest"][0]["statistic"], 1)
            )
            t.setdefault("false_alarms", 0)
            t["false_alarms"] += bool(r["significant"])
    summary = {
        "flights": len(rows),
        "right": sum(bool(r["right"]) for r in rows),
        "clean_flagged": sum(
            bool(r["significant"]) for r in rows if r["planted"] is None
        ),
        "clean": sum(r["planted"] is None for r in rows),
        "table": table,
    }
    path.with_suffix(".summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary, indent=2))
    return summary


def colour(args):
    """False alarms of the rule on a linear problem with known null, by residual
    colour: 2 outputs, 400 samples, AR(1) noise of coefficient `phi` (0, 0.5,
    0.9), the free unknowns a constant and a slope on each of 10 segments per
    output (the shape of shooting nodes), 5 smooth candidates projected on them.
    Each of `--replicates` data sets is fitted (projected, whitened again), its
    largest statistic judged against the (sieve-)bootstrap threshold at level 0.05
    from its own residuals, with and without the replicates refitted."""
    from _shared import segment_projection

    from diffpegasus._diagnose._calibration import calibrate, statistics

    n, o, k = 400, 2, 5
    t, basis, refit = segment_projection(n, o)

    raw = np.stack(
        [
            np.stack(
                [
                    np.sin(2 * np.pi * (j + 1) * 1.3 * t),
                    np.cos(2 * np.pi * (j + 1) * 0.7 * t),
                ],
                -1,
            )
            for j in range(k)
        ],
        -1,
    )
    rows0 = np.stack([refit(raw[..., j]) for j in range(k)], -1)
    out = {}
    for phi in (0.0, 0.5, 0.9):
        rng = np.random.default_rng(args.seed)
        alarms = {"without_refit": 0, "with_refit": 0}
        thresholds = {"without_refit": [], "with_refit": []}
        for _ in range(args.replicates):
            w = rng.normal(size=(n + 200, o))
            x = np.zeros_like(w)
            for i in range(1, len(w)):
                x[i] = phi * x[i - 1] + w[i]
            e = refit(x[200:])
            c = np.sqrt(np.mean(e**2, axis=0))
            rows, e = rows0 / c[None, :, None], e / c
            curvature = np.einsum("nok,nok->k", rows, rows)
            slope = np.einsum("nok,no->k", rows, e)
            observed = statistics(rows, e, curvature, slope).max()
            for key, b in (("without_refit", None), ("with_refit", basis)):
                cal = calibrate(
                    rows, e, curvature, slope, level=0.05, replicates=1000, basis=b
                )
                alarms[key] += bool(observed > cal.threshold)
                thresholds[key].append(cal.threshold)
        out[str(phi)] = {
            "data_sets": args.replicates,
            "level": 0.05,
            "false_alarms": alarms,
            "median_threshold": {
                k_: float(np.median(v)) for k_, v in thresholds.items()
            },
            "null_order_last": int(cal.order),
        }
        print(phi, out[str(phi)], flush=True)
    (OUT / "colour.summary.json").write_text(json.dumps(out, indent=2))


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--part", choices=("pegasus", "hfb320", "refit", "colour"), required=True
    )
    parser.add_argument("--rates", type=float, nargs="+", default=[50.0])
    parser.add_argument("--clean", type=int, default=6)
    parser.add_argument("--planted", type=int, default=2)
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--replicates", type=int, default=20)
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    parts = {"pegasus": pegasus, "hfb320": hfb320, "refit": refit, "colour": colour}
    parts[args.part](args)


if __name__ == "__main__":
    main()
