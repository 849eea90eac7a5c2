"""The innovations' check of the process-noise candidate, output by output, on
launch-vehicle and HFB-320 flights (measurement aid for choosing the check).

Runs `diagnose` in-process on each flight and records, where the likelihood ratio
passes, what the check sees: per output its `N R^2`, whether a process-noise state
drives that output directly (a non-zero column of the output function's Jacobian
in a noisy state), and the filter's innovations, predicted outputs and inputs, so
that variants of the check can be recomputed offline.

    python experiments/turbulence_check.py pegturb,100,7,1.5,10 pegclean,50,13 ...

`pegturb,RATE,SEED,SIGMA,SECONDS[,knotsK]`: the independent generator's turbulent
launch-vehicle flight (diagnosed with `--knots K --rate 25` when SECONDS <= 10, K 4
by default as the test suite does); `pegcalm,RATE,SEED,SECONDS[,knotsK]`: the same
flight in calm air (`make_log`, the test suite's calm flight); `pegclean,RATE,SEED[,EFFECT,VALUE]`: its 30 s acceptance
flight; `hfbgust,SIGMA,SEED` / `hfbcmq,SIGMA,SEED`: the package's HFB-320 simulator, 30 s
at 10 Hz in Dryden gusts (CMq held at 0); `hfbreal`: the real HFB-320 record.
Results: one pickle per flight under experiments/results/turbulence_check/ and a
line on stdout. `python experiments/turbulence_check.py summary` recomputes the
check and its variants from the pickles (`variants`) into
experiments/results/turbulence_check.json.
"""

import json
import pathlib
import pickle
import sys
import time

import jax


jax.config.update("jax_enable_x64", True)
import numpy as np  # noqa: E402
import scipy.stats  # noqa: E402
from typer.testing import CliRunner  # noqa: E402


ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
import independent_generator as gen  # noqa: E402

from diffpegasus._cli import app  # noqa: E402
from diffpegasus._diagnose import _process_noise as pn  # noqa: E402


OUT = ROOT / "experiments" / "results" / "turbulence_check"
LOGS = pathlib.Path("/tmp/turbulence_check_logs")
_seen: dict = {}
_original = pn.turbulence_evidence


def _driven(fem) -> np.ndarray:
    """Outputs a process-noise state enters directly: the output function's
    Jacobian `dg/dx` non-zero in a noisy state's column, at each record's first
    sample and at a point 1% off it."""
    model = fem.model
    noisy = [model.states.index(s) for s in fem.process_noise]
    mask = np.zeros(len(model.outputs), bool)
    theta = jax.numpy.asarray(fem.params)
    for rec in fem.records:
        x0 = rec.x0 if rec.x0 is not None else rec.measured_states(model, [0])[0]
        x0 = np.where(np.isfinite(x0), x0, 1.0)
        u0 = jax.numpy.asarray(rec.inputs[0])
        for x in (x0, 1.01 * x0 + 0.01):
            jac = jax.jacfwd(model.g, argnums=1)(
                rec.t[0], jax.numpy.asarray(x), u0, theta
            )
            mask |= np.any(np.asarray(jac)[:, noisy] != 0, axis=1)
    return mask


def _recording(result, fem, rule, innovations=None):
    out = _original(result, fem, rule, innovations)
    n = sum(len(r.t) for r in fem.records)
    lags = out["lags"]
    per = np.zeros(len(fem.model.outputs))
    for rec, nu, y in zip(fem.records, fem.innovations, fem.outputs, strict=True):
        s, _ = pn.innovation_check(
            np.asarray(nu), np.column_stack([np.asarray(y), rec.inputs]), lags
        )
        per += s
    # every call (the judged fit with its input-timing adjusted innovations, then
    # the report's check of each noise model's fit); the first is the verdict's
    d = dict(
        evidence=out,
        per_output=dict(zip(fem.model.outputs, per.tolist(), strict=True)),
        driven=dict(
            zip(
                fem.model.outputs,
                _driven(fem).tolist(),
                strict=True,
            )
        ),
        innovations=[np.asarray(x) for x in fem.innovations],
        adjusted=None if innovations is None else [np.asarray(x) for x in innovations],
        predicted=[np.asarray(x) for x in fem.outputs],
        inputs=[np.asarray(r.inputs) for r in fem.records],
        outputs=tuple(fem.model.outputs),
        oem_residuals=[
            np.asarray(r.measured) - np.asarray(y)
            for r, y in zip(result.records, result.outputs, strict=True)
        ],
        oem_predicted=[np.asarray(y) for y in result.outputs],
        measured=[np.asarray(r.measured) for r in fem.records],
        noise_states=fem.process_noise,
        F=np.asarray(fem.F),
        R=np.asarray(fem.R),
        samples=n,
        states=tuple(fem.model.states),
    )
    if "evidence" not in _seen:
        _seen.update(d)
    _seen.setdefault("calls", []).append(d)
    return out


pn.turbulence_evidence = _recording


