"""Refit validation flights whose fit with the spline drag ended at a much larger
cost than before, starting from the earlier optimum (its estimates), to tell a
local minimum from a change of the model. Run:
PYTHONPATH=src python experiments/rocket_refit_from_old.py FLIGHTS_DIR NAME [NAME ...]"""

import json
import pathlib
import sys

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from rocket_validation import sim_log  # noqa: E402


def main(folder, names):
    import diffpegasus.rocket as dr

    old = json.loads(
        (ROOT / "benchmarks" / "results" / "rocket_validation_more.json").read_text()
    )
    out = {}
    for name in names:
        f = pathlib.Path(folder) / name
        rocket = dr.read_rocket(f / "rocket.toml")
        problem = dr.prepare(rocket, sim_log(f))
        start = {k: v[0] for k, v in old[name]["estimates"].items()}
        res = dr.fit_rocket(problem, start=start, throw=False)
        mach = np.array(old[name]["mach"])
        cd, sd = res.cd(mach)
        planted = np.array(old[name]["planted"])
        inside = int(np.sum(np.abs(cd - planted) <= 1.96 * sd))
        row = {
            "inside_95": inside,
            "cost": float(res.fit.cost),
            "width_pct": float(100 * np.mean(1.96 * sd / planted)),
            "wind_along": res.estimate("wind_along"),
            "converged": bool(res.fit.converged),
        }
        out[name] = row
        print(name, row, flush=True)
    (ROOT / "experiments" / "results" / "rocket_refit_from_old.json").write_text(
        json.dumps(out, indent=1)
    )


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
