"""Lateral-directional identification end to end: simulate, estimate, compare.

1. Two lateral manoeuvres of the 6-DOF business jet (`dp.business_jet()`, trimmed at
   104.67 m/s): an aileron 3-2-1-1 then a rudder doublet, and a rudder 3-2-1-1 then
   an aileron doublet; 25 s each, logged at 25 Hz with white sensor noise.
2. Output error on both at once with the nonlinear 6-DOF lateral model
   (`dp.sixdof_lateral_model`: 15 coefficient derivatives, the measured longitudinal
   motion as pseudo-inputs) from a start 40% off the truth; table of truth,
   estimate, standard error and error in standard errors.
3. The textbooks' linear model (`dp.lateral_model(manoeuvres=2)`: 15 dimensional
   derivatives, per-manoeuvre state biases, shared output biases) on the same
   records, against the dimensional derivatives the truth implies.
4. The same linear model on the lateral channels of the real HFB-320 record (a
   longitudinal manoeuvre: the controls barely move, so most derivatives are not
   identifiable; reported as a diagnostic, with the correlations flagged).

The last stdout line is one JSON object with every number printed.

Run: `python experiments/lateral.py [--noise-seed N]`.
"""

import argparse
import json
import time

import jax
import numpy as np
from _shared import shared_data

import diffpegasus as dp


SPEED = 104.67  # m/s
DT = 0.04  # s
T_FINAL = 25.0  # s
# white noise of the log, one standard deviation per output of the 6-DOF model:
# beta (rad), p, r (rad/s), phi (rad), ay (m/s^2), pdot, rdot (rad/s^2)
NOISE = np.array([1e-3, 2e-3, 1e-3, 2e-3, 0.05, 0.01, 0.005])


def manoeuvres():
    """The two manoeuvres' aileron and rudder schedules."""
    return [
        dict(
            aileron=dp.three_two_one_one(3.0, 0.5, start=1.0, rise=0.08),
            rudder=dp.doublet(3.0, 1.2, start=9.0, rise=0.08),
        ),
        dict(
            aileron=dp.doublet(3.0, 1.0, start=12.0, rise=0.08),
            rudder=dp.three_two_one_one(3.0, 0.6, start=1.0, rise=0.08),
        ),
    ]


def simulate(aircraft, seed, t_final=T_FINAL):
    """Noise-free flights and noisy records for the 6-DOF lateral model."""
    start = dp.trim(aircraft, SPEED)
    rng = np.random.default_rng(seed)
    flights, records = [], []
    for k, m in enumerate(manoeuvres()):
        f = dp.simulate_sixdof(aircraft, start, t_final=t_final, dt=DT, **m)
        flights.append(f)
        inputs = np.column_stack([f[n] for n in dp.SIXDOF_LATERAL_INPUTS])
        clean = np.column_stack([f[n] for n in dp.SIXDOF_LATERAL_OUTPUTS])
        noisy = clean + rng.normal(size=clean.shape) * NOISE
        x0 = [f["v"][0], f["p"][0], f["r"][0], f["phi"][0]]
        records.append(
            dp.Record(f["t"], inputs, noisy, x0=x0, name=f"manoeuvre {k + 1}")
        )
    return start, flights, records


def lateral_model_of(aircraft, start):
    """The 6-DOF lateral model with the aircraft's mass, inertia, geometry and air."""
    return dp.sixdof_lateral_model(
        mass=aircraft.mass,
        inertia=aircraft.inertia,
        s_ref=aircraft.s_ref,
        b_ref=aircraft.b_ref,
        rho=aircraft.rho,
        start=start,
    )


