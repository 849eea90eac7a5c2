"""The apogee predicted from the log up to burnout + 2 s (the pipeline's `predict`)
with its 95% band ([`apogee_band`][]: the prediction fit's covariance and the held
temperature and lapse rate carried to the apogee by the model's JAX gradient), on
the real flights: is the logged apogee inside? Burnout as the pipeline takes it
(the log's event, else the motor end of the full fit in the page's summary.json);
on a simulated flight (a folder with log.csv, scripts/make_rocket_fixtures.py) the
motor's end from the accelerometer's start value (no full fit run).
Writes experiments/results/rocket_apogee_band_<parent>_<first folder>.json (committed as rocket_apogee_band_real.json and _simulated.json) after every
flight. Run:
PYTHONPATH=src python experiments/rocket_apogee_band.py FOLDER [FOLDER ...]"""

import json
import pathlib
import sys
import time

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]


def main(folders):
    from diffpegasus._log._rocketlogs import read_rocket_log
    from diffpegasus._rocket._data import baro_channel
    from diffpegasus._rocket._pipeline import PREDICTION_HORIZON
    from diffpegasus.rocket import apogee_band, predict, prepare, read_rocket

    out = {}
    path = (
        ROOT
        / "experiments"
        / "results"
        / f"rocket_apogee_band_{pathlib.Path(folders[0]).parent.name}_"
        f"{pathlib.Path(folders[0]).name}.json"
    )
    for folder in map(pathlib.Path, folders):
        rocket = read_rocket(folder / "rocket.toml")
        simulated = (folder / "log.csv").exists()
        if simulated:  # a RocketPy flight (scripts/make_rocket_fixtures.py)
            log = read_rocket_log(folder / "log.csv")
        else:
            log = read_rocket_log(folder / "rocket.toml")
        problem = prepare(rocket, log)
        if "burnout" in log.events:
            burnout = float(log.events["burnout"].t)
        elif simulated:  # no full fit run: the motor's end from the accelerometer
            burnout = problem.start["motor_time"] + rocket.motor.burn_time
        else:
            summary = json.loads(
                (ROOT / "docs" / "rockets" / folder.name / "summary.json").read_text()
            )
            burnout = summary["estimates"]["motor_time"][0] + rocket.motor.burn_time
        t0 = time.perf_counter()
        pred = predict(problem, burnout + PREDICTION_HORIZON)
        t1 = time.perf_counter()
        band = apogee_band(pred)
        t2 = time.perf_counter()
        t, h = baro_channel(log)
        logged = float(np.max(h[t > 0]))
        row = {
            "logged": logged,
            "predicted": pred.apogee,
            "error_pct": 100 * (pred.apogee - logged) / logged,
            "stderr_m": band.stderr,
            "stderr_fit_m": band.stderr_fit,
            "half_width_pct": 100 * band.half_width / pred.apogee,
            "held": band.held,
            "held_gradient": band.held_gradient,
            "gradient": band.gradient,
            "inside_95": bool(abs(pred.apogee - logged) <= band.half_width),
            "z": (logged - pred.apogee) / band.stderr,
            "estimates": {
                k: pred.estimate(k)
                for k, f in zip(pred.fit.model.parameters, pred.fit.free, strict=True)
                if f
            },
            "converged": bool(pred.fit.converged),
            "predict_seconds": t1 - t0,
            "band_seconds": t2 - t1,
        }
        # simulated flights of one name come from several folders
        key = f"{folder.parent.name}/{folder.name}" if simulated else folder.name
        out[key] = row
        print(key, row, flush=True)
        path.parent.mkdir(exist_ok=True)
        path.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main(sys.argv[1:])
