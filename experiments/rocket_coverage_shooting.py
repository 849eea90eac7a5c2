"""CD(Mach) band coverage of RocketPy flights fitted with single shooting (one
segment from the pad) against the fit's default multiple shooting (nodes every 2 s):
does the layout change the optimum the flat start ends in, and the coverage?

`python experiments/rocket_coverage_shooting.py FOLDER [FOLDER ...]`: each FOLDER one
flight as `scripts/make_rocket_fixtures.py` writes it. Prints, per flight and
layout, det(R), whether it converged, the planted CD inside the 95% band (of 20
Mach points from 0.15 to 0.95 of the top, as benchmarks/rocket_validation.py
counts them) and the wind along the rail.
"""

import pathlib
import sys
import time

import numpy as np


sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))


def main():
    from rocket_validation import sim_log

    import diffpegasus.rocket as dr

    for folder in map(pathlib.Path, sys.argv[1:]):
        rocket = dr.read_rocket(folder / "rocket.toml")
        problem = dr.prepare(rocket, sim_log(folder))
        flat = {n: 0.5 for n in problem.flight.knots.names}
        single = float(problem.record.t[-1] - problem.record.t[0]) + 1.0
        for label, interval in (("single", single),):
            t0 = time.perf_counter()
            result = dr.fit_rocket(
                problem, start=flat, shooting_interval=interval, throw=False
            )
            seconds = time.perf_counter() - t0
            mach_true, cd_true = rocket.team_drag_off
            mach = np.linspace(0.15, 0.95 * float(np.max(result.mach)), 20)
            cd, sd = result.cd(mach)
            inside = int(
                np.sum(np.abs(cd - np.interp(mach, mach_true, cd_true)) <= 1.96 * sd)
            )
            wind = result.estimate("wind_along")
            print(
                f"{folder.name} {label}: det(R) {result.fit.cost:.4g} converged "
                f"{result.fit.converged} inside {inside} of 20, wind along "
                f"{wind[0]:+.1f} +/- {wind[1]:.1f}, mean band half-width "
                f"{np.mean(1.96 * sd / cd) * 100:.1f}% ({seconds:.0f} s)",
                flush=True,
            )


if __name__ == "__main__":
    main()
