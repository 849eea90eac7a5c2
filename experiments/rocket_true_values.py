"""The library's rocket model flown at the clean fixture's true values (drag at the
flown curve's 0.01-Mach points, catalogue thrust, RocketPy's motor start) against
RocketPy's own flight: the geometric height and the log's barometric altitude.
Run: PYTHONPATH=src python experiments/rocket_true_values.py [FLIGHT]"""

import pathlib
import sys

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from rocket_validation import sim_log  # noqa: E402


def main(name="clean"):
    import diffpegasus.rocket as dr

    folder = ROOT / "tests" / "data" / "rocket_sim" / name
    rocket = dr.read_rocket(folder / "rocket.toml")
    m, cd = dr.read_drag_curve(folder / "drag.csv")
    sel = m <= 1.0
    knots = dr.DragKnots(tuple(m[sel]))
    problem = dr.prepare(rocket, sim_log(folder), knots=knots)
    start = dict(zip(knots.names, cd[sel], strict=True))
    start.update(
        thrust_scale=1.0,
        motor_time=0.0,
        temperature=287.177 if name == "clean" else None,
    )
    start = {k: v for k, v in start.items() if v is not None}
    res = dr.simulate_flight(problem, start)
    log = np.loadtxt(folder / "log.csv", delimiter=",", skiprows=1)
    print(
        f"{name}: model apogee (baro) {res.apogee:.2f} at {res.apogee_time:.2f}; "
        f"geometric top {res.states[:, 2].max():.2f}; log max {log[:, 1].max():.2f}; "
        f"RocketPy geometric {rocket_truth(folder):.2f}"
    )
    for s in (0.5, 1.0, 3.8, 8, 12, 16, 20, 23):
        i = np.argmin(abs(res.t - s))
        j = np.argmin(abs(log[:, 0] - s))
        print(
            f"  t {s:5.1f}: model z {res.states[i, 2]:8.2f} v {np.linalg.norm(res.states[i, 3:]):7.2f}"
            f"  baro {res.baro[i]:8.2f} log {log[j, 1]:8.2f}"
        )
    return res


def rocket_truth(folder):
    import tomllib

    return tomllib.loads((folder / "rocket.toml").read_text())["truth"][
        "apogee_geometric_agl_m"
    ]


if __name__ == "__main__":
    main(*(sys.argv[1:2] or ["clean"]))
