"""The Pegasus first stage as a [`FlightVehicle`][]: its database, motor and mass
model behind the abstract part interfaces, so the simulator's vehicle is also one
the output-error engine can fit and the library's effects compose with.

[`pegasus_vehicle`][] composes them; its rates and channels are the simulator's
([`evaluate`][] in `_dynamics.py`) to rounding, in the states `V, alpha, theta, q, h`
instead of the simulator's `u, w, q, theta, x, h` (a test checks it). Its
aerodynamic parameters are the scale factors of the database's lift, drag and
moment derivatives (`CL_scale`, `CD_scale`, `CM_scale`, start 1): what the Monte
Carlo campaign perturbs, and what a flight can tell about the database as a whole.
"""

import jax.numpy as jnp

from .._parts import (
    AbstractAerodynamics,
    AbstractMassProperties,
    AbstractPropulsion,
    FlightVehicle,
    Geometry,
    StandardAtmosphere,
)
from ._aerodynamics import AeroDatabase, coefficients
from ._mass import MassModel, MassProperties
from ._propulsion import SolidMotor
from ._vehicle import Vehicle


SCALES = ("CL_scale", "CD_scale", "CM_scale")


class DatabaseAerodynamics(AbstractAerodynamics):
    """CL, CD, CM (about the cp) from the derivative tables over alpha and Mach,
    each scaled by its parameter `CL_scale`, `CD_scale`, `CM_scale`."""

    database: AeroDatabase

    def start(self):
        return dict.fromkeys(SCALES, 1.0)

    def coefficients(self, c, p):
        base = coefficients(self.database.derivatives(c.alpha, c.mach), c.alpha, c.de)
        return (
            base.CL * p["CL_scale"],
            base.CD * p["CD_scale"],
            base.CM * p["CM_scale"],
        )


class MotorPropulsion(AbstractPropulsion):
    """The solid motor's net thrust at the ambient pressure, along body x."""

    motor: SolidMotor
    reads: tuple[str, ...] = ()

    def thrust(self, t, u):
        thrust = self.motor.net_thrust(t, u["ambient_pressure"])
        return thrust, 0.0, jnp.zeros_like(thrust)


class BurningMass(AbstractMassProperties):
    """The component mass model with the motor's propellant burning off."""

    mass: MassModel
    motor: SolidMotor
    reads: tuple[str, ...] = ()

    def at(self, t, u) -> MassProperties:
        del u
        return self.mass.at(t, self.motor)


def pegasus_vehicle(vehicle: Vehicle | None = None) -> FlightVehicle:
    """The Pegasus first stage (`vehicle`, default the nominal one, perturbed ones
    too) composed from the abstract parts, in the standard atmosphere."""
    v = Vehicle() if vehicle is None else vehicle
    return FlightVehicle(
        aerodynamics=DatabaseAerodynamics(v.aero),
        propulsion=MotorPropulsion(v.motor),
        mass=BurningMass(v.mass, v.motor),
        geometry=Geometry(s_ref=v.s_ref, c_ref=v.c_ref, xcp=v.xcp),
        atmosphere=StandardAtmosphere(),
        name="pegasus",
    )
