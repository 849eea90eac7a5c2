"""CD(Mach) band coverage of RocketPy flights fitted to the whole ascent against
the same fit with the last seconds before apogee left out, and with the wind held
at the planted value: is the wind's estimate, and CD with it, bent by the end of
the climb, where RocketPy's rocket flies at an angle of attack the point-mass model
has not (its fins' lift holds the path up, 0.17-0.23 m/s^2, in the last 3 s)?

`python experiments/rocket_coverage_cut.py SECONDS FOLDER [FOLDER ...]`: each FOLDER
one flight as `scripts/make_rocket_fixtures.py` writes it; SECONDS cut before the
log's last sample (0: no cut fit; only the whole ascent and the wind held at the
planted along-rail value, its `[truth]` east and north components projected on
the rail's heading; the cross component is flown as zero). Prints, per flight and fit, the planted CD inside the 95% band
(of 20 Mach points from 0.15 to 0.95 of the top, as benchmarks/rocket_validation.py
counts them), the z of the points and the wind along the rail; writes
experiments/results/rocket_coverage_cut.json.
"""

import json
import pathlib
import sys
import time
import tomllib

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))


def main():
    from rocket_validation import sim_log

    import diffpegasus.rocket as dr

    cut = float(sys.argv[1])
    path = ROOT / "experiments" / "results" / "rocket_coverage_cut.json"
    out = json.loads(path.read_text()) if path.exists() else {}
    for folder in map(pathlib.Path, sys.argv[2:]):
        rocket = dr.read_rocket(folder / "rocket.toml")
        log = sim_log(folder)
        problem = dr.prepare(rocket, log)
        flat = {n: 0.5 for n in problem.flight.knots.names}
        end = float(problem.record.t[-1])
        toml = tomllib.loads((folder / "rocket.toml").read_text())
        head = np.radians(toml["launch"]["heading_deg"])
        truth = toml["truth"]
        along = truth.get("wind_east_m_s", 0.0) * np.sin(head) + truth.get(
            "wind_north_m_s", 0.0
        ) * np.cos(head)
        fits = {
            f"wind held at the planted {along:+.1f}": dict(
                start=flat | {"wind_along": float(along)},
                free=("baro_lag", "static_error"),
            ),
            "whole ascent": dict(start=flat),
        }
        if cut > 0:
            fits[f"last {cut:g} s left out"] = dict(start=flat, until=end - cut)
        mach_true, cd_true = rocket.team_drag_off
        rows = out.setdefault(folder.parent.name + "/" + folder.name, {})
        for label, options in fits.items():
            t0 = time.perf_counter()
            result = dr.fit_rocket(problem, throw=False, **options)
            mach = np.linspace(0.15, 0.95 * float(np.max(result.mach)), 20)
            cd, sd = result.cd(mach)
            z = (cd - np.interp(mach, mach_true, cd_true)) / sd
            names = result.fit.model.parameters
            wind = (
                result.estimate("wind_along")
                if result.fit.model.free[names.index("wind_along")]
                else (0.0, 0.0)
            )
            rows[label] = {
                "inside_95": int(np.sum(np.abs(z) <= 1.96)),
                "z": z.tolist(),
                "wind_along": wind,
                "seconds": time.perf_counter() - t0,
            }
            print(
                f"{folder.name} {label}: inside {rows[label]['inside_95']} of 20, "
                f"z {z.min():+.1f} to {z.max():+.1f}, wind {wind[0]:+.2f} +/- "
                f"{wind[1]:.2f} m/s",
                flush=True,
            )
            path.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
