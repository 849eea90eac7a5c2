"""The barometer's lag to second order: does adding a first-order filter's
`tau^2` term to the model's delay change what `diagnose` names and what `rocket fit`
returns?

The model reads the barometer `s (h - tau dh/dt)` (a delay to first order). A
first-order filter on the pressure reads `s (h - tau dh/dt + tau^2 d2h/dt2 - ...)`,
a pure delay `s (h - tau dh/dt + tau^2/2 d2h/dt2 - ...)`. With `--term` the model
adds `+ s tau^2 d2h/dt2` (the model's vertical acceleration; a switch in
`diffpegasus._vehicle._rocket._model`, not in the interface). Left out, below
0.1 m on these flights: the height scale's own change with height (`ds/dh dh/dt^2`,
about 2e-5 /m times 9e4 m^2/s^2 times tau^2 = 0.01 s^2: 0.02 m) and the pressure
-> altitude curvature of filtering pressure rather than height (`tau^2/2 (dh/dt)^2 /
H`, H the scale height: 0.05 m at 300 m/s).

One case per process (the switch is read when the model is traced):

    python experiments/rocket_lag_order.py diagnose CASE [--term]
        CASE `filter`: tests/test_rocket_baro.py's known-failing flight (the model's
        own 50 Hz flight of tests/data/rocket_sim/clean, its barometer's pressure
        through scripts/make_rocket_fixtures.py's 0.1 s first-order filter, 0.5 m
        and 0.3 m/s^2 noise, seed 12); `delay`: the same flight, its barometer read
        0.1 s late (interpolated in time; the first 0.1 s the pad's reading);
        `clean`: tests/data/rocket_sim/clean as committed.
    python experiments/rocket_lag_order.py fit FLIGHT_FOLDER [--term]
        `diffpegasus rocket fit FLIGHT_FOLDER/rocket.toml --out ...` as the flight's
        docs page runs it.
    python experiments/rocket_lag_order.py warm FLIGHT_FOLDER [--term]
        `fit_rocket(problem, spread=False)`; without the term it writes its
        parameters to experiments/results/rocket_lag_order_start_NAME.json, with it
        it starts there (is a higher det(R) with the term the model or the search?).
    python experiments/rocket_lag_order.py --table

Results go to experiments/results/rocket_lag_order.json (keyed case/flight and
with/without the term). The command's program cache is kept apart per model
(`lag_order_term`, `lag_order_delay` beside the default cache folder): its kept
programs are keyed by the package's source, which the switch does not change.
"""

import json
import os
import pathlib
import shutil
import sys
import tempfile
import time
import tomllib

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
RESULTS = ROOT / "experiments" / "results" / "rocket_lag_order.json"
TAU = 0.1


def _write_case(case, folder):
    """The flight of `case` in `folder` (a copy of the committed clean rocket)."""
    sys.path.insert(0, str(ROOT / "scripts"))
    from make_rocket_fixtures import lagged_baro, write_log

    import diffpegasus.rocket as dr
    from diffpegasus import read_rocket_log

    shutil.copytree(DATA / "rocket_sim" / "clean", folder)
    if case == "clean":
        return
    toml = folder / "rocket.toml"
    problem = dr.prepare(dr.read_rocket(toml), read_rocket_log(toml))
    flown = dr.simulate_flight(problem, start={"thrust_scale": 1.0, "motor_time": 0.0})
    n = len(problem.record.t)
    t = np.asarray(problem.record.t, dtype=float)
    if case == "filter":
        pad = tomllib.loads(toml.read_text())["launch"]["elevation_m"]
        baro = lagged_baro(flown.baro[:n], pad, float(problem.record.dt), TAU)
    elif case == "delay":
        baro = np.interp(t - TAU, t, np.asarray(flown.baro[:n], dtype=float))
    else:
        raise SystemExit(f"unknown case {case!r}")
    rng = np.random.default_rng(12)  # as the validation test
    write_log(
        folder,
        t,
        baro + rng.normal(0.0, 0.5, n),
        flown.accel[:n] + rng.normal(0.0, 0.3, n),
    )


