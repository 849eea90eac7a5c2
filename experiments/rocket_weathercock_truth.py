"""The library's rocket model flown at a simulated flight's planted values (drag at
the flown curve's 0.01-Mach points, planted thrust scale, wind, barometer lag and
static error) against RocketPy's log, with the attitude (weathercocking through
the rocket file's airframe) and without it (pointing along the air-relative
velocity): the barometric-altitude residual over the ascent and the apogee.
Run: PYTHONPATH=src python experiments/rocket_weathercock_truth.py FOLDER..."""

import pathlib
import sys
import tomllib

import equinox as eqx
import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from rocket_validation import sim_log  # noqa: E402


def main(folder):
    import diffpegasus.rocket as dr

    folder = pathlib.Path(folder)
    truth = tomllib.loads((folder / "rocket.toml").read_text())["truth"]
    rocket = dr.read_rocket(folder / "rocket.toml", attitude=True)
    m, cd = dr.read_drag_curve(folder / "drag.csv")
    sel = m <= 1.0
    knots = dr.DragKnots(tuple(m[sel]))
    log = np.loadtxt(folder / "log.csv", delimiter=",", skiprows=1)
    out = {}
    for label, r in (
        ("attitude", rocket),
        (
            "point",
            eqx.tree_at(
                lambda r: r.airframe, rocket, None, is_leaf=lambda x: x is None
            ),
        ),
    ):
        problem = dr.prepare(r, sim_log(folder), knots=knots)
        start = dict(zip(knots.names, cd[sel], strict=True))
        start.update(
            thrust_scale=truth["thrust_scale"],
            motor_time=0.0,
            wind_east=truth["wind_east_m_s"],
            wind_north=truth["wind_north_m_s"],
            baro_lag=truth["baro_lag_s"],
            static_error=truth["static_error"],
        )
        res = dr.simulate_flight(problem, start)
        model_baro = np.interp(log[:, 0], res.t, res.baro)
        e = log[:, 1] - model_baro
        out[label] = e
        print(
            f"{folder.name} {label:8s}: apogee model {res.states[:, 2].max():8.2f} "
            f"RocketPy {truth['apogee_geometric_agl_m']:8.2f}; baro residual "
            f"RMS {np.sqrt(np.mean(e**2)):6.2f} m, at the end {np.mean(e[-50:]):7.2f} m"
        )
    return out


if __name__ == "__main__":
    for f in sys.argv[1:]:
        main(f)
