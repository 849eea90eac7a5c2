"""The one pitch-plane flight model: from the state and what is known about the
vehicle at an instant, the body accelerations, the flight condition and the measured
channels, with every effect of the library plugged in through its hooks.

The simulator (`_dynamics.evaluate`) and every [`FlightVehicle`][] (the HFB-320,
the launch vehicle's diagnosis model, a user's vehicle file) call
[`pitch_plane`][]; they
differ only in where the aerodynamic coefficients, the atmosphere and the mass
properties come from (a database, a spline fitted to a log, a published model).

Body axes x to the nose, z down; `u, w` inertial body velocities (m/s), `q` pitch
rate (rad/s), `theta` pitch attitude (rad), `h` altitude (m).
"""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp

from .._custom_types import Scalar, ScalarLike
from ._effects import AbstractEffect, FlightCondition
from ._pegasus._aerodynamics import body_axis


def pitch_plane_rates(
    u: ScalarLike,
    w: ScalarLike,
    q: ScalarLike,
    theta: ScalarLike,
    fx: ScalarLike,
    fz: ScalarLike,
    moment: ScalarLike,
    mass: ScalarLike,
    iyy: ScalarLike,
    iyy_dot: ScalarLike,
    g: ScalarLike,
) -> tuple[Scalar, Scalar, Scalar]:
    """Body-axis accelerations of a rigid body with varying mass and inertia.

    **Arguments:** body velocities `u, w` (m/s), pitch rate `q` (rad/s), pitch
    attitude `theta` (rad), non-gravitational body forces `fx, fz` (N), pitching
    moment about the CG (N m), mass (kg), `iyy` and `iyy_dot` (kg m^2, kg m^2/s),
    gravity `g` (m/s^2, along inertial +z).

    **Returns:** `(udot, wdot, qdot)`, from `m (udot + q w) = fx - m g sin(theta)`,
    `m (wdot - q u) = fz + m g cos(theta)` and `M = Iyy qdot + Iyy_dot q`.
    """
    udot = -q * w + fx / mass - g * jnp.sin(theta)
    wdot = q * u + fz / mass + g * jnp.cos(theta)
    qdot = (moment - iyy_dot * q) / iyy
    return udot, wdot, qdot


def moment_about_cg(
    qbar: ScalarLike,
    s_ref: float,
    c_ref: float,
    cm: ScalarLike,
    fz_aero: ScalarLike,
    xcg: ScalarLike,
    xcp: ScalarLike,
) -> Scalar:
    """Aerodynamic pitching moment about the CG, N m.

    `cm` is the moment coefficient about the cp station; the aerodynamic z force
    `fz_aero` (N) acts at the cp. Stations from the nose, positive aft (m), so a cp
    aft of the CG turns a negative (upward) `fz_aero` into a nose-down moment.
    """
    return qbar * s_ref * c_ref * cm + (xcp - xcg) * fz_aero


class PitchPlane(eqx.Module):
    """The flight model evaluated at one instant.

    **Fields:** `udot, wdot` (m/s^2), `qdot` (rad/s^2), `hdot` (m/s, climb rate);
    `condition` the [`FlightCondition`][] (with `alpha_dot` and `qdot`); `cl, cd,
    cm` the total coefficients (effects included; `cm` about the cp); `fx, fz` the
    non-gravitational body forces (N); `channels` the noise-free measured channels
    by flight-log name (`ax, az, q, qdot, alpha, V, theta, h, mach, qbar, thrust,
    mass, xcg, xcp`), after the effects' sensor hooks.
    """

    udot: Scalar
    wdot: Scalar
    qdot: Scalar
    hdot: Scalar
    condition: FlightCondition
    cl: Scalar
    cd: Scalar
    cm: Scalar
    fx: Scalar
    fz: Scalar
    channels: dict


def elevator_delay(effects: tuple[AbstractEffect, ...]) -> ScalarLike:
    """The total elevator delay of the effects' `elevator_delay` hooks, s."""
    return sum((e.elevator_delay() for e in effects), 0.0)


def has_delay(effects: tuple[AbstractEffect, ...]) -> bool:
    """Whether any effect implements the `elevator_delay` hook."""
    return any(
        type(e).elevator_delay is not AbstractEffect.elevator_delay for e in effects
    )


