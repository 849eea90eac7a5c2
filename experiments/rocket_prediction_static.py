"""The apogee predicted from the log up to burnout + 2 s with the barometer's
static-pressure error estimated from the same seconds (the pipeline's
prediction, `predict`), on the real flights. Run:
PYTHONPATH=src python experiments/rocket_prediction_static.py FOLDER [FOLDER ...]"""

import json
import pathlib
import sys

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]


def main(folders):
    from diffpegasus._log._rocketlogs import read_rocket_log
    from diffpegasus._rocket._data import baro_channel
    from diffpegasus._rocket._pipeline import predict, PREDICTION_HORIZON
    from diffpegasus.rocket import prepare, read_rocket

    out = {}
    path = (
        ROOT
        / "experiments"
        / "results"
        / f"rocket_prediction_static_{pathlib.Path(folders[0]).name}.json"
    )
    for folder in map(pathlib.Path, folders):
        rocket = read_rocket(folder / "rocket.toml")
        log = read_rocket_log(folder / "rocket.toml")
        problem = prepare(rocket, log)
        summary = json.loads(
            (ROOT / "docs" / "rockets" / folder.name / "summary.json").read_text()
        )
        # the burnout the pipeline used: the log's event, else the fitted motor's end
        if "burnout" in log.events:
            burnout = float(log.events["burnout"].t)
        else:
            burnout = summary["estimates"]["motor_time"][0] + rocket.motor.burn_time
        pred = predict(problem, burnout + PREDICTION_HORIZON)
        t, h = baro_channel(log)
        logged = float(np.max(h[t > 0]))
        row = {
            "logged": logged,
            "predicted_static_free": pred.apogee,
            "error_pct": 100 * (pred.apogee - logged) / logged,
            "default_pct": summary["predicted_error_pct"],
            "static_error": pred.estimate("static_error"),
            "converged": bool(pred.fit.converged),
        }
        out[folder.name] = row
        print(folder.name, row, flush=True)
        path.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main(sys.argv[1:])
