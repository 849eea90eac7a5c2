"""The drag band with and without the sensors' disagreement on real flights (the fit
alone, default effects). Run: `python experiments/rocket_spread_real.py NAME [NAME ...]`
(folders under the shared rocket data, e.g. prometheus_2022 hedy).
"""

import sys
import time

import numpy as np

import diffpegasus.rocket as dr
from diffpegasus._log._rocketlogs import read_rocket_log


ROCKETS = "/work/shared/data/rockets"
for name in sys.argv[1:]:
    path = f"{ROCKETS}/{name}/rocket.toml"
    t0 = time.perf_counter()
    rocket = dr.read_rocket(path)
    log = read_rocket_log(path)
    p = dr.prepare(rocket, log)
    r = dr.fit_rocket(p, throw=False, spread=True)
    m = np.array(r.knots.mach)
    cd, sd = r.cd(m)
    _, sn = r.cd(m, structural=False)
    print(
        name,
        "seconds",
        round(time.perf_counter() - t0),
        "apogee",
        round(r.apogee, 1),
        "rms",
        round(r.rms(), 2),
        "converged",
        bool(r.fit.converged),
        "birge",
        None if r.spread is None else round(r.spread.birge, 2),
        "half-width % noise",
        round(float(np.mean(196 * sn / cd)), 1),
        "with spread",
        round(float(np.mean(196 * sd / cd)), 1),
        "median",
        round(float(np.median(196 * sn / cd)), 1),
        round(float(np.median(196 * sd / cd)), 1),
        flush=True,
    )
    print(
        " mach",
        np.round(m, 2).tolist(),
        "\n cd",
        np.round(cd, 3).tolist(),
        "\n hw noise",
        np.round(1.96 * sn, 3).tolist(),
        "\n hw spread",
        np.round(1.96 * sd, 3).tolist(),
        "\n sensors converged",
        None
        if r.spread is None or r.spread.converged is None
        else r.spread.converged.tolist(),
        "\n note",
        None if r.spread is None else r.spread.note,
        flush=True,
    )
