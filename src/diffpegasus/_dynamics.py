"""Pitch-plane rigid-body dynamics of a vehicle with varying mass.

Flat, non-rotating Earth frame fixed at the drop point (x along the initial track,
z down); body axes x to the nose, z down. The state is `y = [u, w, q, theta, x, h]`
(body velocities m/s, pitch rate rad/s, pitch attitude rad, downrange m, altitude m).
The building blocks (`pitch_plane_rates`, `moment_about_cg`) are what the estimators'
models call too, so the simulator and the estimators share one set of equations.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._aerodynamics import AeroDerivatives, body_axis, coefficients
from ._atmosphere import dynamic_pressure, isa
from ._custom_types import Scalar, ScalarLike
from ._effects import AbstractEffect, FlightCondition
from ._gravity import gravity
from ._inputs import AbstractInput
from ._vehicle import Vehicle


STATE_NAMES = ("u", "w", "q", "theta", "x", "h")


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


class FlightModel(eqx.Module):
    """Vehicle, elevator command and planted effects: everything the dynamics need."""

    vehicle: Vehicle
    elevator: AbstractInput
    effects: tuple[AbstractEffect, ...] = ()


class Evaluation(eqx.Module):
    """The dynamics evaluated at one instant: state rate and every flight quantity."""

    rates: Float[Array, "6"]
    condition: FlightCondition
    derivatives: AeroDerivatives
    channels: dict[str, Scalar]


def evaluate(t: ScalarLike, y: Float[Array, "6"], model: FlightModel) -> Evaluation:
    """The state rate and the noise-free measured channels at `(t, y)`.

    Channels follow the flight-log names (`ax`, `az`, `q`, `qdot`, `alpha`, `V`,
    `theta`, `h`, `mach`, `qbar`, `thrust`, `mass`, `Iyy`, `Iyy_dot`, `xcg`, `xcp`,
    `de`), plus `true_CL`, `true_CD`, `true_CM` (total coefficients, effects included),
    `u`, `w`, `x`, `gamma`. `de` is the recorded command; an actuator delay acts on
    the surface, not on the record.
    """
    vehicle, effects = model.vehicle, model.effects
    u, w, q, theta, _, h = y
    delay = sum((e.elevator_delay() for e in effects), 0.0)
    de_command = model.elevator(t)
    de = model.elevator(t - delay)

    def air_relative(t_, theta_):
        wind = [e.wind(t_, theta_) for e in effects]
        return u - sum((v[0] for v in wind), 0.0), w - sum((v[1] for v in wind), 0.0)

    (ua, wa) = air_relative(t, theta)
    airspeed = jnp.sqrt(ua**2 + wa**2)
    alpha = jnp.arctan2(wa, ua)
    atm = isa(h)
    g = gravity(h)
    mach = airspeed / atm.speed_of_sound
    qbar = dynamic_pressure(atm.density, airspeed)
    props = vehicle.mass.at(t, vehicle.motor)
    thrust = vehicle.motor.net_thrust(t, atm.pressure)
    xcp = vehicle.xcp(mach)
    derivs = vehicle.aero.derivatives(alpha, mach)
    base = coefficients(derivs, alpha, de)
    zero = jnp.zeros(())
    cond = FlightCondition(
        t=jnp.asarray(t, float),
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
        c_ref=vehicle.c_ref,
        s_ref=vehicle.s_ref,
        mass=props.mass,
        xcg=props.xcg,
    )
    cl, cd = base.CL, base.CD
    for e in effects:
        dcl, dcd = e.force_coefficients(cond)
        cl, cd = cl + dcl, cd + dcd
    cx, cz = body_axis(cl, cd, alpha)
    fx_aero = qbar * vehicle.s_ref * cx
    fz_aero = qbar * vehicle.s_ref * cz
    fx, fz = fx_aero + thrust, fz_aero
    # The moment does not enter udot, wdot: get them first, then alpha_dot.
    udot, wdot, _ = pitch_plane_rates(
        u, w, q, theta, fx, fz, 0.0, props.mass, props.Iyy, props.Iyy_dot, g
    )
    # u, w are constants inside air_relative, so its tangent is minus the wind rate.
    _, (minus_wind_u_rate, minus_wind_w_rate) = jax.jvp(
        air_relative, (jnp.asarray(t, float), theta), (jnp.ones(()), q)
    )
    ua_dot = udot + minus_wind_u_rate
    wa_dot = wdot + minus_wind_w_rate
    alpha_dot = (ua * wa_dot - wa * ua_dot) / airspeed**2
    cond = eqx.tree_at(lambda c: c.alpha_dot, cond, alpha_dot)
    cm = base.CM
    extra_moment = zero
    for e in effects:
        cm = cm + e.moment_coefficient(cond)
        extra_moment = extra_moment + e.moment(cond)
    moment = (
        moment_about_cg(qbar, vehicle.s_ref, vehicle.c_ref, cm, fz_aero, props.xcg, xcp)
        + extra_moment
    )
    _, _, qdot = pitch_plane_rates(
        u, w, q, theta, fx, fz, moment, props.mass, props.Iyy, props.Iyy_dot, g
    )
    cond = eqx.tree_at(lambda c: c.qdot, cond, qdot)
    xdot = u * jnp.cos(theta) + w * jnp.sin(theta)
    hdot = u * jnp.sin(theta) - w * jnp.cos(theta)
    rates = jnp.stack([udot, wdot, qdot, q, xdot, hdot])
    channels = {
        "de": de_command,
        "ax": fx / props.mass,
        "az": fz / props.mass,
        "q": q,
        "qdot": qdot,
        "alpha": alpha,
        "V": airspeed,
        "theta": theta,
        "h": h,
        "mach": mach,
        "qbar": qbar,
        "thrust": thrust,
        "mass": props.mass,
        "Iyy": props.Iyy,
        "Iyy_dot": props.Iyy_dot,
        "xcg": props.xcg,
        "xcp": xcp,
        "true_CL": cl,
        "true_CD": cd,
        "true_CM": cm,
        "u": u,
        "w": w,
        "x": y[4],
        "gamma": jnp.arctan2(hdot, xdot),
    }
    for e in effects:
        channels = e.measure(channels, cond)
    return Evaluation(
        rates=rates, condition=cond, derivatives=derivs, channels=channels
    )