def diagnose(case):
    import diffpegasus.rocket as dr
    from diffpegasus import read_rocket_log

    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp) / "flight"
        _write_case(case, folder)
        toml = folder / "rocket.toml"
        problem = dr.prepare(dr.read_rocket(toml), read_rocket_log(toml))
        start = time.process_time()
        named, rows, final = dr.diagnose(problem)
        seconds = time.process_time() - start
    fit = final.fit
    names = list(fit.model.parameters)
    lag = None
    if "baro_lag" in names:
        i = names.index("baro_lag")
        if fit.free[i]:
            lag = [float(fit.params[i]), float(fit.stderr[i])]
    keep = ("barometer lag", "static-pressure error")
    return {
        "named": list(named),
        "rows": [
            {
                "round": int(r["round"]),
                "candidate": r["candidate"],
                "statistic": float(r["statistic"]),
                "threshold": float(r["threshold"]),
                "estimates": {k: float(v) for k, v in r["estimates"].items()},
            }
            for r in rows
            if r["candidate"] in keep or r["significant"]
        ],
        "final_lag": lag,
        "cpu_s": seconds,
    }


def fit(folder):
    from diffpegasus._cli import main

    folder = pathlib.Path(folder)
    with tempfile.TemporaryDirectory() as tmp:
        sys.argv = ["diffpegasus", "rocket", "fit", str(folder / "rocket.toml")]
        sys.argv += ["--out", tmp]
        try:
            main()
        except SystemExit as e:
            if e.code:
                raise
        summary = json.loads((pathlib.Path(tmp) / "summary.json").read_text())
    det = min(v["det_r_flown"] for v in summary["tries"].values())
    return {
        "baro_lag": summary["estimates"].get("baro_lag"),
        "static_error": summary["estimates"].get("static_error"),
        "det_r": det,
        "tries": summary["tries"],
        "apogee_reconstructed_m": summary["apogee_reconstructed_m"],
        "apogee_predicted_m": summary["apogee_predicted_m"],
        "altitude_rms_m": summary["altitude_rms_m"],
        "converged": summary["converged"],
        "cd_table": [[k["mach"], k["cd"], k["stderr"]] for k in summary["cd_table"]],
        "fit_seconds": summary["fit_seconds"],
    }


def warm(folder, term):
    """`fit_rocket` (the noise's band alone) on FLIGHT_FOLDER; with the term, from
    the delay model's optimum (every parameter; written by the run without it to
    experiments/results/rocket_lag_order_start_NAME.json): whether the term's fit
    ending above the delay's det(R) is the term's model or the search's minimum."""
    import diffpegasus.rocket as dr
    from diffpegasus import read_rocket_log

    folder = pathlib.Path(folder)
    toml = folder / "rocket.toml"
    problem = dr.prepare(dr.read_rocket(toml), read_rocket_log(toml))
    path = RESULTS.parent / f"rocket_lag_order_start_{folder.name}.json"
    start = json.loads(path.read_text()) if term else None
    result = dr.fit_rocket(problem, start=start, spread=False, throw=False)
    fit = result.fit
    values = {
        k: float(v) for k, v in zip(fit.model.parameters, fit.params, strict=True)
    }
    if not term:
        path.write_text(json.dumps(values, indent=1, sort_keys=True) + "\n")
    det = min(v[1] for v in result.tries.values())
    return {
        "det_r_flown": det,
        "tries": {k: [float(x) for x in v] for k, v in result.tries.items()},
        "baro_lag": values.get("baro_lag"),
        "apogee": float(result.apogee),
    }


