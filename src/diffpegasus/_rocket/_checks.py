"""Checks beside the output-error fit: equation-error drag and re-simulation.

[`equation_error_drag`][] is the drag the accelerometer measures directly: in the
coast the axial specific force is `-D/m`, so with the fitted trajectory's air data
`CD = -f m / (q S)` at every accelerometer sample (the power-off part, thrust zero).
[`resimulate`][] flies the fitted rocket again with another drag curve (the team's)
and catalogue thrust, for the apogee the team would have predicted.
"""

import equinox as eqx
import numpy as np

from ._identify import Problem, RocketFit, trajectory


def equation_error_drag(result: RocketFit, min_q: float = 2e3):
    """`(mach, cd)` arrays from measured coast acceleration, where the fitted
    dynamic pressure exceeds `min_q` Pa (below it the quantisation of the sensor
    dominates the drag it reads) — empty without an accelerometer."""
    import jax.numpy as jnp

    if "accel" not in result.outputs:
        return np.zeros(0), np.zeros(0)
    rec, fit = result.record, result.fit
    model = fit.model
    p = model.named(jnp.asarray(fit.params))
    flight = result.flight
    has = rec.inputs[:, 2] > 0
    idx = np.flatnonzero(has & (rec.t <= result.t[-1]))
    rocket = flight.rocket
    t_motor = rec.t[idx] - float(p["motor_time"])
    coast = t_motor > rocket.motor.burn_time * float(p["burn_scale"]) + 0.1
    idx = idx[coast]
    x = np.interp(rec.t[idx], result.t, np.arange(len(result.t)))
    states = np.array(
        [np.interp(x, np.arange(len(result.t)), result.states[:, j]) for j in range(6)]
    ).T
    mach = np.interp(rec.t[idx], result.t, result.mach)
    f = (rec.measured[idx, 1] - float(p["accel_bias"])) / float(p["accel_scale"])
    mass = rocket.dry_mass + float(p["mass_offset"])
    rho = np.array(
        [float(flight.air(s[2], p)[0]) for s in states[:: max(1, len(states) // 200)]]
    )
    hs = states[:: max(1, len(states) // 200), 2]
    rho = np.interp(states[:, 2], hs[np.argsort(hs)], rho[np.argsort(hs)])
    head = np.radians(rocket.heading)
    along = float(p["wind_along"])
    wind = np.array(
        [
            float(p["wind_east"]) + along * np.sin(head),
            float(p["wind_north"]) + along * np.cos(head),
            0.0,
        ]
    )
    speed = np.linalg.norm(states[:, 3:] - wind, axis=1)
    q = 0.5 * rho * speed**2
    keep = q > min_q
    cd = -f[keep] * mass / (q[keep] * rocket.area)
    return mach[keep], cd


def resimulate(problem: Problem, result: RocketFit, cd_curve=None) -> RocketFit:
    """The fitted flight flown again with catalogue thrust and the drag curve
    `cd_curve` `(mach, cd)` (default: the team's power-off curve; the team's
    power-on ratio), sensors and day as fitted."""
    knots = problem.flight.knots
    mach, cd = cd_curve if cd_curve is not None else problem.rocket.team_drag_off
    good = mach >= 0.05
    params = np.asarray(result.fit.params, float).copy()
    names = result.fit.model.parameters
    for name, m in zip(knots.names, knots.mach, strict=True):
        params[names.index(name)] = np.interp(m, mach[good], cd[good])
    params[names.index("cd_scale")] = 1.0
    params[names.index("thrust_scale")] = 1.0
    params[names.index("burn_scale")] = 1.0
    refit = eqx.tree_at(lambda f: f.params, result.fit, params)
    return trajectory(
        problem.rocket, problem.flight, refit, result.record, result.outputs
    )
