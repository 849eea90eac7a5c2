"""Frequency-domain output error and equation error beside time-domain output error,
on the same model files and records: the HFB-320 flight record (the linear
short-period model `examples/hfb320_linear.py`), the unstable aircraft
(`examples/unstable_aircraft.py`) and a simulated ATTAS-like lateral manoeuvre (the
linear lateral model without biases; simulated here by the matrix exponential).

For every estimated parameter: the three estimates, their corrected standard
errors, and `z = (frequency - time) / stderr_time`. Writes the Bode and
residual-spectrum figures of each frequency-domain output-error fit.

Run: `python experiments/frequency_domain.py [--out DIR]`; the last stdout line is
the JSON summary (also DIR/summary.json).
"""

import argparse
import json
import pathlib
import time

import numpy as np
from _shared import attas_like, shared_data

import diffpegasus as dp


ROOT = pathlib.Path(__file__).resolve().parents[1]


def compare(model, record, band, out, units, shooting=None):
    start = time.perf_counter()
    td = dp.fit(model, record, shooting=shooting)
    t_td = time.perf_counter() - start
    start = time.perf_counter()
    fd = dp.estimate(model, record, dp.FrequencyOutputError(band=band))
    t_fd = time.perf_counter() - start
    ee = None
    if all(s in model.outputs for s in model.states):
        ee = dp.estimate(model, record, dp.FrequencyEquationError(band=band))
    dp.plot_bode(fd, out, units=units)
    rows = {}
    for i, name in enumerate(model.parameters):
        if not fd.free[i]:
            continue
        rows[name] = {
            "time_oe": float(td.params[i]),
            "time_oe_stderr": float(td.stderr_corrected[i]),
            "freq_oe": float(fd.params[i]),
            "freq_oe_stderr": float(fd.stderr_corrected[i]),
            "freq_oe_crb": float(fd.stderr[i]),
            "z": float((fd.params[i] - td.params[i]) / td.stderr_corrected[i]),
        }
        if ee is not None:
            rows[name]["freq_ee"] = float(ee.params[i])
            rows[name]["freq_ee_stderr"] = float(ee.stderr_corrected[i])
    return {
        "record": record.name,
        "band_hz": [float(fd.frequencies[0][0]), float(fd.frequencies[0][-1])],
        "frequencies": len(fd.frequencies[0]),
        "seconds_time_oe": t_td,
        "seconds_freq_oe": t_fd,
        "max_abs_z": max(abs(r["z"]) for r in rows.values()),
        "parameters": rows,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/frequency_domain")
    )
    args = parser.parse_args()
    summary = {}
    path = shared_data("hfb320/hfb320_1_10.asc")
    if path.exists():
        spec = dp.load_model_file(ROOT / "examples" / "hfb320_linear.py")
        rec = dp.load_record(spec.model, path, spec.columns)
        summary["hfb320"] = compare(
            spec.model, rec, (0.0, 1.5), args.out / "hfb320",
            {"alpha": "rad", "q": "rad/s", "qdot": "rad/s^2", "az": "m/s^2"},
        )  # fmt: skip
    path = shared_data("unstable_aircraft/unStabAC_sim.asc")
    if path.exists():
        spec = dp.load_model_file(ROOT / "examples" / "unstable_aircraft.py")
        rec = dp.load_record(spec.model, path, spec.columns, x0=spec.x0)
        summary["unstable_aircraft"] = compare(
            spec.model, rec, (0.0, 2.0), args.out / "unstable_aircraft",
            {"az": "m/s^2", "w": "m/s", "q": "rad/s"}, shooting=spec.shooting,
        )  # fmt: skip
    model = dp.lateral.lateral_model(state_biases=False, output_biases=False)
    summary["attas_like"] = compare(
        model, dp.Record(*attas_like(), x0=np.zeros(2), name="ATTAS-like (simulated)"), (0.0, 3.0), args.out / "attas_like",
        {"pdot": "rad/s^2", "rdot": "rad/s^2", "ay": "m/s^2", "p": "rad/s", "r": "rad/s"},
    )  # fmt: skip
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    for k, v in summary.items():
        print(f"{k}: max |z| = {v['max_abs_z']:.2f} over {len(v['parameters'])}")
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
