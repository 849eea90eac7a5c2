"""Where the point-mass model's apogee leaves RocketPy's on the clean fixture flight.

RocketPy flies the clean flight (scripts/make_rocket_fixtures.py's spec); a numpy
point mass (the model's equations: thrust and drag along the air-relative velocity,
the rail) flies it with RocketPy's own density, speed of sound, gravity and drag
table, from the same rail. Terms RocketPy has and the model lacks are then added one
at a time as accelerations measured on RocketPy's flight (functions of time), and the
apogee gap re-measured. Run: python experiments/rocket_coast_gap.py
"""

import json
import pathlib
import sys

import numpy as np
from scipy.integrate import solve_ivp


ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
import make_rocket_fixtures as mk  # noqa: E402


def main():
    spec = mk.FLIGHTS["clean"]
    env, rocket, fl = mk.rocketpy_flight(spec)
    t_apo = float(fl.apogee_time)
    t = np.arange(0.0, t_apo, 0.01)
    st = np.array(fl.solution)  # t, x, y, z, vx, vy, vz, e0..e3, w1..w3
    ts = st[:, 0]

    def at(s, col):
        return np.interp(s, ts, st[:, col])

    # body axis in the inertial frame, RocketPy's aerodynamic force and mass
    w_earth = np.array(env.earth_rotation_vector)
    area = np.pi * 0.052**2
    rail_exit = float(fl.out_of_rail_time)
    burnout = float(rocket.motor.burn_out_time)
    mass_dry = 8.2 + 1.6
    thrust_t, thrust_f = mk.THRUST[:, 0], mk.THRUST[:, 1] * spec["scale"]
    impulse = np.trapezoid(thrust_f, thrust_t)

    def thrust(s):
        return np.interp(s, thrust_t, thrust_f, left=0, right=0)

    fine = np.linspace(0, thrust_t[-1], 4001)
    cum = np.concatenate(
        [[0], np.cumsum(np.diff(fine) * 0.5 * (thrust(fine[1:]) + thrust(fine[:-1])))]
    )

    def mass(s):
        return mass_dry + 1.9 * (1 - np.interp(s, fine, cum) / impulse)

    cd_off = rocket.power_off_drag
    rho_f, sound_f, g_f = env.density, env.speed_of_sound, env.gravity
    wind = np.array([spec["wind"][0], spec["wind"][1], 0.0])

    # RocketPy's aerodynamic force per unit mass (inertial), from its own record
    rp_aero = np.array([[fl.R1(s), fl.R2(s), fl.R3(s)] for s in t])
    bx_t = np.zeros((len(t), 3))
    by_t = np.zeros((len(t), 3))
    bz_t = np.zeros((len(t), 3))
    for i, s in enumerate(t):
        q = np.array([at(s, 7 + k) for k in range(4)])
        q /= np.linalg.norm(q)
        a0, a1, a2, a3 = q
        K = np.array(
            [
                [
                    a0**2 + a1**2 - a2**2 - a3**2,
                    2 * (a1 * a2 - a0 * a3),
                    2 * (a1 * a3 + a0 * a2),
                ],
                [
                    2 * (a1 * a2 + a0 * a3),
                    a0**2 - a1**2 + a2**2 - a3**2,
                    2 * (a2 * a3 - a0 * a1),
                ],
                [
                    2 * (a1 * a3 - a0 * a2),
                    2 * (a2 * a3 + a0 * a1),
                    a0**2 - a1**2 - a2**2 + a3**2,
                ],
            ]
        )
        bx_t[i], by_t[i], bz_t[i] = K[:, 0], K[:, 1], K[:, 2]
    aero_in = rp_aero[:, :1] * bx_t + rp_aero[:, 1:2] * by_t + rp_aero[:, 2:3] * bz_t
    m_t = np.array([float(rocket.total_mass(s)) for s in t])
    vel_t = np.stack([at(t, 4), at(t, 5), at(t, 6)], axis=1)
    air_t = vel_t - wind
    vhat = air_t / np.linalg.norm(air_t, axis=1, keepdims=True)
    # split RocketPy's aero force: along the air-relative velocity, and across it
    along = np.einsum("ij,ij->i", aero_in, vhat)[:, None] * vhat
    across = (aero_in - along) / m_t[:, None]
    z_t = at(t, 3)
    qdyn = 0.5 * np.array([rho_f(z) for z in z_t]) * np.sum(air_t**2, axis=1)
    mach_t = np.linalg.norm(air_t, axis=1) / np.array([sound_f(z) for z in z_t])
    cd_t = np.array([cd_off(m) for m in mach_t])
    ours_drag = qdyn * area * cd_t
    along_diff = (
        (-np.einsum("ij,ij->i", aero_in, vhat) - ours_drag)[:, None]
        * (-vhat)
        / m_t[:, None]
    )
    alpha = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", bz_t, vhat), -1, 1)))
    mass_diff = m_t - np.array([mass(s) for s in t])

    def extra_fn(series):
        return lambda s: np.array([np.interp(s, t, series[:, k]) for k in range(3)])

    terms = {
        "across": extra_fn(across),
        "along": extra_fn(along_diff),
    }

    def fly(coriolis=False, add=(), start=None):
        def f(s, x):
            pos, vel = x[:3], x[3:]
            m = mass(s)
            z = 150.0 + pos[2]
            air = vel - wind
            sp = np.linalg.norm(air)
            mach = sp / sound_f(z)
            cd = cd_off(mach)
            drag = 0.5 * rho_f(z) * sp**2 * area * cd
            th = thrust(s)
            a = (th - drag) / m * air / sp + np.array([0, 0, -g_f(z)])
            for k in add:
                a = a + terms[k](s)
            if coriolis:
                a = a - 2 * np.cross(w_earth, vel)
            return np.concatenate([vel, a])

        s0, x0 = start
        ev = lambda s, x: x[5]  # noqa: E731
        ev.terminal, ev.direction = True, -1
        sol = solve_ivp(
            f,
            (s0, 60),
            x0,
            rtol=1e-10,
            atol=1e-8,
            events=ev,
            max_step=0.05,
            dense_output=True,
        )
        return sol.t_events[0][0], sol.y_events[0][0][2], sol

    # start at RocketPy's rail exit (its state there): the coast compared alone
    x_exit = np.array([at(rail_exit, c) for c in range(1, 7)])
    x_exit[2] -= 150.0
    rp_apogee = float(fl.apogee) - 150.0
    out = {
        "rocketpy_apogee_agl": rp_apogee,
        "rail_exit_s": rail_exit,
        "burnout_s": burnout,
        "apogee_s": t_apo,
    }
    for name, s0 in (
        ("rail exit", rail_exit),
        ("burnout", burnout),
        ("burnout + 5 s", burnout + 5),
    ):
        x0 = np.array([at(s0, c) for c in range(1, 7)])
        x0[2] -= 150.0
        ta, za, sol = fly(start=(s0, x0), coriolis=True, add=("across",))
        zz = {
            f"{s:.0f}": float(sol.sol(s)[2] + 150 - at(s, 3))
            for s in (3.8, 8, 12, 16, 20, 23)
            if s > s0
        }
        print(
            f"from {name}: gap with Coriolis and across {za - rp_apogee:+.2f} m; z gaps {zz}"
        )
        out[f"from {name}"] = {"gap_m": za - rp_apogee, "z_gaps": zz}
    for label, kw in [
        ("point mass", {}),
        ("+ Coriolis", dict(coriolis=True)),
        ("+ aero across the airspeed", dict(add=("across",))),
        ("+ aero along (axial vs along-velocity)", dict(add=("along",))),
        ("+ Coriolis + across", dict(coriolis=True, add=("across",))),
        ("+ all three", dict(coriolis=True, add=("across", "along"))),
    ]:
        ta, za, _ = fly(start=(rail_exit, x_exit), **kw)
        out[label] = {"apogee_agl": za, "gap_m": za - rp_apogee, "t": ta}
        print(f"{label:45s} apogee {za:9.2f}  gap {za - rp_apogee:+7.2f} m  t {ta:.2f}")
    out["mass_diff_max_kg"] = float(np.max(np.abs(mass_diff)))
    out["alpha_deg"] = {
        f"{s:.0f}": float(np.interp(s, t, alpha))
        for s in (5, 10, 15, 20, 25, t_apo - 1)
    }
    out["across_up_m_s2"] = {
        f"{s:.0f}": float(np.interp(s, t, across[:, 2]))
        for s in (5, 10, 15, 20, 25, t_apo - 1)
    }
    print(
        json.dumps(
            {k: out[k] for k in ("mass_diff_max_kg", "alpha_deg", "across_up_m_s2")},
            indent=1,
        )
    )
    (ROOT / "experiments" / "results" / "rocket_coast_gap.json").write_text(
        json.dumps(out, indent=1)
    )


if __name__ == "__main__":
    main()
