"""The rocket as a [`Model`][]: a point mass flying along its air-relative velocity.

States (east-north-up, pad origin): position `e, n, u` (m) and velocity
`ve, vn, vu` (m/s). On the rail the rocket moves along it (held until the hold-down
releases and thrust exceeds weight along the rail). Off the rail:

- without an airframe in the rocket file, it points into the relative wind (zero
  angle of attack), so thrust acts along the air-relative velocity and drag
  against it;
- with one ([`Airframe`][]: Barrowman's normal-force slopes and centres of pressure,
  the mass distribution), it weathercocks: six more states, the body axis `ax_e,
  ax_n, ax_u` (unit vector, east-north-up) and the angular velocity `w_e, w_n, w_u`
  (rad/s, across the axis; no roll). Thrust acts along the body axis, drag
  (`q S CD`) against it, and each surface a normal force `-1/2 rho V S CN_alpha
  v_perp` at its centre of pressure, `v_perp` the part across the axis of the air
  velocity at that station (the rotation included: the pitch damping); their
  moment about the centre of mass over the lateral inertia (both with the
  propellant burned) turns the axis.

Parameters (name: unit, meaning):

- `cd_0`...: drag coefficient at each knot Mach number, power off.
- `cd_scale`: factor on the whole curve (1 when the knots are estimated).
- `power_on_ratio`: CD power on / power off.
- `thrust_scale`: delivered / catalogue impulse (the thrust's factor at the
  catalogue's burn time).
- `motor_time`: s, log time of the thrust curve's zero.
- `burn_scale`: burn time / catalogue burn time (1 the catalogue's): the curve
  stretched in time and divided by it, so the impulse stays `thrust_scale`'s and
  the propellant burns along the stretched curve (a solid motor's grain
  temperature: cold burns longer and weaker, hot shorter and harder).
- `temperature`: K at the pad; `lapse_rate`: K/km, its fall with geopotential
  height (-6.5 the standard atmosphere's). Together they set density, speed of sound and what the
  barometer reads (it converts pressure with the standard atmosphere).
- `wind_east`, `wind_north`: m/s, a constant wind; `wind_along`: m/s, blowing
  towards the rail's heading (a tail wind; the part a flight at zero angle of attack
  shows to first order: a cross wind moves altitude and axial acceleration only to
  second order, so its derivative at zero wind is zero; the GNSS position drifts
  with either component at first order).
- `baro_lag`: s; `static_error`: static-pressure error per dynamic pressure;
  `transonic_error`: its extra part at Mach 1.
- `mass_offset`: kg added to the dry mass.
- `rail_friction`: coefficient of friction on the rail.
- `airbrake_cd`: CD added at full air-brake deployment (input `airbrake`).
- `altitude_bias` (m), `accel_bias` (m/s^2): sensor offsets; `accel_scale`: the
  accelerometer's reading per m/s^2 of specific force (1 when calibrated).
- `cn_alpha_scale`: factor on every surface's `CN_alpha` (Barrowman's) for the
  force of the air's angle of attack (the centre of pressure kept);
  `pitch_damping_scale`: factor on the force the rotation adds (the pitch damping
  `Cmq` Barrowman's slopes give, `-sum CN_alpha_i (x_i - x_cg)^2 / d^2` per
  radian of `q d / V`, scaled alone). Both 1 by default; with the attitude only
  (without an airframe nothing depends on them).

With a [`Descent`][] (the record past apogee), from the first deployment the
rocket falls under each parachute stage's drag area (parameters `cds_drogue`,
`cds_main`, m^2, each from its opening time `open_drogue`, `open_main` s after
its event; see `_descent`), the attitude frozen.

Outputs: `altitude` (m), `accel` (m/s^2), with the attitude `gyro`: the
lateral body rate `sqrt(w_pitch^2 + w_yaw^2)` (rad/s; what two gyros across the
axis read whatever the roll), and `gnss_e`, `gnss_n` (m): the GNSS receiver's
horizontal position, east and north of the pad (the states `e`, `n`; where the
log has a fix). A cross wind drifts them at first order.
"""