def _knots(extra: list) -> str:
    """`knotsK` among a spec's trailing fields: K Mach functions (4 if absent)."""
    return next((x[5:] for x in extra if x.startswith("knots")), "4")


def _flight(spec: str):
    a = spec.split(",")
    LOGS.mkdir(exist_ok=True)
    settings: tuple[str, ...] = ()
    if a[0] == "pegturb":
        rate, seed, sigma, seconds = float(a[1]), int(a[2]), float(a[3]), float(a[4])
        csv = LOGS / f"pegturb_{int(rate)}_{seed}_{sigma:g}_{seconds:g}.csv"
        if not csv.exists():
            gen.make_turbulent_log(csv, seed, rate, seconds, sigma)
        if seconds <= 10:
            settings = ("--knots", _knots(a[5:]), "--rate", "25")
    elif a[0] == "pegcalm":
        rate, seed, seconds = float(a[1]), int(a[2]), float(a[3])
        csv = LOGS / f"pegcalm_{int(rate)}_{seed}_{seconds:g}.csv"
        if not csv.exists():
            gen.make_log(csv, seed, rate, seconds)
        settings = ("--knots", _knots(a[4:]), "--rate", "25")
    elif a[0] == "pegclean":
        rate, seed = float(a[1]), int(a[2])
        effects = {a[3]: float(a[4])} if len(a) > 4 else None
        csv = LOGS / f"pegclean_{int(rate)}_{seed}_{a[3] if effects else 'clean'}.csv"
        csv = pathlib.Path(str(csv).replace(":", "_"))
        if not csv.exists():
            gen.make_log(csv, seed, rate, 30.0, effects)
    elif a[0] == "hfbreal":
        sys.path.insert(0, str(ROOT / "experiments"))
        from hfb320 import DEFAULT_DATA

        csv = pathlib.Path(DEFAULT_DATA)
        settings = ("--vehicle", "hfb320")
    elif a[0] in ("hfbgust", "hfbcmq"):
        return None, (float(a[1]), int(a[2]))
    else:
        raise SystemExit(f"unknown flight {spec}")
    return csv, settings


def _hfb_package(cmq_held: bool, sigma: float, seed: int) -> dict:
    """A 30 s, 10 Hz flight of the package's HFB-320 simulator in Dryden gusts
    `sigma` m/s through `dp.diagnose_model` (CMq held at 0 with `cmq_held`)."""
    import diffpegasus as dp
    from diffpegasus._registry import vehicle_spec
    from diffpegasus._registry._hfb320_simulator import simulate_log, simulated_record

    spec = vehicle_spec("hfb320", candidates=True)
    model = spec.model
    if cmq_held:
        model = model.replace(start={"CMq": 0.0}, fixed=(*model.fixed, "CMq"))
    rec = simulated_record(simulate_log(duration=30.0, seed=seed, turbulence=sigma)[0])
    _, ranking = dp.diagnose_model(
        model,
        rec,
        spec.candidates,
        process_noise=("V", "alpha", "theta", "q"),
        throw=False,
    )
    return {
        "ranking": ranking,
        "significant": [r["effect"] for r in ranking if r["significant"]],
    }


def _r2(y, x):
    q, _ = np.linalg.qr(x)
    fitted = q @ (q.T @ y)
    return float(fitted @ fitted) / float(y @ y)


def _standardised(z):
    z = z[:, np.std(z, axis=0) > 0]
    return (z - z.mean(axis=0)) / z.std(axis=0)


def variants(d: dict) -> dict:
    """Per output, the check and the variants measured against it, each `N R^2`
    with its degrees of freedom: `full` the check as it stands (own lags,
    predicted outputs, inputs), `lags` own lags only (whiteness),
    `inputs_given_lags` the inputs' share beyond the own lags (exogeneity:
    `N (R^2[lags, inputs] - R^2[lags])`), `signals_given_lags` the predicted
    outputs' and inputs' share beyond the own lags, `lags_given_signals` the own
    lags' share beyond the predicted outputs and inputs (whiteness of the part
    the flight's signals do not predict); the records' statistics and
    degrees of freedom add."""
    lags = d["evidence"]["lags"]
    names = (
        "full",
        "lags",
        "inputs_given_lags",
        "signals_given_lags",
        "lags_given_signals",
    )
    stat = {k: np.zeros(len(d["outputs"])) for k in names}
    dof = dict.fromkeys(names, 0)
    judged = d.get("adjusted") or d["innovations"]
    for nu, yhat, u in zip(judged, d["predicted"], d["inputs"], strict=True):
        nu, yhat, u = np.asarray(nu), _standardised(yhat), _standardised(u)
        n = len(nu)
        one = np.ones((n, 1))
        for i in range(nu.shape[1]):
            y = nu[:, i] - nu[:, i].mean()
            own = np.column_stack(
                [np.concatenate([np.zeros(j), y[:-j]]) for j in range(1, lags + 1)]
            )
            r_lags = _r2(y, np.column_stack([one, own]))
            r_full = _r2(y, np.column_stack([one, own, yhat, u]))
            r_u = _r2(y, np.column_stack([one, own, u]))
            r_signals = _r2(y, np.column_stack([one, yhat, u]))
            stat["full"][i] += n * r_full
            stat["lags"][i] += n * r_lags
            stat["inputs_given_lags"][i] += n * (r_u - r_lags)
            stat["signals_given_lags"][i] += n * (r_full - r_lags)
            stat["lags_given_signals"][i] += n * (r_full - r_signals)
        dof["full"] += lags + yhat.shape[1] + u.shape[1]
        dof["lags"] += lags
        dof["inputs_given_lags"] += u.shape[1]
        dof["signals_given_lags"] += yhat.shape[1] + u.shape[1]
        dof["lags_given_signals"] += lags
    m = len(d["outputs"])
    driven = [d["driven"][o] for o in d["outputs"]]
    out = {}
    for k in names:
        every = float(scipy.stats.chi2.isf(0.01 / m, dof[k]))
        some = float(scipy.stats.chi2.isf(0.01 / sum(driven), dof[k]))
        out[k] = {
            "dof": dof[k],
            "threshold": every,
            "threshold_driven_only": some,
            "statistic": dict(
                zip(d["outputs"], stat[k].round(1).tolist(), strict=True)
            ),
            "passes": bool(stat[k].max() <= every),
            "passes_driven_only": bool(
                max(v for v, dv in zip(stat[k], driven, strict=True) if dv) <= some
            ),
        }
    return out