def table(names, truth, fit, title):
    est = fit.estimates()
    sd = dict(zip(fit.model.parameters, fit.stderr_corrected.tolist(), strict=True))
    crb = dict(zip(fit.model.parameters, fit.stderr.tolist(), strict=True))
    print(f"\n{title}")
    print(f"{'parameter':>10} {'truth':>11} {'estimate':>11} {'std err':>9} {'z':>6}")
    rows = []
    for n in names:
        z = (est[n] - truth[n]) / crb[n] if truth is not None else float("nan")
        t = truth[n] if truth is not None else float("nan")
        print(f"{n:>10} {t:11.5f} {est[n]:11.5f} {sd[n]:9.5f} {z:6.2f}")
        rows.append(dict(parameter=n, truth=t, estimate=est[n], stderr=sd[n], z=z))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--noise-seed", type=int, default=17)
    args = ap.parse_args()
    aircraft = dp.business_jet()
    result = {}

    t0 = time.perf_counter()
    start, flights, records = simulate(aircraft, args.noise_seed)
    result["simulate_s"] = time.perf_counter() - t0
    truth = {
        n: float(getattr(aircraft.lateral, n)) for n in dp.LATERAL_DERIVATIVE_NAMES
    }
    for k, f in enumerate(flights):
        print(
            f"manoeuvre {k + 1}: |p| <= {np.abs(f['p']).max():.3f} rad/s, "
            f"|beta| <= {np.rad2deg(np.abs(f['beta']).max()):.2f} deg, "
            f"|phi| <= {np.rad2deg(np.abs(f['phi']).max()):.2f} deg"
        )

    model = lateral_model_of(aircraft, start={n: 0.6 * v for n, v in truth.items()})
    t0 = time.perf_counter()
    fit = dp.fit(model, records)
    result["nonlinear_fit_s"] = time.perf_counter() - t0
    result["nonlinear"] = dict(
        rows=table(
            dp.LATERAL_DERIVATIVE_NAMES,
            truth,
            fit,
            "6-DOF lateral model, two manoeuvres",
        ),
        det_R=fit.cost,
        iterations=fit.iterations,
        high_correlations=fit.high_correlations(),
    )
    print(
        f"det R {fit.cost:.6e}, {fit.iterations} iterations, "
        f"correlated above 0.9: {fit.high_correlations()}"
    )

    lin = dp.lateral_model(manoeuvres=2)
    lin_records = []
    for k, f in enumerate(flights):
        rec = records[k]
        out = {n: rec.measured[:, i] for i, n in enumerate(dp.SIXDOF_LATERAL_OUTPUTS)}
        u = np.column_stack([f["da"], f["dr"], out["beta"]])
        y = np.column_stack([out[n] for n in dp.LATERAL_OUTPUTS])
        lin_records.append(dp.lateral_record(lin, f["t"], u, y, manoeuvre=k + 1))
    t0 = time.perf_counter()
    lfit = dp.fit(lin, lin_records)
    result["linear_fit_s"] = time.perf_counter() - t0
    implied = dp.implied_lateral_derivatives(aircraft, SPEED)
    result["linear"] = dict(
        rows=table(
            dp.LATERAL_DERIVATIVES,
            implied,
            lfit,
            "linear model (beta measured, noisy) against the implied derivatives",
        ),
        det_R=lfit.cost,
        iterations=lfit.iterations,
    )
    print(f"det R {lfit.cost:.6e}, {lfit.iterations} iterations")

    # sideslip and bank angle as states of the linear model: no noisy input
    alpha0, theta0 = float(start.y[7]), float(start.y[7])
    sl = dp.lateral_model(
        manoeuvres=2, sideslip="state", flight=(SPEED, alpha0, theta0)
    )
    sl_records = []
    for k, f in enumerate(flights):
        rec = records[k]
        out = {n: rec.measured[:, i] for i, n in enumerate(dp.SIXDOF_LATERAL_OUTPUTS)}
        u = np.column_stack([f["da"], f["dr"]])
        y = np.column_stack([out[n] for n in (*dp.LATERAL_OUTPUTS, "beta", "phi")])
        sl_records.append(dp.lateral_record(sl, f["t"], u, y, manoeuvre=k + 1))
    t0 = time.perf_counter()
    sfit = dp.fit(sl, sl_records)
    result["linear_state_fit_s"] = time.perf_counter() - t0
    result["linear_state"] = dict(
        rows=table(
            dp.LATERAL_DERIVATIVES,
            implied,
            sfit,
            "linear model, sideslip and bank angle as states",
        ),
        det_R=sfit.cost,
        iterations=sfit.iterations,
    )
    print(f"det R {sfit.cost:.6e}, {sfit.iterations} iterations")

    path = shared_data("hfb320/hfb320_1_10.asc")
    if path.exists():
        ch = dp.read_lateral_asc(path)
        one = dp.lateral_model()
        rec = dp.lateral_record(
            one, ch["t"],
            np.column_stack([ch["da"], ch["dr"], ch["beta"]]),
            np.column_stack([ch[n] for n in dp.LATERAL_OUTPUTS]),
            name="hfb320_1_10",
        )  # fmt: skip
        hfit = dp.fit(one, rec, throw=False)
        print(
            f"\nHFB-320 lateral channels: aileron spread {np.ptp(ch['da']):.2e} rad, "
            f"rudder {np.ptp(ch['dr']):.2e} rad, sideslip {np.ptp(ch['beta']):.2e} rad"
        )
        table(dp.LATERAL_DERIVATIVES, None, hfit, "HFB-320 record, linear model")
        print(
            f"converged {hfit.converged}, det R {hfit.cost:.6e}, "
            f"{len(hfit.high_correlations())} pairs correlated above 0.9"
        )
        result["hfb320"] = dict(
            converged=hfit.converged,
            det_R=hfit.cost,
            estimates=hfit.estimates(),
            stderr=dict(
                zip(one.parameters, hfit.stderr_corrected.tolist(), strict=True)
            ),
            high_correlations=len(hfit.high_correlations()),
        )
    print(json.dumps(result, default=float))


if __name__ == "__main__":
    jax.config.update("jax_enable_x64", True)
    main()