import functools

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._errors import LogError
from ..._model import Model
from .._atmosphere import GAMMA_AIR, R_AIR
from .._gravity import coriolis, gravity, normal_gravity
from ._config import Rocket
from ._descent import Descent, parachute_acceleration
from ._drag import DragKnots
from ._motor import motor_at
from ._sensors import axial_specific_force, baro_altitude, layered_air


STATES = ("e", "n", "u", "ve", "vn", "vu")
ATTITUDE = ("ax_e", "ax_n", "ax_u", "w_e", "w_n", "w_u")
# the channels a log may give, in this order
OUTPUTS = ("altitude", "accel", "gyro", "gnss_e", "gnss_n")
EFFECTS = (
    "cd_scale",
    "power_on_ratio",
    "thrust_scale",
    "motor_time",
    "burn_scale",
    "temperature",
    "lapse_rate",
    "wind_east",
    "wind_north",
    "wind_along",
    "baro_lag",
    "static_error",
    "transonic_error",
    "mass_offset",
    "rail_friction",
    "airbrake_cd",
    "altitude_bias",
    "accel_bias",
    "accel_scale",
    "cn_alpha_scale",
    "pitch_damping_scale",
)
# The effects positive by their meaning, and what each is. At 0 or below the model
# is no rocket: a burn stretched by 0 divides the thrust by zero (NaN), a pad at
# 0 K has no speed of sound, a thrust, drag or reading scale of 0 or less turns its
# force or channel off or round. No start may be there (`unphysical`) and no
# fit may step there (`physical` in `observe`: the step is rejected and damped).
POSITIVE = {
    "burn_scale": "the burn time over the catalogue's",
    "thrust_scale": "the impulse over the catalogue's",
    "cd_scale": "the drag curve's factor",
    "power_on_ratio": "CD power on over power off",
    "accel_scale": "the accelerometer's reading per m/s^2",
    "temperature": "the pad's temperature (K)",
}
# The parachutes' opening times after their events (with a descent), 0 or above: a
# canopy full at its event is physical (it opens at once), one full before its
# event fired is not: the ramp is cut at the event, so below 0 the opening moves
# only what is left of the ramp, and below -FILL/2 nothing (the canopy full at its
# event, the cost flat in it). No start below 0 and no step there, as the
# `POSITIVE` effects.
NONNEGATIVE = {
    "open_drogue": "the drogue's opening time after its event (s)",
    "open_main": "the main's opening time after its event (s)",
}


