"""Where the one-sample colour of the launch vehicle's innovations in 1.5 m/s gusts
comes from (measurement aid).

`measured`: per flight stored by `turbulence_check.py` (its pickles), per output
the autocorrelation of the judged innovations (the filter's, less the input's
timing) at lags 1-5, the noise model kept, its correlation time and whether the
gain constraint `diag(K C) <= 1` was active at the fit.

`toy`: the same question on a flight one can solve by hand: a first-order
Gauss-Markov vertical gust (the independent generator's: 1.5 m/s, 533 m at
236 m/s, drawn by its exact recursion at 100 Hz) seen by an alpha vane
(1e-3 rad noise) and a normal accelerometer (-12 m/s^2 per rad of gust angle,
0.02 m/s^2 noise), logged at 100 Hz and brought to 25 Hz either by centred block
means (the launch vehicle's decimation: weights 1/2, 1, 1, 1, 1/2 over 4) or by
taking every fourth sample; the gust filter (the gust state, diagonal innovation
covariance relaxed, correlation time and intensity by maximum likelihood, as the
filter-error fit does) with its gain free or held at `diag(K C) <= 1` or 0.9.

    python experiments/turbulence_colour.py measured
    python experiments/turbulence_colour.py toy

Results: experiments/results/turbulence_colour.json (each part's key).
"""

import json
import pathlib
import pickle
import sys

import numpy as np
import scipy.optimize
import scipy.signal


ROOT = pathlib.Path(__file__).resolve().parent.parent
PICKLES = ROOT / "experiments" / "results" / "turbulence_check"
OUT = ROOT / "experiments" / "results" / "turbulence_colour.json"


def autocorrelation(x: np.ndarray, lags: int = 5) -> list[float]:
    """Sample autocorrelation of `x` `(n,)` at lags 1..`lags`."""
    x = np.asarray(x, float) - np.mean(x)
    return [round(float(x[k:] @ x[:-k] / (x @ x)), 3) for k in range(1, lags + 1)]


def measured() -> list[dict]:
    rows = []
    for f in sorted(PICKLES.glob("*.pkl")):
        d = pickle.load(open(f, "rb"))
        pn = next(r for r in d["report"]["ranking"] if r["effect"] == "process_noise")
        row = {
            "flight": d["spec"],
            "named": d["significant"],
            "likelihood_ratio": round(pn["statistic"], 1),
            "noise_model": pn.get("noise_model", {}).get("model"),
            "tau": pn.get("noise_model", {}).get("coloured", {}).get("tau"),
            "constraint_active": pn.get("constraint_active"),
        }
        if "innovations" in d:
            judged = d.get("adjusted") or d["innovations"]
            nu = np.concatenate([np.asarray(x) for x in judged])
            row["check"] = {k: round(v, 1) for k, v in d["per_output"].items()}
            row["threshold"] = round(d["evidence"]["threshold"], 1)
            row["autocorrelation"] = {
                o: autocorrelation(nu[:, i]) for i, o in enumerate(d["outputs"])
            }
            row["intensities"] = dict(
                zip(d["noise_states"], np.asarray(d["F"]).tolist(), strict=True)
            )
        rows.append(row)
        print(json.dumps(row))
    return rows


# --- the toy flight ---------------------------------------------------------------
SPEED = 236.0  # m/s, the generator's airspeed at drop (Mach 0.8 at 12.5 km)
TAU = 533.0 / SPEED  # s
SIGMA = 1.5 / SPEED  # rad, gust angle
AZ_PER_RAD = -12.0  # m/s^2 per rad of gust angle
NOISE = (1e-3, 0.02)  # alpha (rad), az (m/s^2) per 100 Hz sample
STEP = 4  # 100 Hz to 25 Hz
DT = 0.04


def _toy_log(decimation: str, seconds: float = 200.0, seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    m = int(seconds * 100)
    a = np.exp(-0.01 / TAU)
    g = np.empty(m)
    g[0] = SIGMA * rng.normal()
    kick = SIGMA * np.sqrt(1 - a * a) * rng.normal(size=m)
    for k in range(1, m):
        g[k] = a * g[k - 1] + kick[k]
    z = np.column_stack(
        [
            g + NOISE[0] * rng.normal(size=m),
            AZ_PER_RAD * g + NOISE[1] * rng.normal(size=m),
        ]
    )
    idx = np.arange(2, m - 2, STEP)
    if decimation == "point":
        return z[idx]
    w = np.array([0.5, 1.0, 1.0, 1.0, 0.5]) / STEP
    return sum(w[j] * z[idx + j - 2] for j in range(5))


def _filter(z, log_tau, log_f, r):
    """Innovations and `diag(K C)` of the steady-state gust filter with innovation
    covariance `r` held (the filter-error method's Riccati, closed form for one
    state)."""
    c = np.array([1.0, AZ_PER_RAD])
    tau, f = np.exp(log_tau), np.exp(log_f)
    phi = np.exp(-DT / tau)
    q = f * f * tau / 2 * (1 - phi * phi)
    s = c @ np.linalg.solve(r, c)
    p = (-(1 - phi**2) + np.sqrt((1 - phi**2) ** 2 + 4 * phi**2 * s * q)) / (
        2 * phi**2 * s
    )
    k = p * np.linalg.solve(r, c)
    # x~_k+1 = phi (1 - K c) x~_k + phi K z_k, from x~_0 = 0
    x = scipy.signal.lfilter([0.0, 1.0], [1.0, -phi * (1 - k @ c)], phi * (z @ k))
    return z - x[:, None] * c, float(p * s)


def _toy_fit(z, cap):
    """Maximum likelihood with the diagonal innovation covariance relaxed, the
    gain held at `diag(K C) <= cap` (a penalty) when `cap` is given."""
    n = len(z)
    r = np.diag(np.var(np.diff(z, axis=0), axis=0))
    p = np.array([np.log(2.0), np.log(0.005)])
    for _ in range(50):

        def cost(v, r=r):
            nu, kc = _filter(z, *v, r)
            pen = 0.0 if cap is None or kc <= cap else 1e6 * n * (kc - cap) ** 2
            return float(np.sum(nu**2 / np.diag(r))) + pen

        p = scipy.optimize.minimize(
            cost,
            p,
            method="Nelder-Mead",
            options={"xatol": 1e-7, "fatol": 1e-9, "maxiter": 2000},
        ).x
        nu, kc = _filter(z, *p, r)
        new = np.diag(np.mean(nu**2, axis=0))
        if np.allclose(new, r, rtol=1e-7):
            break
        r = new
    return {
        "tau": round(float(np.exp(p[0])), 3),
        "kc": round(kc, 3),
        "n_ln_det_R": round(float(n * np.log(np.linalg.det(r))), 1),
        "autocorrelation": {
            "alpha": autocorrelation(nu[:, 0]),
            "az": autocorrelation(nu[:, 1]),
        },
    }


def toy() -> list[dict]:
    rows = []
    for decimation in ("block", "point"):
        z = _toy_log(decimation)
        for cap in (None, 1.0, 0.9):
            row = {"decimation": decimation, "gain_cap": cap, **_toy_fit(z, cap)}
            rows.append(row)
            print(json.dumps(row))
    return rows


def main():
    part = sys.argv[1] if len(sys.argv) > 1 else "measured"
    rows = {"measured": measured, "toy": toy}[part]()
    old = json.loads(OUT.read_text()) if OUT.exists() else {}
    old[part] = rows
    OUT.write_text(json.dumps(old, indent=1))


if __name__ == "__main__":
    main()