def table(results):
    def fmt_named(r):
        return " + ".join(r["named"]) or "nothing"

    def first(r, cand):
        row = next(
            (x for x in r["rows"] if x["candidate"] == cand and x["round"] == 1), None
        )
        if row is None:
            return "-"
        est = next(iter(row["estimates"].values()))
        return f"{row['statistic']:.1f} / {row['threshold']:.1f} ({est:.4g})"

    print(
        "| flight | model | named | lag, 1st round | static error, 1st round "
        "| final lag (s) |"
    )
    for case in ("filter", "delay", "clean"):
        for term in ("delay", "term"):
            r = results.get(f"diagnose/{case}/{term}")
            if r is None:
                continue
            lag = r["final_lag"]
            lag = "-" if lag is None else f"{lag[0]:.4f} ± {lag[1]:.4f}"
            print(
                f"| {case} | {term} | {fmt_named(r)} | "
                f"{first(r, 'barometer lag')} | {first(r, 'static-pressure error')} "
                f"| {lag} |"
            )
    print()
    print(
        "| flight | lag (s) delay / term | det(R) delay / term | apogee recon. "
        "(m) delay / term | apogee pred. (m) | static error | max dCD, M >= 0.3 (in se) |"
    )
    flights = sorted({k.split("/")[1] for k in results if k.startswith("fit/")})
    for f in flights:
        a, b = results.get(f"fit/{f}/delay"), results.get(f"fit/{f}/term")
        if a is None or b is None:
            continue

        def pm(v):
            return "-" if v is None else f"{v[0]:.4f} ± {v[1]:.4f}"

        dcd = [
            (abs(x[1] - y[1]), abs(x[1] - y[1]) / x[2])
            for x, y in zip(a["cd_table"], b["cd_table"], strict=True)
            if x[0] >= 0.3
        ]
        worst = max(dcd) if dcd else (float("nan"), float("nan"))
        print(
            f"| {f} | {pm(a['baro_lag'])} / {pm(b['baro_lag'])} | "
            f"{a['det_r']:.6g} / {b['det_r']:.6g} | "
            f"{a['apogee_reconstructed_m']:.1f} / {b['apogee_reconstructed_m']:.1f} | "
            f"{a['apogee_predicted_m']:.1f} / {b['apogee_predicted_m']:.1f} | "
            f"{pm(a['static_error'])} / {pm(b['static_error'])} | "
            f"{worst[0]:.4f} ({worst[1]:.2f}) |"
        )

    print()
    print(
        "| flight | fit_rocket det(R), lag (s): delay / term from the delay's optimum |"
    )
    for f in sorted({k.split("/")[1] for k in results if k.startswith("warm/")}):
        a, b = results.get(f"warm/{f}/delay"), results.get(f"warm/{f}/term")
        if a is None or b is None:
            continue
        print(
            f"| {f} | {a['det_r_flown']:.6g}, {a['baro_lag']:.4f} / "
            f"{b['det_r_flown']:.6g}, {b['baro_lag']:.4f} |"
        )


def main():
    args = sys.argv[1:]
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    if args == ["--table"]:
        table(results)
        return
    term = "--term" in args
    args = [a for a in args if a != "--term"]
    # the command's kept programs are keyed by the package's source, not by the
    # switch: each model its own cache folder, else one reads the other's program
    from diffpegasus._cache import default_cache_dir

    folder = default_cache_dir().parent / f"lag_order_{'term' if term else 'delay'}"
    os.environ["JAX_COMPILATION_CACHE_DIR"] = str(folder)
    if term:
        second_order_lag()
    kind, what = args
    if kind == "diagnose":
        key, out = f"diagnose/{what}", diagnose(what)
    elif kind == "warm":
        key, out = f"warm/{pathlib.Path(what).name}", warm(what, term)
    elif kind == "fit":
        key, out = f"fit/{pathlib.Path(what).name}", fit(what)
    else:
        raise SystemExit(__doc__)
    key += "/term" if term else "/delay"
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    results[key] = out
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(results, indent=1, sort_keys=True) + "\n")
    print(key, json.dumps(out)[:2000])


def second_order_lag():
    """Add the first-order filter's `tau^2` term to the model's barometer, `+ s
    lag^2 d2h/dt2` (`s` the reading's change per metre, the vertical acceleration),
    before any model is built: the model's `observe` (and the fit's copy, for the
    reconstructed outputs) wrapped. The height scale's change with height and the
    pressure-to-height curvature of filtering pressure, of the same order, are left
    out (below 0.1 m at 0.1 s and 300 m/s)."""
    from diffpegasus._rocket import _identify
    from diffpegasus._vehicle._rocket import _model

    plain = _model.observe

    def observe(flight, t, x, u, p):
        y = plain(flight, t, x, u, p)
        accel, _, (*_, scale, _) = flight.forces(t, x, u, p)
        return y.at[0].add(scale * p["baro_lag"] ** 2 * accel[2] * u[1])

    _model.observe = observe
    _identify._observe = observe


if __name__ == "__main__":
    main()
