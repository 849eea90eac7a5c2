"""A vehicle is a value: abstract parts, a [`FlightVehicle`][] that composes them on
the one flight model ([`pitch_plane`][]), and [`vehicle_model`][] that turns it into
a [`Model`][] to simulate and identify, with any library effects plugged in.

Parts (each an `eqx.Module`; write your own by subclassing the abstract one):

| part | gives | built in |
|---|---|---|
| [`AbstractAerodynamics`][] | CL, CD, CM from the flight condition and parameters | your published model |
| [`AbstractPropulsion`][] | thrust (N), its inclination (rad) and moment (N m) | [`LoggedThrust`][] |
| [`AbstractMassProperties`][] | mass, Iyy, Iyy_dot, CG station | [`ConstantMass`][], [`LoggedMass`][] |
| [`Geometry`][] | reference area, length, cp station | |
| [`AbstractAtmosphere`][] | density, speed of sound, gravity | [`ConstantAtmosphere`][], [`StandardAtmosphere`][] |

The model's states are `V, alpha, theta, q` (m/s, rad, rad, rad/s; `h` is added
when the atmosphere depends on altitude) and its known inputs `de` (rad) plus what
the parts read from the log (e.g. `thrust`).
"""

import abc
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
from equinox import AbstractVar

from .._model import Model
from ._atmosphere import isa
from ._effects import AbstractEffect, FlightCondition, make_effect
from ._flight import elevator_delay, has_delay, pitch_plane, PitchPlane
from ._gravity import gravity
from ._pegasus._mass import MassProperties


class AbstractAerodynamics(eqx.Module):
    """The aerodynamic model: `coefficients(c, p) -> (CL, CD, CM)` with `c` the
    [`FlightCondition`][] (it must not use `c.alpha_dot` or `c.qdot`) and `p` the
    parameters by name; CM about the geometry's cp station. `start()` gives the
    parameters' names and start values."""

    @abc.abstractmethod
    def start(self) -> dict[str, float]: ...

    @abc.abstractmethod
    def coefficients(self, c: FlightCondition, p: dict): ...


class AbstractPropulsion(eqx.Module):
    """`thrust(t, u) -> (thrust N, inclination rad, moment about CG N m)` where `u`
    is a dict of the known inputs named in `reads` (the log channels it needs) and
    `"ambient_pressure"` (Pa, from the vehicle's atmosphere), for motors whose
    thrust depends on it."""

    reads: AbstractVar[tuple[str, ...]]

    @abc.abstractmethod
    def thrust(self, t, u: dict): ...


class AbstractMassProperties(eqx.Module):
    """`at(t, u) -> MassProperties` (kg, kg m^2, kg m^2/s, m from the nose), with
    `u` a dict of the known inputs named in `reads` (the log channels it needs,
    e.g. a mass the log records)."""

    reads: AbstractVar[tuple[str, ...]]

    @abc.abstractmethod
    def at(self, t, u: dict) -> MassProperties: ...


class AbstractAtmosphere(eqx.Module):
    """`at(h) -> (density kg/m^3, speed of sound m/s, gravity m/s^2)`;
    `altitude`: whether it depends on `h` (then `h` is a state); `pressure(h)`, the
    ambient pressure (Pa), NaN unless the atmosphere knows it (only a motor that
    needs it asks)."""

    altitude: AbstractVar[bool]

    @abc.abstractmethod
    def at(self, h): ...

    def pressure(self, h):
        del h
        return jnp.nan


class LoggedThrust(AbstractPropulsion):
    """Thrust read from the log's `thrust` channel, inclined `angle` (rad, nose up)
    to body x, with `moment_per_newton` (N m per N: its arm about the CG, positive
    nose up)."""

    angle: float = 0.0
    moment_per_newton: float = 0.0
    reads: tuple[str, ...] = ("thrust",)

    def thrust(self, t, u):
        del t
        return u["thrust"], self.angle, self.moment_per_newton * u["thrust"]


class ConstantMass(AbstractMassProperties):
    """Mass (kg), pitch inertia (kg m^2) and CG station (m) that do not change."""

    mass: float
    iyy: float
    xcg: float = 0.0
    reads: tuple[str, ...] = ()

    def at(self, t, u):
        del u
        zero = jnp.zeros_like(jnp.asarray(t, float))
        return MassProperties(
            mass=zero + self.mass,
            Iyy=zero + self.iyy,
            Iyy_dot=zero,
            xcg=zero + self.xcg,
        )


