"""The process-noise candidate on HFB-320 flights (package simulator, 30 s at 10 Hz),
the independent generator's clean HFB-320 flight and the real HFB-320 record:
likelihood ratio, the innovations' check and the verdict. Measurement aid."""

import json
import pathlib
import sys
import time

import jax


jax.config.update("jax_enable_x64", True)
import diffpegasus as dp  # noqa: E402
from diffpegasus._registry import vehicle_spec  # noqa: E402
from diffpegasus._registry._hfb320_simulator import simulate_log, simulated_record  # noqa: E402


ROOT = pathlib.Path(__file__).resolve().parent.parent
STATES = ("V", "alpha", "theta", "q")


def show(name, model, candidates, rec):
    t0 = time.perf_counter()
    _, ranking = dp.diagnose_model(
        model, rec, candidates, process_noise=STATES, throw=False
    )
    pn = next(r for r in ranking if r["effect"] == "process_noise")
    ev = pn["turbulence_evidence"] or {}
    n = len(rec.t)
    row = dict(
        flight=name,
        LR=pn["statistic"],
        LR_per_N=pn["statistic"] / n,
        check=ev.get("statistic"),
        threshold=ev.get("threshold"),
        output=ev.get("output"),
        significant=[r["effect"] for r in ranking if r["significant"]],
        survivors=[
            (
                r["effect"],
                r.get("statistic_under_process_noise"),
                r.get("threshold_under_process_noise"),
            )
            for r in ranking
            if r.get("significant_output_error")
        ],
        seconds=time.perf_counter() - t0,
    )
    print(json.dumps(row), flush=True)


def real():
    """The real HFB-320 record through `diagnose --vehicle hfb320 --json`."""
    from typer.testing import CliRunner

    from diffpegasus._cli import app

    sys.path.insert(0, str(ROOT / "experiments"))
    from hfb320 import DEFAULT_DATA

    t0 = time.perf_counter()
    res = CliRunner().invoke(
        app, ["diagnose", str(DEFAULT_DATA), "--vehicle", "hfb320", "--json"]
    )
    report = json.loads(res.stdout.strip().splitlines()[-1])
    pn = next(r for r in report["ranking"] if r["effect"] == "process_noise")
    ev = pn["turbulence_evidence"] or {}
    print(
        json.dumps(
            dict(
                flight="hfb320 real record",
                LR=pn["statistic"],
                check=ev.get("statistic"),
                threshold=ev.get("threshold"),
                output=ev.get("output"),
                significant=report["significant"],
                message=report["message"][:300],
                seconds=time.perf_counter() - t0,
            )
        ),
        flush=True,
    )


def independent():
    """The independent generator's clean HFB-320 flight (20 Hz, seed 1: true
    elevator steps between samples) through `diagnose --vehicle hfb320 --json`."""
    import tempfile

    from typer.testing import CliRunner

    from diffpegasus._cli import app

    sys.path.insert(0, str(ROOT / "tests"))
    import independent_generator as gen

    csv = pathlib.Path(tempfile.mkdtemp()) / "hfb320_20_1_clean.csv"
    gen.write(csv, *gen.generate_hfb320(1, 20.0))
    t0 = time.perf_counter()
    res = CliRunner().invoke(
        app, ["diagnose", str(csv), "--vehicle", "hfb320", "--json"]
    )
    report = json.loads(res.stdout.strip().splitlines()[-1])
    pn = next(r for r in report["ranking"] if r["effect"] == "process_noise")
    ev = pn["turbulence_evidence"] or {}
    print(
        json.dumps(
            dict(
                flight="hfb320 independent clean 20 Hz seed 1",
                LR=pn["statistic"],
                check=ev.get("statistic"),
                threshold=ev.get("threshold"),
                output=ev.get("output"),
                significant=report["significant"],
                message=report["message"][:300],
                seconds=time.perf_counter() - t0,
            )
        ),
        flush=True,
    )


if __name__ == "__main__":
    spec = vehicle_spec("hfb320", candidates=True)
    which = sys.argv[1:] or ["clean", "gust", "cmq"]
    for w in which:
        if w == "clean":
            show(
                "hfb320 package clean seed 100",
                spec.model,
                spec.candidates,
                simulated_record(simulate_log(duration=30.0, seed=100)[0]),
            )
        if w == "gust":
            show(
                "hfb320 package gusts 0.3 seed 100",
                spec.model,
                spec.candidates,
                simulated_record(
                    simulate_log(duration=30.0, seed=100, turbulence=0.3)[0]
                ),
            )
        if w == "gust05":
            show(
                "hfb320 package gusts 0.05 seed 101",
                spec.model,
                spec.candidates,
                simulated_record(
                    simulate_log(duration=30.0, seed=101, turbulence=0.05)[0]
                ),
            )
        if w == "independent":
            independent()
        if w == "real":
            real()
        if w == "cmq":
            held = spec.model.replace(
                start={"CMq": 0.0}, fixed=(*spec.model.fixed, "CMq")
            )
            show(
                "hfb320 package CMq=0 gusts 0.1 seed 100",
                held,
                spec.candidates,
                simulated_record(
                    simulate_log(duration=30.0, seed=100, turbulence=0.1)[0]
                ),
            )