def _cell(v: dict, driven: list, driven_only: bool) -> str:
    stat = {o: x for o, x in v["statistic"].items() if o in driven or not driven_only}
    worst = max(stat, key=stat.get)
    threshold = v["threshold_driven_only" if driven_only else "threshold"]
    verdict = "passes" if stat[worst] <= threshold else "**fails**"
    return f"{stat[worst]:.1f} ({worst}) vs {threshold:.1f}, {verdict}"


def summary():
    """Every measured flight's variants to experiments/results/turbulence_check.json
    and a markdown table on stdout: the likelihood ratio, what is named today,
    then per variant the largest statistic (its output) against its chi-square
    point (0.01, Bonferroni over the outputs judged)."""
    rows = []
    for f in sorted(OUT.glob("*.pkl")):
        d = pickle.load(open(f, "rb"))
        row = {
            "flight": d["spec"],
            "samples": d.get("samples"),
            "likelihood_ratio": d["lr"],
            "named": d["significant"],
            "seconds": round(d["seconds"]),
        }
        if "innovations" in d:
            row["driven"] = [o for o in d["outputs"] if d["driven"][o]]
            row["variants"] = variants(d)
        rows.append(row)
        v = row.get("variants")
        cells = (
            [
                _cell(v["full"], row["driven"], False),
                _cell(v["full"], row["driven"], True),
                *(
                    _cell(v[k], row["driven"], False)
                    for k in (
                        "lags",
                        "inputs_given_lags",
                        "signals_given_lags",
                        "lags_given_signals",
                    )
                ),
            ]
            if v
            else ["(likelihood ratio fails)"] + [""] * 4
        )
        print(
            f"| {d['spec']} | {d['lr']:.0f} | {', '.join(d['significant']) or '-'} | "
            + " | ".join(cells)
            + " |"
        )
    if rows:  # the pickles are not kept in the repository: keep the last summary
        (OUT.parent / "turbulence_check.json").write_text(json.dumps(rows, indent=1))


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    if sys.argv[1:] == ["summary"]:
        return summary()
    for spec in sys.argv[1:]:
        stem = spec.replace(",", "_").replace(":", "_")
        if (OUT / f"{stem}.pkl").exists():
            continue
        csv, settings = _flight(spec)
        _seen.clear()
        t0 = time.perf_counter()
        if csv is None:
            report = _hfb_package(spec.startswith("hfbcmq"), *settings)
        else:
            res = CliRunner().invoke(app, ["diagnose", str(csv), "--json", *settings])
            if res.exit_code != 0:
                print(spec, "failed", res.output[-2000:], flush=True)
                continue
            report = json.loads(res.stdout.strip().splitlines()[-1])
        seconds = time.perf_counter() - t0
        row = next(r for r in report["ranking"] if r["effect"] == "process_noise")
        d = dict(
            spec=spec,
            seconds=seconds,
            significant=report["significant"],
            lr=row["statistic"],
            lr_passes=row.get("likelihood_ratio_passes"),
            report=report,
            **_seen,
        )
        pickle.dump(d, open(OUT / f"{stem}.pkl", "wb"))
        per = d.get("per_output")
        print(
            spec,
            f"{seconds:.0f}s LR {row['statistic']:.0f} named {report['significant']}",
            "check",
            {k: round(v, 1) for k, v in per.items()} if per else "-",
            "threshold",
            round(d["evidence"]["threshold"], 1) if per else "-",
            "driven",
            [k for k, v in d.get("driven", {}).items() if v],
            flush=True,
        )


if __name__ == "__main__":
    main()