class LoggedMass(AbstractMassProperties):
    """Mass properties the log records: channels `mass` (kg), `Iyy` (kg m^2),
    `Iyy_dot` (kg m^2/s) and `xcg` (m from the nose), e.g. from a motor's
    burn-off model the flight computer or the simulator logged."""

    reads: tuple[str, ...] = ("mass", "Iyy", "Iyy_dot", "xcg")

    def at(self, t, u):
        del t
        return MassProperties(
            mass=u["mass"], Iyy=u["Iyy"], Iyy_dot=u["Iyy_dot"], xcg=u["xcg"]
        )


class ConstantAtmosphere(AbstractAtmosphere):
    """Density, speed of sound and gravity held at one flight condition."""

    density: float
    speed_of_sound: float = 340.29
    g: float = 9.80665
    ambient_pressure: float = float("nan")
    altitude: bool = False

    def at(self, h):
        del h
        return self.density, self.speed_of_sound, self.g

    def pressure(self, h):
        del h
        return self.ambient_pressure


class StandardAtmosphere(AbstractAtmosphere):
    """The 1976 standard atmosphere and inverse-square gravity at altitude `h`."""

    altitude: bool = True

    def at(self, h):
        atm = isa(h)
        return atm.density, atm.speed_of_sound, gravity(h)

    def pressure(self, h):
        return isa(h).pressure


class Geometry(eqx.Module):
    """Reference area `s_ref` (m^2), reference length `c_ref` (m) and the station
    `xcp` (m from the nose, positive aft) where the aerodynamic force acts (the CM
    reference): a number, a function of Mach for a centre of pressure that
    travels, or the name of the log channel that records it."""

    s_ref: float
    c_ref: float
    xcp: float | Callable | str = 0.0

    @property
    def reads(self) -> tuple[str, ...]:
        """The log channels the geometry needs (the cp station, when logged)."""
        return (self.xcp,) if isinstance(self.xcp, str) else ()

    def station(self, mach, u: dict):
        """The cp station (m from the nose) at `mach`, `u` the known inputs."""
        if isinstance(self.xcp, str):
            return u[self.xcp]
        return self.xcp(mach) if callable(self.xcp) else self.xcp


class FlightVehicle(eqx.Module):
    """A rigid vehicle in the pitch plane, composed of parts."""

    aerodynamics: AbstractAerodynamics
    propulsion: AbstractPropulsion
    mass: AbstractMassProperties
    geometry: Geometry
    atmosphere: AbstractAtmosphere
    name: str = eqx.field(static=True, default="vehicle")

    @property
    def states(self) -> tuple[str, ...]:
        base = ("V", "alpha", "theta", "q")
        return base + (("h",) if self.atmosphere.altitude else ())

    @property
    def inputs(self) -> tuple[str, ...]:
        reads = self.propulsion.reads + self.mass.reads + self.geometry.reads
        return ("de",) + tuple(dict.fromkeys(reads))

    def evaluate(self, t, x, u, p, effects: tuple[AbstractEffect, ...]):
        """State rates `(states,)` and the [`PitchPlane`][] at `(t, x)`; `u` the
        known inputs `(inputs,)` (the elevator already delayed)."""
        v, alpha, theta, q = x[0], x[1], x[2], x[3]
        h = x[4] if self.atmosphere.altitude else 0.0
        known = dict(
            zip(self.inputs, [u[i] for i in range(len(self.inputs))], strict=True)
        )
        density, sound, g = self.atmosphere.at(h)
        known["ambient_pressure"] = self.atmosphere.pressure(h)
        thrust, angle, moment = self.propulsion.thrust(t, known)
        props = self.mass.at(t, known)
        uu, ww = v * jnp.cos(alpha), v * jnp.sin(alpha)
        pp: PitchPlane = pitch_plane(
            t,
            uu,
            ww,
            q,
            theta,
            h,
            de=known["de"],
            aero=lambda c: self.aerodynamics.coefficients(c, p),
            effects=effects,
            s_ref=self.geometry.s_ref,
            c_ref=self.geometry.c_ref,
            density=density,
            speed_of_sound=sound,
            g=g,
            thrust=thrust,
            thrust_angle=angle,
            thrust_moment=moment,
            mass=props.mass,
            iyy=props.Iyy,
            iyy_dot=props.Iyy_dot,
            xcg=props.xcg,
            xcp=lambda mach: self.geometry.station(mach, known),
        )
        # body-axis accelerations into V and alpha rates (exact)
        vdot = (uu * pp.udot + ww * pp.wdot) / v
        alphadot = (uu * pp.wdot - ww * pp.udot) / v**2
        rates = [vdot, alphadot, q, pp.qdot]
        if self.atmosphere.altitude:
            rates.append(pp.hdot)
        return jnp.stack(rates), pp