def pitch_plane(
    t: ScalarLike,
    u: ScalarLike,
    w: ScalarLike,
    q: ScalarLike,
    theta: ScalarLike,
    h: ScalarLike,
    *,
    de: ScalarLike,
    aero: Callable[[FlightCondition], tuple[Scalar, Scalar, Scalar]],
    effects: tuple[AbstractEffect, ...],
    s_ref: float,
    c_ref: float,
    density: ScalarLike,
    speed_of_sound: ScalarLike,
    g: ScalarLike,
    thrust: ScalarLike,
    mass: ScalarLike,
    iyy: ScalarLike,
    iyy_dot: ScalarLike,
    xcg: ScalarLike,
    xcp: ScalarLike | Callable[[Scalar], Scalar],
    thrust_angle: ScalarLike = 0.0,
    thrust_moment: ScalarLike = 0.0,
    recorded: dict | None = None,
) -> PitchPlane:
    """Accelerations, condition and measured channels of a rigid vehicle in the
    pitch plane.

    **Arguments:**

    - `t` (s); the state `u, w` (m/s), `q` (rad/s), `theta` (rad), `h` (m).
    - `de`: elevator deflection acting on the vehicle (rad; already delayed by any
      actuator delay, see [`elevator_delay`][]).
    - `aero`: the vehicle's aerodynamic model, `condition -> (CL, CD, CM)` with CM
      about the cp station; it must not use `condition.alpha_dot` or `.qdot`.
    - `effects`: library effects, called through their hooks.
    - `s_ref` (m^2), `c_ref` (m); `density` (kg/m^3), `speed_of_sound` (m/s) and
      `g` (m/s^2) at the vehicle.
    - `thrust` (N), inclined `thrust_angle` (rad, nose-up positive) from body x;
      `thrust_moment` (N m) its moment about the CG.
    - `recorded`: other channels the log records (e.g. the elevator command), put
      beside the computed ones before the effects' sensor hooks see them.
    - `mass` (kg), `iyy` (kg m^2), `iyy_dot` (kg m^2/s), `xcg` (m from the nose);
      `xcp` (m from the nose) or a function of Mach giving it.

    **Returns:** a [`PitchPlane`][].
    """

    def air_relative(t_, theta_):
        wind = [e.wind(t_, theta_) for e in effects]
        return u - sum((v[0] for v in wind), 0.0), w - sum((v[1] for v in wind), 0.0)

    t = jnp.asarray(t, float)
    ua, wa = air_relative(t, theta)
    airspeed = jnp.sqrt(ua**2 + wa**2)
    alpha = jnp.arctan2(wa, ua)
    mach = airspeed / speed_of_sound
    qbar = 0.5 * density * airspeed**2
    zero = jnp.zeros(())
    cond = FlightCondition(
        t=t,
        alpha=alpha,
        alpha_dot=zero,
        airspeed=airspeed,
        mach=mach,
        qbar=qbar,
        q=q,
        qdot=zero,
        theta=theta,
        h=h,
        de=de,
        thrust=thrust,
        c_ref=c_ref,
        s_ref=s_ref,
        mass=mass,
        xcg=xcg,
    )
    cl, cd, cm = aero(cond)
    for e in effects:
        dcl, dcd = e.force_coefficients(cond)
        cl, cd = cl + dcl, cd + dcd
    cx, cz = body_axis(cl, cd, alpha)
    fz_aero = qbar * s_ref * cz
    fx = qbar * s_ref * cx + thrust * jnp.cos(thrust_angle)
    fz = fz_aero - thrust * jnp.sin(thrust_angle)
    udot, wdot, _ = pitch_plane_rates(
        u, w, q, theta, fx, fz, 0.0, mass, iyy, iyy_dot, g
    )
    # u, w are constants inside air_relative: its tangent along (1, q) is minus the
    # rate of change of the wind seen by the body (gust in time, turning with theta)
    _, (dua, dwa) = jax.jvp(
        air_relative,
        (t, jnp.asarray(theta, float)),
        (jnp.ones(()), jnp.asarray(q, float)),
    )
    alpha_dot = (ua * (wdot + dwa) - wa * (udot + dua)) / airspeed**2
    cond = eqx.tree_at(lambda c: c.alpha_dot, cond, alpha_dot)
    extra = zero + thrust_moment
    for e in effects:
        cm = cm + e.moment_coefficient(cond)
        extra = extra + e.moment(cond)
    xcp = xcp(mach) if callable(xcp) else xcp
    moment = moment_about_cg(qbar, s_ref, c_ref, cm, fz_aero, xcg, xcp) + extra
    _, _, qdot = pitch_plane_rates(
        u, w, q, theta, fx, fz, moment, mass, iyy, iyy_dot, g
    )
    cond = eqx.tree_at(lambda c: c.qdot, cond, qdot)
    channels = {
        "ax": fx / mass,
        "az": fz / mass,
        "q": q,
        "qdot": qdot,
        "alpha": alpha,
        "V": airspeed,
        "theta": theta,
        "h": h,
        "mach": mach,
        "qbar": qbar,
        "thrust": thrust,
        "mass": mass,
        "xcg": xcg,
        "xcp": xcp,
        **(recorded or {}),
    }
    for e in effects:
        channels = e.measure(channels, cond)
    return PitchPlane(
        udot=udot,
        wdot=wdot,
        qdot=qdot,
        hdot=u * jnp.sin(theta) - w * jnp.cos(theta),
        condition=cond,
        cl=cl,
        cd=cd,
        cm=cm,
        fx=fx,
        fz=fz,
        channels=channels,
    )