class Flight(eqx.Module):
    """What the dynamics need besides the parameters: the rocket and the day.

    **Fields:** `rocket`, `knots` ([`DragKnots`][]), `pad_pressure` (Pa),
    `descent` (a [`Descent`][]: the parachutes' deployment times, or `None`: the
    ascent alone).
    """

    rocket: Rocket
    knots: DragKnots
    pad_pressure: float = eqx.field(static=True)
    descent: Descent | None = None

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """The model's parameters: the drag knots, the effects and the
        parachutes' drag areas (with a descent)."""
        d = self.descent
        chutes = () if d is None else d.names + d.openings
        return self.knots.names + EFFECTS + chutes

    def rail_axis(self):
        r = self.rocket
        inc, head = np.radians(r.inclination), np.radians(r.heading)
        return np.array(
            [np.cos(inc) * np.sin(head), np.cos(inc) * np.cos(head), np.sin(inc)]
        )

    def air(self, height, p):
        """Density (kg/m^3), speed of sound (m/s), the barometer's reading (m above
        the pad) and its rate per metre of height, at `height` m above the pad."""
        pressure, temperature, reading, rate = layered_air(
            self.pad_pressure,
            p["temperature"],
            p["lapse_rate"],
            height,
            elevation=self.rocket.elevation,
        )
        return (
            pressure / (R_AIR * temperature),
            jnp.sqrt(GAMMA_AIR * R_AIR * temperature),
            reading,
            rate,
        )

    def gravity(self, height):
        """m/s^2 at `height` m above the pad: normal gravity at the pad's latitude
        where the rocket file gives one, else standard gravity."""
        h = self.rocket.elevation + height
        if self.rocket.latitude is None:
            return gravity(h)
        return normal_gravity(h, self.rocket.latitude)

    @property
    def states(self) -> tuple:
        """The state names: position and velocity, and the attitude's with an
        airframe."""
        return STATES + (ATTITUDE if self.rocket.airframe is not None else ())

    def initial_state(self) -> np.ndarray:
        """At rest at the pad, pointing along the rail."""
        x = np.zeros(len(self.states))
        if self.rocket.airframe is not None:
            x[6:9] = self.rail_axis()
        return x

    def attitude(self, x, air, rho, speed, mach, thrust_on, burned, p):
        """`(axis, normal force (3,) N, angular acceleration (3,) rad/s^2)` of the
        weathercocking body (see the module) at air velocity `air` `(3,)` m/s."""
        frame = self.rocket.airframe
        r = self.rocket
        axis = x[6:9] / jnp.linalg.norm(x[6:9])
        w = x[9:12]
        rocket_mass = r.dry_mass - r.motor.dry_mass + p["mass_offset"]
        motor_mass = r.motor.dry_mass + r.motor.propellant_mass * (1 - burned)
        mass = rocket_mass + motor_mass
        cg = (rocket_mass * frame.cg_rocket + motor_mass * frame.motor_cg) / mass
        inertia = (
            frame.inertia
            + rocket_mass * (frame.cg_rocket - cg) ** 2
            + frame.motor_inertia
            + motor_mass * (frame.motor_cg - cg) ** 2
        )
        arm = jnp.asarray(frame.stations) - cg  # (k,) m forward of the CG
        cna = frame.cn_alpha(mach)
        turn = jnp.cross(w[None, :], arm[:, None] * axis[None, :])
        local = p["cn_alpha_scale"] * air[None, :] + p["pitch_damping_scale"] * turn
        perp = local - (local @ axis)[:, None] * axis[None, :]
        each = -0.5 * rho * speed * r.area * cna[:, None] * perp  # (k, 3) N
        moment = jnp.sum(jnp.cross(arm[:, None] * axis[None, :], each), axis=0)
        return axis, jnp.sum(each, axis=0), moment / inertia

    def forces(self, t, x, u, p):
        """Acceleration `(3,)` m/s^2, body axis `(3,)`, and the air data (with
        the attitude's angular acceleration last, zeros without an airframe)."""
        r = self.rocket
        pos, vel = x[:3], x[3:6]
        tables = tuple(jnp.asarray(a) for a in r.motor.tables())
        tm = t - p["motor_time"]
        thrust, burned = motor_at(tables, tm, p["burn_scale"])
        thrust = p["thrust_scale"] * thrust
        mass = r.dry_mass + p["mass_offset"] + r.motor.propellant_mass * (1 - burned)
        rho, sound, reading, rate = self.air(pos[2], p)
        head = np.radians(r.heading)
        wind = jnp.stack(
            [
                p["wind_east"] + p["wind_along"] * np.sin(head),
                p["wind_north"] + p["wind_along"] * np.cos(head),
                0.0,
            ]
        )
        air = vel - wind
        speed = jnp.sqrt(jnp.sum(air**2) + 1e-6)
        rail = jnp.asarray(self.rail_axis())
        along = jnp.dot(pos, rail)
        on_rail = along < r.rail_length
        mach = speed / sound
        q = 0.5 * rho * speed**2
        cd = self.knots(mach, jnp.stack([p[k] for k in self.knots.names]))
        cd = p["cd_scale"] * cd * jnp.where(thrust > 0, p["power_on_ratio"], 1.0)
        cd = cd + p["airbrake_cd"] * u[0]
        drag = q * r.area * cd
        g = self.gravity(pos[2])
        gvec = jnp.stack([0.0, 0.0, -g])
        if r.airframe is None:
            axis = jnp.where(on_rail, rail, air / speed)
            free = (thrust - drag) / mass * axis + gvec
            spin = jnp.zeros(0)
        else:
            body, normal, spin = self.attitude(
                x, air, rho, speed, mach, thrust > 0, burned, p
            )
            axis = jnp.where(on_rail, rail, body)
            free = ((thrust - drag) * body + normal) / mass + gvec
            spin = jnp.where(on_rail, 0.0, spin)
        if r.latitude is not None:  # the pad's frame turns with the Earth
            free = free + coriolis(vel, r.latitude)
        # on the rail: the component along it, less friction, never backwards from rest
        v_along = jnp.dot(vel, rail)
        normal = g * jnp.sqrt(jnp.clip(1 - rail[2] ** 2, 0.0, None))
        a_along = (thrust - drag * jnp.sign(v_along + 1e-9)) / mass - g * rail[2]
        a_along = a_along - p["rail_friction"] * normal
        held = (tm < r.holddown) | ((v_along <= 1e-6) & (a_along < 0))
        a_along = jnp.where(held, 0.0, a_along)
        accel = jnp.where(on_rail, a_along * rail, free)
        if self.descent is not None:
            chute = parachute_acceleration(
                vel, wind, rho, g, mass, self.descent.drag_area(t, p)
            )
            if r.latitude is not None:
                chute = chute + coriolis(vel, r.latitude)
            # before the drogue's canopy is full the rocket flies as before
            full = self.descent.opened(0, t, p)
            accel = jnp.where(full >= 1.0, chute, accel + full * (chute - accel))
            spin = jnp.where(full > 0.0, 0.0, spin)
        return accel, axis, (q, rho, g, mach, reading, rate, spin)