# Library effects that compose with any FlightVehicle (`--add`, `diagnose`).
PITCH_PLANE_EFFECTS = (
    "pitch_damping",
    "alpha_dot_damping",
    "lift_alpha_squared",
    "drag_alpha_squared",
    "moment_alpha_squared",
    "actuator_delay",
    "sensor_bias:ax",
    "sensor_bias:az",
    "sensor_bias:qdot",
    "sensor_bias:q",
    "sensor_bias:alpha",
    "sensor_bias:theta",
)


def effect_parameter(name: str) -> str:
    """The model parameter of a library effect: `pitch_damping.Cmq`."""
    return f"{name}.{make_effect(name).parameter}"


class _Frozen:
    """A vehicle as a static (hashable) value: equal when its structure and every
    leaf are equal, so jit shares programs between equal vehicles even when their
    parts hold arrays (a database's tables)."""

    __slots__ = ("value", "_key")

    def __init__(self, value):
        import numpy as np

        leaves, treedef = jax.tree.flatten(value)
        arrays = tuple(
            (np.shape(x), str(np.result_type(x)), np.asarray(x).tobytes())
            if eqx.is_array_like(x)
            else x
            for x in leaves
        )
        self.value = value
        self._key = (treedef, arrays)

    def __hash__(self):
        return hash(self._key)

    def __eq__(self, other):
        return isinstance(other, _Frozen) and self._key == other._key


class _VehicleFunctions(eqx.Module):
    """The vehicle's rates and outputs with the library effects `effects`."""

    frozen: _Frozen = eqx.field(static=True)
    outputs: tuple[str, ...] = eqx.field(static=True)
    effects: tuple[str, ...] = eqx.field(static=True)

    @property
    def vehicle(self) -> FlightVehicle:
        return self.frozen.value

    def _effects(self, p):
        return tuple(make_effect(n, p[effect_parameter(n)]) for n in self.effects)

    def rates(self, t, x, u, p):
        return self.vehicle.evaluate(t, x, u, p, self._effects(p))[0]

    def observe(self, t, x, u, p):
        ch = self.vehicle.evaluate(t, x, u, p, self._effects(p))[1].channels
        return jnp.stack([ch[n] for n in self.outputs])

    def delays(self, p):
        tau = elevator_delay(self._effects(p))
        return jnp.stack([tau] + [0.0] * (len(self.vehicle.inputs) - 1))


DEFAULT_OUTPUTS = ("V", "alpha", "theta", "q", "qdot", "ax", "az")


def vehicle_model(
    vehicle: FlightVehicle,
    outputs: tuple[str, ...] = DEFAULT_OUTPUTS,
    effects: tuple[str, ...] = (),
    free: tuple[str, ...] = (),
    **changes,
) -> Model:
    """The [`Model`][] of `vehicle`: its aerodynamic parameters (start values from
    the part), states and inputs, the measured `outputs` (any channel of
    [`PitchPlane`][]), and library `effects` (canonical names) composed through
    their hooks, each adding its parameter (`name.parameter`, start 0) held at zero
    unless named in `free`. Keyword arguments change the model's fields (e.g.
    `fixed=("CMq",)`, `start={"CMq": 0.0}`)."""
    effects = tuple(effects)
    functions = _VehicleFunctions(_Frozen(vehicle), tuple(outputs), effects)
    extra = {effect_parameter(e): 0.0 for e in effects}
    held = tuple(k for k in extra if k not in free and k.split(".")[0] not in free)
    probe = tuple(make_effect(e) for e in effects)
    model = Model(
        states=vehicle.states,
        inputs=vehicle.inputs,
        outputs=tuple(outputs),
        parameters={**vehicle.aerodynamics.start(), **extra},
        rates=functions.rates,
        observe=functions.observe,
        fixed=held,
        delays=functions.delays if has_delay(probe) else None,
    )
    if changes.get("fixed"):
        changes["fixed"] = tuple(changes["fixed"]) + held
    return model.replace(**changes) if changes else model
