"""Diagnosis on real flight data: the HFB-320 vehicle with its pitch-damping term
held at zero, fitted to the real record, then every library effect that composes
with the vehicle scored (SPEC section 6).

Nothing is re-implemented here: the vehicle (`dp.vehicle_spec("hfb320")`) is the one
flight model with the book's aerodynamics, and the candidates are the library's own
effects (pitch and alpha-dot damping, the alpha^2 terms, an actuator delay, sensor
biases), composed through their hooks and held at zero; `dp.diagnose_model` fits
and score-tests them. The same as `diffpegasus diagnose FILE --vehicle hfb320 --fix
CMq=0`.

Run: `python experiments/hfb320_diagnosis.py [--data FILE]`; the last stdout line is
one JSON object `{"ranking": [...], "significant": [...]}`.
"""

import argparse
import json
import pathlib

from _shared import shared_data

import diffpegasus as dp


DEFAULT_DATA = shared_data("hfb320/hfb320_1_10.asc")


def diagnose_missing_pitch_damping(path=DEFAULT_DATA) -> dict:
    spec = dp.vehicle_spec("hfb320", candidates=True)
    model = spec.model.replace(start={"CMq": 0.0}, fixed=(*spec.model.fixed, "CMq"))
    record = dp.load_record(model, path, spec.columns, x0=spec.x0)
    result, ranking = dp.diagnose_model(model, record, spec.candidates)
    return {
        "cost": result.cost,
        "ranking": ranking,
        "significant": [r["parameter"] for r in ranking if r["significant"]],
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", type=pathlib.Path, default=DEFAULT_DATA)
    args = parser.parse_args()
    result = diagnose_missing_pitch_damping(args.data)
    for r in result["ranking"]:
        print(
            f"{r['parameter']:28s} {100 * r['cost_reduction']:6.1f}%  "
            f"p = {r['p_value']:.2g}  estimate {r['estimate']:.4g} +/- {r['stderr']:.2g}"
        )
    print(json.dumps(result))


if __name__ == "__main__":
    main()
