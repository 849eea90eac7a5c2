"""Where the launch vehicle's noise-free misfit against the independent generator
comes from, term by term: fly `tests/independent_generator.py` noise-free, then
evaluate what the diagnosis's model (`diagnose --vehicle pegasus`) would compute
at the generator's own states (same inputs, logged thrust, mass, Iyy, Iyy_dot,
CG and cp stations) and size each difference in the pitch acceleration (qdot) and
in the pitch rate q it leaves over one shooting interval (1 s, the model's node
spacing).

    nice python experiments/lv_misfit_terms.py [--seeds 13 0 1] [--rates 50 50 50]
        [--out experiments/results/lv_misfit_terms.json] [--knot-choices]

Terms (each alone, all else the generator's):

- `atmosphere`: the model's 1976 standard atmosphere (geopotential altitude) for
  the generator's (hydrostatics on geometric altitude): density and speed of sound
  at the same geometric altitude, so qbar and Mach.
- `gravity`: the model's inverse-square gravity (r0 = 6 356 766 m) for the
  generator's (6 371 000 m): a vertical acceleration, no moment.
- `aero_form_K`: the model's aerodynamics (cubic B-splines over Mach, `K` knots
  placed at the record's Mach quantiles, alpha, alpha^2, alpha^3, de, alpha de)
  fitted by least squares to the generator's exact CL, CD and CM at its states:
  what is left is what no parameter value of the model can express.
- `input_rk4`: the model's integrator and input: fixed-step RK4 at the model rate
  with the elevator interpolated linearly between samples (the model's input),
  against the exact solution of the same equations with the true step input.
- `input_exact_rk4`: RK4 at the model rate with the true step input (integration
  alone).
- `thrust arm, CG travel, jet damping, inertia variation`: the model reads thrust,
  mass, Iyy, Iyy_dot and the CG and cp stations from the log and writes the same
  equations (`M = Iyy qdot + Iyy_dot q`, thrust along body x through the CG): zero
  by construction, not evaluated.
"""

import argparse
import json
import pathlib
import sys

import numpy as np
from scipy.integrate import solve_ivp


HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

import independent_generator as gen  # noqa: E402


def _states(seed, duration=30.0, fine=1000.0):
    """The generator's noise-free flight at `fine` Hz: times, states
    `(n, 7)` (u, w, q, theta, x, h, m) and the true surface deflection."""
    times, levels = gen.elevator_schedule(seed, duration)
    fl = gen._Flight(times, levels, {})
    ch = gen._fly(fl, seed, fine, duration, 1e-10, 1e-9)
    alpha, v = ch["alpha"], ch["V"]
    x = np.stack(
        [
            v * np.cos(alpha),
            v * np.sin(alpha),
            ch["q"],
            ch["theta"],
            np.zeros_like(v),
            ch["h"],
            ch["mass"],
        ],
        1,
    )
    return fl, ch, x


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def _nonwhite(x):
    """Share of the variance not in first differences' white part: 1 - var(dx)/(2 var x)."""
    x = x - x.mean()
    if not np.any(x):
        return 0.0
    return float(1.0 - np.mean(np.diff(x) ** 2) / (2.0 * np.mean(x**2)))


def _segment_q(dqdot, dt, node=1.0):
    """The q error (rad/s) a qdot error `dqdot` (sampled every `dt`) builds up
    over shooting intervals of `node` s, each started exact (integral from the node)."""
    n = int(round(node / dt))
    out = np.empty_like(dqdot)
    for i in range(0, len(dqdot), n):
        seg = dqdot[i : i + n]
        out[i : i + n] = (
            np.concatenate([[0.0], np.cumsum(0.5 * (seg[1:] + seg[:-1]))]) * dt
        )
    return out


