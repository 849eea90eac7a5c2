"""Rigid-body six-degree-of-freedom flight: equations, lateral aerodynamics, an
aircraft, trim and simulation of lateral manoeuvres.

Flat, non-rotating Earth; north-east-down inertial axes; body axes x to the nose, y
to the right wing, z down; Euler angles `phi, theta, psi` (roll, pitch, yaw, rad) in
the 3-2-1 order. The state of [`sixdof_rates`][] is

    y = [u, v, w, p, q, r, phi, theta, psi, x_north, y_east, h]

(body velocities m/s, body rates rad/s, attitude rad, position m, altitude m). The
pitch-plane model of `_dynamics.py` is the symmetric special case `v = p = r = phi =
psi = 0` (tests check that the two agree).

Aerodynamics: lift and drag act in the stability axes (the small-sideslip form: the
drag is not rotated by `beta`), the side force along body y; the lateral
coefficients are linear in `beta`, the nondimensional rates `p b / 2V`, `r b / 2V`
and the controls ([`lateral_coefficients`][]).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._inputs import AbstractInput, NoInput
from .._rk4 import rk4_scan
from ._axes import wind_body


G = 9.80665  # m/s^2
_NONE = NoInput()
STATE_NAMES = ("u", "v", "w", "p", "q", "r", "phi", "theta", "psi", "x", "y", "h")
LATERAL_DERIVATIVE_NAMES = (
    "CY_beta", "CY_p", "CY_r", "CY_da", "CY_dr",
    "Cl_beta", "Cl_p", "Cl_r", "Cl_da", "Cl_dr",
    "Cn_beta", "Cn_p", "Cn_r", "Cn_da", "Cn_dr",
)  # fmt: skip


def inertia_tensor(ixx, iyy, izz, ixz=0.0, ixy=0.0, iyz=0.0) -> Float[Array, "3 3"]:
    """The inertia tensor `(3, 3)` (kg m^2) from moments and products of inertia
    (`ixz` = integral of `x z dm`, so the tensor holds `-ixz` off the diagonal)."""
    return jnp.array(
        [[ixx, -ixy, -ixz], [-ixy, iyy, -iyz], [-ixz, -iyz, izz]], dtype=float
    )


def euler_rates(omega, euler) -> Float[Array, "3"]:
    """`(phidot, thetadot, psidot)` (rad/s) of the 3-2-1 Euler angles `euler` (rad)
    for body rates `omega = (p, q, r)` (rad/s)."""
    p, q, r = omega
    phi, theta, _ = euler
    s, c = jnp.sin(phi), jnp.cos(phi)
    return jnp.stack(
        [
            p + (q * s + r * c) * jnp.tan(theta),
            q * c - r * s,
            (q * s + r * c) / jnp.cos(theta),
        ]
    )


def body_to_earth(euler) -> Float[Array, "3 3"]:
    """Rotation matrix from body to north-east-down axes for Euler angles (rad)."""
    phi, theta, psi = euler
    cf, sf = jnp.cos(phi), jnp.sin(phi)
    ct, st = jnp.cos(theta), jnp.sin(theta)
    cp, sp = jnp.cos(psi), jnp.sin(psi)
    return jnp.array(
        [
            [ct * cp, sf * st * cp - cf * sp, cf * st * cp + sf * sp],
            [ct * sp, sf * st * sp + cf * cp, cf * st * sp - sf * cp],
            [-st, sf * ct, cf * ct],
        ]
    )


def rigid_body_rates(vel, omega, euler, force, moment, mass, inertia, inertia_dot, g):
    """Body-axis accelerations of a rigid body with varying mass and inertia.

    **Arguments:** body velocity `vel = (u, v, w)` (m/s), body rates `omega = (p, q,
    r)` (rad/s), Euler angles `euler` (rad), non-gravitational body force `force`
    (N) and moment about the CG `moment` (N m), each `(3,)`; `mass` (kg); `inertia`
    and `inertia_dot` `(3, 3)` (kg m^2, kg m^2/s); gravity `g` (m/s^2, along +z of
    the Earth axes).

    **Returns:** `(vel_dot, omega_dot, euler_dot)`, each `(3,)`, from
    `m (vdot + omega x v) = F + m g_body` and
    `I omegadot + Idot omega + omega x (I omega) = M` (the rate of the inertia of a
    burning stage acts like the pitch plane's `Iyy_dot q`).
    """
    phi, theta, _ = euler
    g_body = g * jnp.stack(
        [-jnp.sin(theta), jnp.sin(phi) * jnp.cos(theta), jnp.cos(phi) * jnp.cos(theta)]
    )
    vel_dot = -jnp.cross(omega, vel) + force / mass + g_body
    torque = moment - inertia_dot @ omega - jnp.cross(omega, inertia @ omega)
    omega_dot = jnp.linalg.solve(inertia, torque)
    return vel_dot, omega_dot, euler_rates(omega, euler)


class LateralDerivatives(eqx.Module):
    """Side-force, rolling- and yawing-moment derivatives (per rad; the rate
    derivatives per unit of `p b / 2V`, `r b / 2V`)."""

    CY_beta: float = 0.0
    CY_p: float = 0.0
    CY_r: float = 0.0
    CY_da: float = 0.0
    CY_dr: float = 0.0
    Cl_beta: float = 0.0
    Cl_p: float = 0.0
    Cl_r: float = 0.0
    Cl_da: float = 0.0
    Cl_dr: float = 0.0
    Cn_beta: float = 0.0
    Cn_p: float = 0.0
    Cn_r: float = 0.0
    Cn_da: float = 0.0
    Cn_dr: float = 0.0


def lateral_coefficients(derivs: LateralDerivatives, beta, p, r, da, dr, speed, span):
    """`(CY, Cl, Cn)` at sideslip `beta` (rad), body rates `p, r` (rad/s), aileron
    `da` and rudder `dr` (rad), airspeed `speed` (m/s) and span `span` (m)."""
    ph, rh = p * span / (2 * speed), r * span / (2 * speed)
    d = derivs
    cy = d.CY_beta * beta + d.CY_p * ph + d.CY_r * rh + d.CY_da * da + d.CY_dr * dr
    cl = d.Cl_beta * beta + d.Cl_p * ph + d.Cl_r * rh + d.Cl_da * da + d.Cl_dr * dr
    cn = d.Cn_beta * beta + d.Cn_p * ph + d.Cn_r * rh + d.Cn_da * da + d.Cn_dr * dr
    return cy, cl, cn


class Aircraft(eqx.Module):
    """A rigid aircraft for 6-DOF simulation: mass properties, geometry, constant
    air density and linear aerodynamics.

    Longitudinal: `CL = CL0 + CLa alpha`, `CD = CD0 + CDa alpha`,
    `Cm = Cm0 + Cma alpha + Cmq q c / 2V + Cmde de`; lateral: [`LateralDerivatives`][].
    Thrust (N) acts along body x through the CG.
    """

    mass: float
    inertia: Float[Array, "3 3"]
    s_ref: float
    b_ref: float
    c_ref: float
    rho: float
    CL0: float
    CLa: float
    CD0: float
    CDa: float
    Cm0: float
    Cma: float
    Cmq: float
    Cmde: float
    lateral: LateralDerivatives


def business_jet() -> Aircraft:
    """An HFB-320-like business jet. Mass, wing area, chord, density and the
    longitudinal derivatives are the HFB-320 values of Jategaonkar's test case 4
    (speed terms folded in at 104.67 m/s, `Cmq` converted from `q c / V` to
    `q c / 2V`); span 14.45 m as published for the type. The roll and yaw inertias,
    the product of inertia and the lateral derivatives are NOT published values:
    plausible numbers for a small twin jet, chosen for a lightly damped Dutch roll
    (about 1.6 rad/s) and a roll mode of about 2 /s."""
    return Aircraft(
        mass=7472.0,
        inertia=inertia_tensor(35000.0, 45694.0, 75000.0, ixz=2000.0),
        s_ref=30.097,
        b_ref=14.45,
        c_ref=1.215,
        rho=0.792,
        CL0=-0.05795,
        CLa=5.37576,
        CD0=0.013401,
        CDa=0.674256,
        Cm0=0.06874,
        Cma=-0.498586,
        Cmq=-51.6878,
        Cmde=-0.990687,
        lateral=LateralDerivatives(
            CY_beta=-0.60,
            CY_p=0.0,
            CY_r=0.40,
            CY_da=0.0,
            CY_dr=0.15,
            Cl_beta=-0.08,
            Cl_p=-0.50,
            Cl_r=0.12,
            Cl_da=-0.10,
            Cl_dr=0.012,
            Cn_beta=0.10,
            Cn_p=-0.03,
            Cn_r=-0.16,
            Cn_da=-0.004,
            Cn_dr=-0.07,
        ),
    )


class Controls(eqx.Module):
    """Elevator, aileron, rudder (rad) and thrust (N) at one instant."""

    de: Float[Array, ""]
    da: Float[Array, ""]
    dr: Float[Array, ""]
    thrust: Float[Array, ""]


def sixdof_evaluate(y, controls: Controls, aircraft: Aircraft):
    """The state rate `(12,)` and the measured channels (dict of scalars: `u, v, w,
    p, q, r, phi, theta, psi, h, V, alpha, beta, ax, ay, az` (body specific forces,
    m/s^2), `pdot, qdot, rdot`, the controls and `true_CL, true_CD, true_Cm, true_CY,
    true_Cl, true_Cn`) at state `y` `(12,)`."""
    a = aircraft
    vel, omega, euler = y[0:3], y[3:6], y[6:9]
    u, v, w = vel
    p, q, r = omega
    speed = jnp.sqrt(u**2 + v**2 + w**2)
    alpha = jnp.arctan2(w, u)
    beta = jnp.arcsin(v / speed)
    qbar = 0.5 * a.rho * speed**2
    cl = a.CL0 + a.CLa * alpha
    cd = a.CD0 + a.CDa * alpha
    cm = (
        a.Cm0 + a.Cma * alpha + a.Cmq * q * a.c_ref / (2 * speed) + a.Cmde * controls.de
    )
    cy, cr, cn = lateral_coefficients(
        a.lateral, beta, p, r, controls.da, controls.dr, speed, a.b_ref
    )
    cx, cz = wind_body(cl, cd, alpha)
    force = qbar * a.s_ref * jnp.stack([cx, cy, cz]) + jnp.stack(
        [controls.thrust, 0.0, 0.0]
    )
    moment = qbar * a.s_ref * jnp.stack([a.b_ref * cr, a.c_ref * cm, a.b_ref * cn])
    vel_dot, omega_dot, euler_dot = rigid_body_rates(
        vel, omega, euler, force, moment, a.mass, a.inertia, jnp.zeros((3, 3)), G
    )
    ned_dot = body_to_earth(euler) @ vel
    rates = jnp.concatenate([vel_dot, omega_dot, euler_dot, ned_dot[:2], -ned_dot[2:]])
    specific = force / a.mass
    channels = {
        "u": u, "v": v, "w": w, "p": p, "q": q, "r": r,
        "phi": euler[0], "theta": euler[1], "psi": euler[2], "h": y[11],
        "V": speed, "alpha": alpha, "beta": beta,
        "ax": specific[0], "ay": specific[1], "az": specific[2],
        "pdot": omega_dot[0], "qdot": omega_dot[1], "rdot": omega_dot[2],
        "de": controls.de, "da": controls.da, "dr": controls.dr,
        "thrust": controls.thrust,
        "true_CL": cl, "true_CD": cd, "true_Cm": cm,
        "true_CY": cy, "true_Cl": cr, "true_Cn": cn,
    }  # fmt: skip
    return rates, channels


def sixdof_rates(y, controls: Controls, aircraft: Aircraft) -> Float[Array, "12"]:
    """The state rate `(12,)` (see [`sixdof_evaluate`][])."""
    return sixdof_evaluate(y, controls, aircraft)[0]


class Trim(eqx.Module):
    """A wings-level steady flight: the state `y` `(12,)`, elevator `de` (rad) and
    thrust (N)."""

    y: Float[Array, "12"]
    de: Float[Array, ""]
    thrust: Float[Array, ""]


def _trim_state(z, speed, altitude):
    alpha = z[0]
    y = jnp.zeros(12)
    y = y.at[0].set(speed * jnp.cos(alpha)).at[2].set(speed * jnp.sin(alpha))
    return y.at[7].set(alpha).at[11].set(altitude)


@jax.jit
def _trim(aircraft, speed, altitude):
    # one compiled program for every aircraft of one structure, speed and altitude
    # (a jitted closure was traced and compiled again on every call)
    def residual(z):
        c = Controls(de=z[1], da=jnp.zeros(()), dr=jnp.zeros(()), thrust=z[2])
        rates = sixdof_rates(_trim_state(z, speed, altitude), c, aircraft)
        return jnp.stack([rates[0], rates[2], rates[4]])

    def newton(_, z):
        return z - jnp.linalg.solve(jax.jacfwd(residual)(z), residual(z))

    z = jnp.stack([jnp.array(0.1), jnp.array(0.0), 0.1 * aircraft.mass * G])
    z = jax.lax.fori_loop(0, 20, newton, z)
    return Trim(y=_trim_state(z, speed, altitude), de=z[1], thrust=z[2])


def trim(aircraft: Aircraft, speed: float, altitude: float = 1000.0) -> Trim:
    """Level, wings-level, unaccelerated flight at `speed` (m/s): Newton on
    `udot = wdot = qdot = 0` over angle of attack (= pitch attitude), elevator and
    thrust (converges in a few iterations: the equations are nearly linear)."""
    return _trim(aircraft, jnp.asarray(speed, float), jnp.asarray(altitude, float))


@eqx.filter_jit
def _simulate(aircraft, start, aileron, rudder, elevator, dt, n):
    ts = dt * jnp.arange(n)

    def controls(t):
        return Controls(
            de=start.de + elevator(t),
            da=aileron(t),
            dr=rudder(t),
            thrust=start.thrust,
        )

    def field(t, y):
        return sixdof_rates(y, controls(t), aircraft)

    ys = rk4_scan(field, start.y, ts, dt)
    out = jax.vmap(lambda t, y: sixdof_evaluate(y, controls(t), aircraft)[1])(ts, ys)
    return {**out, "t": ts}


def simulate_sixdof(
    aircraft: Aircraft,
    start: Trim,
    *,
    aileron: AbstractInput = _NONE,
    rudder: AbstractInput = _NONE,
    elevator: AbstractInput = _NONE,
    t_final: float = 20.0,
    dt: float = 0.02,
) -> dict[str, np.ndarray]:
    """A 6-DOF flight from the trim `start` with aileron, rudder and elevator
    schedules added to the trim controls (rad; e.g. `doublet(...)`).

    Classical RK4 at the sample step `dt` (s) with the inputs evaluated at the
    stage times. **Returns:** channels of [`sixdof_evaluate`][] at the samples plus
    `t`, each `(samples,)`; `da, dr, de` are the deflections applied.
    """
    n = int(round(t_final / dt)) + 1
    out = _simulate(aircraft, start, aileron, rudder, elevator, dt, n)
    return {k: np.asarray(v) for k, v in out.items()}


def linearise(aircraft: Aircraft, start: Trim):
    """The Jacobian `(12, 12)` of [`sixdof_rates`][] at the trim state and the
    control Jacobian `(12, 2)` for `(da, dr)` (per rad)."""

    def f(y, ctl):
        c = Controls(de=start.de, da=ctl[0], dr=ctl[1], thrust=start.thrust)
        return sixdof_rates(y, c, aircraft)

    # one compiled program (operation by operation the two Jacobians took ~140
    # small compilations)
    @jax.jit
    def both(y, ctl):
        return jax.jacfwd(f, 0)(y, ctl), jax.jacfwd(f, 1)(y, ctl)

    return both(start.y, jnp.zeros(2))
