"""The coloured gust fit of the process-noise candidate under variants of the
filter's gain schedule and of the gust model, on one flight (measurement aid).

Runs `diagnose` in-process up to its process-noise candidate, keeps the
diagnosis's own white and coloured fits, refits the coloured model from the same
start under each variant, and writes per fit the innovations' check per output,
det R, the likelihood ratio's pieces and the correlation time; then stops.

    python experiments/gust_variants.py pegturb,100,7,1.5,10 base sched64 airspeed

Variants: `base` (the diagnosis's coloured fit, 16-point schedule), `schedN`
(N-point schedule), `airspeed` (the gust's correlation time `L / V`, the length
`L` estimated), `knotsK` (the diagnosis with K Mach functions). Results: experiments/results/gust_variants/<flight>.json.
"""

import dataclasses
import json
import pathlib
import sys
import time

import jax


jax.config.update("jax_enable_x64", True)
import numpy as np  # noqa: E402
from typer.testing import CliRunner  # noqa: E402


ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "experiments"))
import turbulence_check as tc  # noqa: E402

from diffpegasus._cli import app  # noqa: E402
from diffpegasus._diagnose import _process_noise as pn  # noqa: E402
from diffpegasus._estimate._filter_gain import ScheduledGain  # noqa: E402


OUT = ROOT / "experiments" / "results" / "gust_variants"
_original = pn.white_or_coloured
_variants: list[str] = []
_rows: dict = {}
_base: list[bool] = [True]
_arrays: dict = {}


class _Done(Exception):
    pass


def _row(fem, result, seconds):
    rule = pn.ProcessNoiseRule()
    ev = pn.turbulence_evidence(result, fem, rule)
    n = sum(len(r.t) for r in fem.records)
    per = np.zeros(len(fem.model.outputs))
    for rec, nu, y in zip(fem.records, fem.innovations, fem.outputs, strict=True):
        s, _ = pn.innovation_check(
            np.asarray(nu), np.column_stack([np.asarray(y), rec.inputs]), ev["lags"]
        )
        per += s
    params = dict(
        zip(fem.model.parameters, np.asarray(fem.params).tolist(), strict=True)
    )
    return {
        "converged": bool(fem.converged),
        "det_R": float(fem.cost),
        "N_ln_detR": n * float(np.log(fem.cost)),
        "unknowns": pn._unknowns(fem),
        "check": {
            o: round(float(v), 1) for o, v in zip(fem.model.outputs, per, strict=True)
        },
        "threshold": ev["threshold"],
        "passes": ev["passes"],
        "F": np.asarray(fem.F).tolist(),
        "gust_params": {k: v for k, v in params.items() if k.startswith("gust")},
        "seconds": seconds,
    }


def _wrapped(result, process_noise, gust, **fem_options):
    t0 = time.process_time()
    # without `base` the diagnosis's own coloured fit is skipped (white only)
    fem, choice = _original(
        result, process_noise, gust if _base[0] else None, **fem_options
    )
    fits = choice.get("fits", {"white": fem})
    for name, f in fits.items():
        _rows[name] = _row(f, result, time.process_time() - t0)
        _arrays[name] = f
    print({k: (v["check"], v["det_R"]) for k, v in _rows.items()}, flush=True)
    shared = pn._starts(result, process_noise, fem_options)
    white = fits["white"]
    start = white.params if white.converged else result.params
    for v in _variants:
        t0 = time.process_time()
        options, residuals, x0 = shared
        g = gust
        if v.startswith("sched"):
            options = {**options, "gain": ScheduledGain(int(v[5:]))}
        elif v == "airspeed":
            g = dataclasses.replace(gust, airspeed=gust.states[0])
        else:
            continue
        f = pn._fit_from(result, process_noise, (options, residuals, x0), start, g)
        _rows[v] = _row(f, result, time.process_time() - t0)
        _arrays[v] = f
        print(v, _rows[v], flush=True)
    raise _Done


def main():
    spec, *variants = sys.argv[1:]
    _variants.extend(v for v in variants if v != "base")
    _base[0] = "base" in variants
    pn.white_or_coloured = _wrapped
    OUT.mkdir(parents=True, exist_ok=True)
    csv, settings = tc._flight(spec)
    for v in variants:  # `knotsK`: K Mach functions instead of the flight's
        if v.startswith("knots"):
            settings = ("--knots", v[5:], *settings[2:])
    res = CliRunner().invoke(app, ["diagnose", str(csv), "--json", *settings])
    if not isinstance(res.exception, _Done):
        print(res.output[-3000:], res.exception)
    stem = spec.replace(",", "_") + "_" + "_".join(variants)
    (OUT / f"{stem}.json").write_text(json.dumps(_rows, indent=1))
    # innovations, predicted outputs and inputs of each fit (first record)
    np.savez(
        OUT / f"{stem}.npz",
        **{
            f"{k}_{what}": np.asarray(getattr(f, what)[0])
            for k, f in _arrays.items()
            for what in ("innovations", "outputs")
        },
        **{f"{k}_inputs": np.asarray(f.records[0].inputs) for k, f in _arrays.items()},
        **{f"{k}_t": np.asarray(f.records[0].t) for k, f in _arrays.items()},
    )
    print(json.dumps(_rows, indent=1))


if __name__ == "__main__":
    main()