def terms(seed: int, log_rate: float, knot_counts=(6, 8, 12), rate=50.0) -> dict:
    from diffpegasus._vehicle._atmosphere import isa
    from diffpegasus._vehicle._gravity import gravity
    from diffpegasus._vehicle._mach_spline import (
        mach_breakpoints,
        MachSplineAerodynamics,
    )

    fl, ch, x = _states(seed)
    t = ch["t"]
    step = int(round(1000.0 / rate))
    sel = slice(0, None, step)
    u, w, q, theta, _, h, m = x[sel].T
    de = fl.surface(t[sel])
    alpha, v, mach, qbar = (
        ch["alpha"][sel],
        ch["V"][sel],
        ch["mach"][sel],
        ch["qbar"][sel],
    )
    iyy, xcg, xcp = ch["Iyy"][sel], ch["xcg"][sel], ch["xcp"][sel]
    s, c = gen.S_REF, gen.C_REF
    cl, cd, cm = gen.coefficients(alpha, de, mach)
    fz = -qbar * s * (cd * np.sin(alpha) + cl * np.cos(alpha))
    moment_aero = qbar * s * c * cm + (xcp - xcg) * fz
    res = {
        "seed": seed,
        "rate": log_rate,
        "alpha_deg_range": np.rad2deg([alpha.min(), alpha.max()]).tolist(),
        "mach_range": [float(mach.min()), float(mach.max())],
        "h_range": [float(h.min()), float(h.max())],
    }
    terms = {}

    # atmosphere: density and speed of sound of the 1976 standard atmosphere
    atm = isa(h)
    rho_m, a_m = np.asarray(atm.density), np.asarray(atm.speed_of_sound)
    _, _, rho_g, a_g = gen.atmosphere(h)
    drho = rho_m / rho_g - 1.0
    mach_m = v / a_m
    cl2, cd2, cm2 = gen.coefficients(alpha, de, mach_m)
    qbar_m = qbar * (1.0 + drho)
    fz2 = -qbar_m * s * (cd2 * np.sin(alpha) + cl2 * np.cos(alpha))
    dq_atm = (qbar_m * s * c * cm2 + (xcp - xcg) * fz2 - moment_aero) / iyy
    terms["atmosphere"] = {
        "density_rel": [float(drho.min()), float(drho.max())],
        "mach_diff": [float((mach_m - mach).min()), float((mach_m - mach).max())],
        "qdot": dq_atm,
        "az": (fz2 - fz) / m,
    }
    dg = gravity(h) - gen.gravity(h)
    terms["gravity"] = {
        "g_diff": [float(dg.min()), float(dg.max())],
        "qdot": 0.0 * h,
        "az": np.asarray(dg) * np.cos(theta),
    }

    # aerodynamic form: best least-squares fit of the model's regressors to the
    # generator's coefficients; `_atm`: to the coefficients the model's own
    # atmosphere reads (the generator's forces over the model's qbar, at its Mach)
    for k in knot_counts:
        part = MachSplineAerodynamics(knots=k)
        for tag, mk, scale in (("", mach, 1.0), ("_atm", mach_m, 1.0 / (1.0 + drho))):
            breaks = mach_breakpoints(mk, k - 2)
            a = part.regressors(mk, alpha, de, breaks)
            fits = [
                y - a @ np.linalg.lstsq(a, y, rcond=None)[0]
                for y in (cl * scale, cd * scale, cm * scale)
            ]
            dcl, dcd, dcm = fits
            qb = qbar / scale
            dfz = -qb * s * (dcd * np.sin(alpha) + dcl * np.cos(alpha))
            terms[f"aero_form_{k}{tag}"] = {
                "CM_rms": _rms(dcm),
                "CL_rms": _rms(dcl),
                "qdot": -(qb * s * c * dcm + (xcp - xcg) * dfz) / iyy,
                "az": -dfz / m,
            }

    # integration and input: RK4 at the model rate (50 Hz) over 1 s segments from
    # the true state, the elevator the log's samples at `rate` reduced to 50 Hz by
    # centred block means (what the diagnosis does) and interpolated linearly
    from diffpegasus._registry._pegasus import block_means

    dt = 1.0 / rate
    t_log = np.arange(int(round(30.0 * log_rate)) + 1) / log_rate
    de_log = gen._step_value(t_log, fl.times, fl.levels)
    de_samples = block_means(de_log, int(round(log_rate / rate)))[0]

    def exact_interp():
        out = np.empty_like(q)
        n = int(round(1.0 / dt))
        xs, ts = x[sel], t[sel]
        for i0 in range(0, len(q), n):
            i1 = min(i0 + n, len(q))
            if i1 - i0 < 2:
                out[i0] = xs[i0, 2]
                continue
            sol = solve_ivp(
                lambda tt, y: fl.rhs(tt, y, np.interp(tt, ts, de_samples)),
                (ts[i0], ts[i1 - 1]),
                xs[i0],
                method="DOP853",
                rtol=1e-10,
                atol=1e-9,
                t_eval=ts[i0:i1],
                max_step=dt / 4,
            )
            out[i0:i1] = sol.y[2]
        return out - q

    def rk4(exact_input):
        out = np.empty_like(q)
        n = int(round(1.0 / dt))
        xs = x[sel]
        for i0 in range(0, len(q), n):
            y = xs[i0].copy()
            out[i0] = y[2]
            for i in range(i0, min(i0 + n, len(q)) - 1):
                ti = t[sel][i]
                if exact_input:
                    d0, dm, d1 = (
                        fl.surface(ti),
                        fl.surface(ti + dt / 2),
                        fl.surface(ti + dt),
                    )
                else:
                    d0, d1 = de_samples[i], de_samples[i + 1]
                    dm = 0.5 * (d0 + d1)
                k1 = fl.rhs(ti, y, d0)
                k2 = fl.rhs(ti + dt / 2, y + dt / 2 * k1, dm)
                k3 = fl.rhs(ti + dt / 2, y + dt / 2 * k2, dm)
                k4 = fl.rhs(ti + dt, y + dt * k3, d1)
                y = y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
                out[i + 1] = y[2]
        return out - q

    dq_interp = exact_interp()
    dq_rk4 = rk4(False)
    terms["input"] = {"q_direct": dq_interp}
    terms["integration"] = {"q_direct": dq_rk4 - dq_interp}
    terms["input_and_integration"] = {"q_direct": dq_rk4}

    out = {}
    for name, d in terms.items():
        row = {k: v for k, v in d.items() if not isinstance(v, np.ndarray)}
        if "qdot" in d:
            dqs = _segment_q(np.asarray(d["qdot"], float), dt)
            row.update(
                qdot_rms=_rms(d["qdot"]), q_rms=_rms(dqs), q_nonwhite=_nonwhite(dqs)
            )
        if "az" in d:
            row["az_rms"] = _rms(d["az"])
        if "q_direct" in d:
            row.update(q_rms=_rms(d["q_direct"]), q_nonwhite=_nonwhite(d["q_direct"]))
        out[name] = row
    res["terms"] = out
    res["q_noise_sigma"] = gen.NOISE["q"]
    return res