def airframe_mass(rocket: Rocket, mass_offset):
    """kg, the rocket without its motor (casing and propellant): the rocket file's
    dry mass less the motor's casing, plus `mass_offset`."""
    return rocket.dry_mass - rocket.motor.dry_mass + mass_offset


def _openings(flight: Flight) -> tuple[str, ...]:
    """The `NONNEGATIVE` parameters `flight` has: its parachutes' opening times."""
    return () if flight.descent is None else flight.descent.openings


def physical(flight: Flight, p):
    """Whether the parameters `p` (name -> value) describe a rocket (traced bool):
    every `POSITIVE` effect above 0, every parachute's opening time (with a
    descent; `NONNEGATIVE`) 0 or above and the rocket without its motor heavier
    than 0 kg."""
    ok = [jnp.asarray(p[k]) > 0 for k in POSITIVE]
    ok += [jnp.asarray(p[k]) >= 0 for k in _openings(flight)]
    ok = jnp.all(jnp.stack(ok))
    return ok & (airframe_mass(flight.rocket, p["mass_offset"]) > 0)


def unphysical(flight: Flight, values: dict) -> str:
    """One line saying which of `values` (name -> number) is no rocket's, and
    why (`physical`'s rule); "" when all are."""
    for k, meaning in POSITIVE.items():
        if not values[k] > 0:  # NaN too
            return f"{k} = {values[k]:g}: {meaning} must be above 0"
    for k in _openings(flight):
        if not values[k] >= 0:  # NaN too
            return f"{k} = {values[k]:g}: {NONNEGATIVE[k]} must be 0 or above"
    mass = airframe_mass(flight.rocket, values["mass_offset"])
    if not mass > 0:
        return (
            f"mass_offset = {values['mass_offset']:g} kg leaves the rocket without its "
            f"motor at {mass:g} kg: it must be above "
            f"{-airframe_mass(flight.rocket, 0.0):g} kg"
        )
    return ""


def rates(flight: Flight, t, x, u, p):
    """`dx/dt` `(6,)`: velocity and acceleration; `(12,)` with the attitude: the
    axis turning at the angular velocity, and the angular acceleration."""
    accel, _, (*_, spin) = flight.forces(t, x, u, p)
    if flight.rocket.airframe is None:
        return jnp.concatenate([x[3:], accel])
    return jnp.concatenate([x[3:6], accel, jnp.cross(x[9:12], x[6:9]), spin])


