"""What real logs hold after apogee, for telling a barometer lag from a barometer
error that depends on height (on the descent the climb rate changes sign at the
same heights): per flight the ascent's and the drogue descent's duration and
barometer samples, and where the log has GNSS altitude, the barometric minus the
GNSS altitude fitted by a polynomial in height (degree 2 to 4) plus a term in the
barometer's climb rate, over the coast alone (burnout + 1 s to apogee - 1 s) and
over the coast with the drogue descent (drogue + 3 s to main - 1 s). The climb-rate
term is the barometer's lag relative to the GNSS altitude's (both unknown).

`python experiments/rocket_baro_descent.py ROCKET_TOML [ROCKET_TOML ...]`; writes
experiments/results/rocket_baro_descent.json.
"""

import json
import pathlib
import sys

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]


def relative_lag(t, h, v, d, mask, degree):
    """Least squares of `d` on `1, (h/km)^1..degree, v` over `mask`: the
    coefficient of `v` (s) and its standard error, the residual RMS (m)."""
    hk = h[mask] / 1000.0
    a = np.column_stack(
        [hk**k for k in range(degree + 1)] + [v[mask]],
    )
    c, *_ = np.linalg.lstsq(a, d[mask], rcond=None)
    r = d[mask] - a @ c
    s2 = float(r @ r) / (len(r) - a.shape[1])
    cov = s2 * np.linalg.inv(a.T @ a)
    return float(c[-1]), float(np.sqrt(cov[-1, -1])), float(np.sqrt(s2))


def main():
    from diffpegasus._log._rocketlogs import read_rocket_log

    out = {}
    for toml in map(pathlib.Path, sys.argv[1:]):
        log = read_rocket_log(toml)
        ev = {k: float(e.t) for k, e in log.events.items()}
        baro = log.channels["altitude"]
        tb, hb = np.asarray(baro.t), np.asarray(baro.values)
        row = {"events_s": ev}
        if "drogue" in ev:
            end = ev.get("main", ev.get("landing", tb[-1]))
            row["drogue_descent_s"] = float(end - ev["drogue"])
            row["drogue_samples"] = int(np.sum((tb > ev["drogue"]) & (tb < end)))
        row["ascent_samples"] = int(np.sum((tb > 0) & (tb < ev["apogee"])))
        print(f"{toml.parent.name}: events {ev}; {row}")
        if "gnss_alt" in log.channels and "drogue" in ev and "main" in ev:
            g = log.channels["gnss_alt"]
            tg, hg = np.asarray(g.t), np.asarray(g.values)
            hg = hg - (np.median(hg[tg < 0]) if np.any(tg < 0) else hg[0])

            def rate(t0, tb=tb, hb=hb):
                m = np.abs(tb - t0) < 0.5
                return np.polyfit(tb[m], hb[m], 1)[0]

            v = np.array([rate(s) for s in tg])
            d = np.interp(tg, tb, hb) - hg
            coast = (tg > ev["burnout"] + 1) & (tg < ev["apogee"] - 1)
            drogue = (tg > ev["drogue"] + 3) & (tg < ev["main"] - 1)
            for degree in (2, 3, 4):
                for label, m in (("coast", coast), ("coast+drogue", coast | drogue)):
                    c, s, rms = relative_lag(tg, hg, v, d, m, degree)
                    row[f"{label} degree {degree}"] = {
                        "climb_rate_term_s": c,
                        "stderr_s": s,
                        "rms_m": rms,
                        "samples": int(m.sum()),
                    }
                    print(
                        f"  baro - GNSS over the {label}, height degree {degree}: "
                        f"{c:+.3f} +- {s:.3f} s per m/s of climb "
                        f"(RMS {rms:.1f} m, {int(m.sum())} GNSS samples)"
                    )
        out[toml.parent.name] = row
    path = ROOT / "experiments" / "results" / "rocket_baro_descent.json"
    path.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