def knot_choices(seed: int, log_rate: float) -> dict:
    """How many Mach functions the log supports, as the diagnosis reads it (block
    means to 50 Hz, coefficients reconstructed from the channels): the choice of
    `choose_knots` (the library's rule; `results/lv_knot_choices.json` holds the
    choices of the cross-validation across 1 s segments it replaced) on the
    noise-free and the noisy log, per coefficient, and that of a Bayesian information criterion
    `n sum_c log(RSS_c / n) + p log n` of the full-record regression (noisy log)."""
    from diffpegasus._estimate._coefficients import reconstruct_coefficients
    from diffpegasus._registry._pegasus import block_means
    from diffpegasus._vehicle._mach_spline import (
        choose_knots,
        mach_breakpoints,
        MachSplineAerodynamics,
    )

    res = {"seed": seed, "rate": log_rate}
    for noise in (False, True):
        ch, _ = gen.generate(seed, log_rate, 30.0, {}, noise)
        red = {k: block_means(v, int(round(log_rate / 50.0)))[0] for k, v in ch.items()}
        c = reconstruct_coefficients(red, gen.S_REF, gen.C_REF)
        y = [np.asarray(v) for v in (c.CL, c.CD, c.CM)]
        seg = np.floor(red["t"]).astype(int)
        tag = "noisy" if noise else "noise_free"
        args = (red["mach"], red["alpha"], red["de"])
        res[f"choose_knots_{tag}"] = choose_knots(*args, tuple(y), seg).knots
        if noise:
            for name, v in zip(("CL", "CD", "CM"), y, strict=True):
                res[f"choose_knots_{name}_only"] = choose_knots(*args, (v,), seg).knots
            n, bic = len(seg), {}
            for k in range(4, 13):
                part = MachSplineAerodynamics(knots=k)
                a = part.regressors(*args, mach_breakpoints(red["mach"], k - 2))
                ys = np.column_stack(y)
                rss = ((ys - a @ np.linalg.lstsq(a, ys, rcond=None)[0]) ** 2).sum(0)
                bic[k] = float(n * np.log(rss / n).sum() + 3 * a.shape[1] * np.log(n))
            res["bic_choice"] = min(bic, key=bic.get)
    return res


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[13, 0, 1])
    ap.add_argument("--rates", type=float, nargs="+", default=[50.0, 50.0, 50.0])
    ap.add_argument("--out", type=pathlib.Path)
    ap.add_argument("--knot-choices", action="store_true")
    a = ap.parse_args()
    if a.knot_choices:
        rows = [knot_choices(s, r) for s, r in zip(a.seeds, a.rates, strict=True)]
        for r in rows:
            print(r)
        if a.out:
            a.out.write_text(json.dumps(rows, indent=1))
        return
    results = [terms(s, r) for s, r in zip(a.seeds, a.rates, strict=True)]
    for r in results:
        print(
            f"seed {r['seed']} {r['rate']:.0f} Hz: alpha {r['alpha_deg_range']} deg, Mach {r['mach_range']}, h {r['h_range']}"
        )
        for name, row in r["terms"].items():
            print(
                f"  {name:18s} "
                + ", ".join(
                    f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}"
                    for k, v in row.items()
                )
            )
    if a.out:
        a.out.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
