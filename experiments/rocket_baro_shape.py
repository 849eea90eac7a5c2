"""Can a smooth function of height take RocketPy's atmosphere-table error and leave a
barometer lag? Offline, without a fit: per flight flown twice with the same seed
(`make_rocket_fixtures.py --validation DIR` and `--validation DIR --smooth`), the
difference of the two barometric altitudes is the table's error alone (the noise
is the same draw); the lag's signature is the climb rate (a Chebyshev fit of the
exact-atmosphere flight's altitude, differentiated), the static-pressure error's
the dynamic pressure over density and gravity. Each is projected on a
piecewise-linear function of height (zero at the pad, knots every `k` burnout
heights, the height where the climb rate peaks) plus the reading's scale and
curvature (what the pad temperature and lapse rate change); printed: the share of
each signature's RMS that is left.

`python experiments/rocket_baro_shape.py TABLE_DIR SMOOTH_DIR FLIGHT [FLIGHT ...]`;
writes experiments/results/rocket_baro_shape.json.
"""

import json
import pathlib
import sys

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
SPACINGS = (0.5, 1.0, 1.5, 2.0)


def read(path):
    return np.genfromtxt(path, delimiter=",", names=True)


def left(y, a):
    """Share of `y`'s RMS that least squares on the columns of `a` leaves."""
    c, *_ = np.linalg.lstsq(a, y, rcond=None)
    return float(np.sqrt(np.mean((y - a @ c) ** 2) / np.mean(y**2)))


def main():
    table, smooth, *flights = sys.argv[1:]
    out = {}
    for name in flights:
        a = read(pathlib.Path(table) / name / "log.csv")
        b = read(pathlib.Path(smooth) / name / "log.csv")
        t = b["time_s"]
        cheb = np.polynomial.Chebyshev.fit(t, b["altitude_m"], 25)
        h, v = cheb(t), cheb.deriv()(t)
        error = a["altitude_m"] - b["altitude_m"]
        burnout = float(h[np.argmax(v)])
        static = 0.5 * v**2 / 9.81
        row = {
            "burnout_height_m": burnout,
            "table_error_rms_m": float(np.sqrt(np.mean(error**2))),
            "table_error_range_m": [float(error.min()), float(error.max())],
        }
        for k in SPACINGS:
            n = int(np.ceil(h.max() / (k * burnout)))
            knots = np.arange(n + 1) * k * burnout
            hats = [np.interp(h, knots, np.eye(n + 1)[j]) for j in range(1, n + 1)]
            basis = np.column_stack(hats + [h, h**2])
            row[f"x{k:g}"] = {
                "knots": n,
                "table": left(error, basis),
                "lag": left(v, basis),
                "static": left(static, basis),
            }
            r = row[f"x{k:g}"]
            print(
                f"{name}: knots every {k:g} burnout heights ({k * burnout:.0f} m, "
                f"{n}): left of the table's error {r['table']:.2f}, of a lag "
                f"{r['lag']:.2f}, of a static-pressure error {r['static']:.2f}"
            )
        out[name] = row
    path = ROOT / "experiments" / "results" / "rocket_baro_shape.json"
    path.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