def observe(flight: Flight, t, x, u, p, which=None):
    """The measured channels: barometric altitude (m AGL), axial specific force
    (m/s^2), with the attitude the lateral body rate (rad/s) (0 without), and the
    GNSS position east and north of the pad (m), those at the indices `which`
    into `OUTPUTS` (default the first `u.shape[0] - 1`), each multiplied by its
    `has_` input (0 where the log has no sample)."""
    accel, axis, (q, rho, g, mach, reading, rate, _) = flight.forces(t, x, u, p)
    h = baro_altitude(
        reading,
        x[5],
        rate,
        p["baro_lag"],
        p["static_error"],
        p["transonic_error"],
        q,
        rho,
        g,
        mach,
    )
    f = axial_specific_force(accel, g, axis)
    gyro = jnp.sqrt(jnp.sum(x[9:12] ** 2) + 1e-12) if x.shape[0] > 6 else 0.0
    which = tuple(range(u.shape[0] - 1)) if which is None else tuple(which)
    y = [h + p["altitude_bias"], p["accel_scale"] * f + p["accel_bias"], gyro]
    if max(which) > 2:  # the GNSS position: the states east and north
        y += [x[0], x[1]]
    y = jnp.stack(y)
    # no rocket, no reading: a fit's step there has a NaN cost, which the engine
    # rejects as it does any step that does not lower the cost
    y = jnp.where(physical(flight, p), y, jnp.nan)
    if which == tuple(range(len(which))):
        return y[: len(which)] * u[1:]
    return y[jnp.asarray(which)] * u[1:]


def rocket_model(flight: Flight, outputs, start: dict, free) -> Model:
    """The [`Model`][] of `flight` with the measured `outputs` (a subset of
    `OUTPUTS` in its order, `altitude` first; `gyro` with an airframe only), start
    values `start` (name -> value) and the estimated parameter names `free`. A start
    value no rocket has (`unphysical`) raises a `LogError` naming it."""
    outputs = tuple(outputs)
    if (
        not outputs
        or outputs[0] != "altitude"
        or any(o not in OUTPUTS for o in outputs)
        or list(outputs) != sorted(outputs, key=OUTPUTS.index)
    ):
        raise ValueError(
            f"outputs must be a subset of {OUTPUTS} in its order, altitude first, "
            f"got {outputs}"
        )
    if "gyro" in outputs and flight.rocket.airframe is None:
        raise ValueError("a gyro output needs the attitude (an airframe)")
    names = flight.parameter_names
    missing = [n for n in names if n not in start]
    if missing:
        raise ValueError(f"no start value for {missing}")
    why = unphysical(flight, start)
    if why:
        raise LogError(f"{flight.rocket.name}: start value {why}")
    rates_fn, observe_fn = _functions(flight, outputs)
    scale = (100.0, 100.0, 100.0, 10.0, 10.0, 10.0)
    if flight.rocket.airframe is not None:
        scale = scale + (1.0, 1.0, 1.0, 0.1, 0.1, 0.1)
    return Model(
        states=flight.states,
        inputs=("airbrake",) + tuple(f"has_{o}" for o in outputs),
        outputs=outputs,
        parameters={n: float(start[n]) for n in names},
        rates=rates_fn,
        observe=observe_fn,
        fixed=tuple(n for n in names if n not in free),
        state_scale=scale,
    )


_FUNCTIONS: dict = {}


def _functions(flight: Flight, outputs: tuple):
    """One `rates` per flight and one `observe` per flight and outputs, so that
    every model of one flight (other starts, other estimated sets) has one
    structure and one compilation."""
    if id(flight) not in _FUNCTIONS or _FUNCTIONS[id(flight)][0] is not flight:
        _FUNCTIONS[id(flight)] = (flight, functools.partial(rates, flight))
    key = (id(flight), outputs)
    if key not in _FUNCTIONS or _FUNCTIONS[key][0] is not flight:
        which = tuple(OUTPUTS.index(o) for o in outputs)
        _FUNCTIONS[key] = (flight, functools.partial(observe, flight, which=which))
    return _FUNCTIONS[id(flight)][1], _FUNCTIONS[key][1]
