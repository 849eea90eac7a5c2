"""The plausible Pegasus lateral database in use: a short fin manoeuvre of the 6-DOF
Pegasus first stage, and the 15 lateral derivatives identified from it.

`dp.pegasus_aircraft()` (20 s after the drop, Mach 2, 16 km; an estimate, not
published data: see its module docstring) trimmed level; differential horizontal
fins (roll, 0.5 deg 3-2-1-1, 0.3 s unit) then the ventral fin (yaw, 0.5 deg doublet,
0.4 s); 5 s at 50 Hz, white noise. The vehicle is directionally unstable (a 0.6 /s
divergence), so the output-error fit uses multiple shooting (a node every 1 s), from
a start at 70% of the truth.

Run: `python experiments/pegasus_lateral.py`; the last stdout line is one JSON object.
"""

import json
import time

import numpy as np

import diffpegasus as dp


NOISE = np.array([2e-4, 1e-3, 5e-4, 1e-3, 0.05, 0.01, 0.005])  # the 7 outputs


def main():
    aircraft = dp.pegasus_aircraft()
    start = dp.trim(aircraft, dp.pegasus_speed(), altitude=16_000.0)
    t0 = time.perf_counter()
    f = dp.simulate_sixdof(
        aircraft,
        start,
        aileron=dp.three_two_one_one(0.5, 0.3, start=0.5),
        rudder=dp.doublet(0.5, 0.4, start=2.5),
        t_final=5.0,
        dt=0.02,
    )
    simulate_s = time.perf_counter() - t0
    print(
        f"|beta| <= {np.degrees(np.abs(f['beta']).max()):.1f} deg, |phi| <= "
        f"{np.degrees(np.abs(f['phi']).max()):.1f} deg, |p| <= "
        f"{np.abs(f['p']).max():.2f} rad/s"
    )
    rng = np.random.default_rng(5)
    y = np.column_stack([f[n] for n in dp.SIXDOF_LATERAL_OUTPUTS])
    y = y + rng.normal(size=y.shape) * NOISE
    u = np.column_stack([f[n] for n in dp.SIXDOF_LATERAL_INPUTS])
    x0 = [f[n][0] for n in dp.SIXDOF_LATERAL_STATES]
    truth = {
        n: float(getattr(aircraft.lateral, n)) for n in dp.LATERAL_DERIVATIVE_NAMES
    }
    model = dp.sixdof_lateral_model(
        mass=aircraft.mass,
        inertia=aircraft.inertia,
        s_ref=aircraft.s_ref,
        b_ref=aircraft.b_ref,
        rho=aircraft.rho,
        start={n: 0.7 * v for n, v in truth.items()},
    )
    t0 = time.perf_counter()
    fit = dp.fit(
        model,
        dp.Record(f["t"], u, y, x0=x0),
        shooting=dp.MultipleShooting(interval=1.0),
    )
    fit_s = time.perf_counter() - t0
    est = fit.estimates()
    sd = dict(zip(model.parameters, fit.stderr.tolist(), strict=True))
    print(f"{'derivative':>10} {'truth':>9} {'estimate':>9} {'std err':>8} {'z':>6}")
    rows = []
    for n in dp.LATERAL_DERIVATIVE_NAMES:
        z = (est[n] - truth[n]) / sd[n]
        print(f"{n:>10} {truth[n]:9.4f} {est[n]:9.4f} {sd[n]:8.4f} {z:6.2f}")
        rows.append(dict(parameter=n, truth=truth[n], estimate=est[n], stderr=sd[n]))
    print(
        f"converged {fit.converged}, {fit.iterations} iterations, correlated above "
        f"0.9: {fit.high_correlations()}"
    )
    print(
        json.dumps(
            dict(
                rows=rows,
                det_R=fit.cost,
                iterations=fit.iterations,
                high_correlations=fit.high_correlations(),
                simulate_s=simulate_s,
                fit_s=fit_s,
            )
        )
    )


if __name__ == "__main__":
    main()
