"""A descent fit whose main opens before its stated event: the bound on the opening
time. RocketPy's flight whose main is full 2.5 s after its trigger at 300 m
(tests/data/rocket_descent/descent-open-c-s9-20hz), its log's `main` event stated
`LATE` s after the trigger, so that the canopy is full `LATE - 2.5` s before the
event the fit is told. The main's opening time cannot go below 0 (a canopy full
before its event fired); the fit (the main's opening started from the log's
reading, `spread=False`) stops against that bound and is reported `nonfinite`, one
line naming it. Prints the result, its line, the estimates of the main's opening
and drag area and the drogue's, and CPU-s.

`python experiments/rocket_open_bound.py [LATE] [--single]` (default 3.5 s: full
1 s before the event stated; `--single`: single shooting alone, where by default the
fit's multiple-shooting tries come first).
"""

import dataclasses
import pathlib
import sys
import time


ROOT = pathlib.Path(__file__).resolve().parents[1]


def main():
    import diffpegasus as dp
    import diffpegasus.rocket as dr

    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    late = float(args[0]) if args else 3.5
    toml = ROOT / "tests/data/rocket_descent/descent-open-c-s9-20hz/rocket.toml"
    log = dp.read_rocket_log(toml)
    main_event = log.events["main"]
    log.events["main"] = dataclasses.replace(main_event, t=main_event.t + late)
    t0 = time.process_time()
    problem = dr.prepare(dr.read_rocket(toml), log, descent=True)
    print(
        f"main event stated at {log.events['main'].t:.2f} s (RocketPy's trigger "
        f"{main_event.t:.2f} s, its canopy full 2.5 s later); the main's opening "
        f"started at {problem.start['open_main']:.3f} s"
    )
    # --single: single shooting alone (one segment as long as the record)
    every = 1e4 if "--single" in sys.argv else 2.0
    r = dr.fit_rocket(problem, throw=False, spread=False, shooting_interval=every)
    print(f"{time.process_time() - t0:.0f} CPU-s")
    print(f"result {r.fit.result}, converged {r.fit.converged}")
    print(f"reason {r.fit.reason!r}")
    for label, (cost, flown, converged) in r.tries.items():
        print(
            f"try {label}: det(R) {cost:.4g}, flown {flown:.8g}, converged {converged}"
        )
    for name in ("open_main", "cds_main", "cds_drogue", "baro_lag"):
        value, stderr = r.estimate(name)
        print(f"{name} {value:.4g} +/- {stderr:.2g}")


if __name__ == "__main__":
    main()
