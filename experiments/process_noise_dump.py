"""Dump the output-error and filter-error fits of held-out flights (measurement aid)."""

import pathlib
import pickle
import sys
import time

import jax


jax.config.update("jax_enable_x64", True)
import numpy as np  # noqa: E402


ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
import independent_generator as gen  # noqa: E402

from diffpegasus._cli._runners import _fit_spec  # noqa: E402
from diffpegasus._diagnose._candidates import score_candidates  # noqa: E402
from diffpegasus._diagnose._process_noise import process_noise_candidate  # noqa: E402
from diffpegasus._registry import vehicle_entry  # noqa: E402


OUT = ROOT / "experiments" / "results" / "pnoise"


def run(kind, rate, seed, sigma=0.0, planted=None, value=0.0, vehicle="pegasus"):
    stem = f"{kind}_{int(rate)}_{seed}_{sigma:g}_{planted or 'clean'}".replace(":", "_")
    dest = OUT / f"{stem}.pkl"
    if dest.exists():
        return
    csv = pathlib.Path("/tmp/pnoise_logs") / f"{stem}.csv"
    csv.parent.mkdir(exist_ok=True)
    if kind == "pegasus":
        if sigma > 0:
            gen.make_turbulent_log(csv, seed, rate, 30.0, sigma)
        else:
            gen.make_log(csv, seed, rate, 30.0, {planted: value} if planted else None)
    elif kind == "hfb320":
        gen.write(
            csv,
            *gen.generate_hfb320(
                seed,
                rate,
                effects={planted: value} if planted else None,
                **({"turbulence": sigma} if sigma else {}),
            ),
        )
    elif kind == "hfbpkg":
        import os
        import subprocess

        hidden = ["--hidden", f"turbulence={sigma}"] if sigma else []
        subprocess.run(
            [
                sys.executable,
                "-m",
                "diffpegasus",
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
            ],
            check=True,
            env=dict(os.environ, PYTHONPATH=str(ROOT / "src")),
            capture_output=True,
        )
    t0 = time.perf_counter()
    entry = vehicle_entry(vehicle)
    from diffpegasus._log._format import read_log

    spec, records = entry.problem([read_log(csv)], candidates=True)
    spec, result = _fit_spec(spec, [csv], None, (), None, None, None, records, None)
    ranking = score_candidates(result, spec.candidates)
    t1 = time.perf_counter()
    fem, new, message = process_noise_candidate(
        result, ranking, tuple(spec.process_noise), gain=None
    )
    t2 = time.perf_counter()
    d = dict(
        kind=kind,
        rate=rate,
        seed=seed,
        sigma=sigma,
        planted=planted,
        oe_seconds=t1 - t0,
        fem_seconds=t2 - t1,
        oe_residuals=[
            np.asarray(r.measured - y)
            for r, y in zip(result.records, result.outputs, strict=True)
        ],
        oe_R=np.asarray(result.R),
        oe_cost=float(result.cost),
        oe_converged=result.converged,
        inputs=[np.asarray(r.inputs) for r in result.records],
        measured=[np.asarray(r.measured) for r in result.records],
        outputs=tuple(result.model.outputs),
        states=tuple(result.model.states),
        fem_innov=[np.asarray(x) for x in fem.innovations],
        fem_R=np.asarray(fem.R),
        fem_cost=float(fem.cost),
        fem_converged=fem.converged,
        F=np.asarray(fem.F),
        gain=np.asarray(fem.gain),
        noise_states=fem.process_noise,
        ranking=new,
        message=message,
        oe_ranking=ranking,
    )
    pickle.dump(d, open(dest, "wb"))
    pn = next(r for r in new if r["effect"] == "process_noise")
    print(
        stem,
        f"LR {pn['statistic']:.0f} N {sum(len(r.t) for r in result.records)} oe {t1 - t0:.0f}s fem {t2 - t1:.0f}s",
        [r["effect"] for r in ranking if r["significant"]],
        flush=True,
    )


if __name__ == "__main__":
    for spec in sys.argv[1:]:
        a = spec.split(",")
        run(
            a[0],
            float(a[1]),
            int(a[2]),
            float(a[3]),
            a[4] if len(a) > 4 and a[4] else None,
            float(a[5]) if len(a) > 5 else 0.0,
            "hfb320" if a[0] in ("hfb320", "hfbpkg") else "pegasus",
        )
