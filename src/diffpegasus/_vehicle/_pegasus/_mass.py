"""Mass, pitch inertia and CG of the Pegasus first-stage configuration.

A component model: the first-stage motor's case and propellant plus everything else
(second and third stages, payload and fairing, wing, fins and interstage), each a
slender uniform body with a mass, a centroid station and a length. The propellant mass
falls linearly with time over the burn at a fixed centroid (the thesis's linear fuel
model); CG and Iyy follow from the parallel-axis theorem. Stations are measured from
the nose, positive aft, in metres.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..._custom_types import Scalar, ScalarLike
from ._propulsion import SolidMotor


# name: (mass kg, centroid station m, length m) -- engineering estimates scaled from
# the published stage masses (Orion 50 about 3,370 kg, Orion 38 about 890 kg).
FIXED_COMPONENTS = {
    "payload_fairing_avionics": (400.0, 0.8, 2.4),
    "stage3_orion38": (890.0, 2.5, 1.3),
    "stage2_orion50": (3370.0, 4.0, 2.7),
    "wing_fins_interstage": (440.0, 8.5, 3.0),
}
MOTOR_CASE = (952.0, 11.5, 8.9)
PROPELLANT_STATION = 10.46
PROPELLANT_LENGTH = 8.6


class MassProperties(eqx.Module):
    """Mass properties at one instant.

    **Fields:** `mass` (kg), `xcg` (CG station from the nose, positive aft, m),
    `Iyy` (pitch inertia about the CG, kg m^2), `Iyy_dot` (its rate, kg m^2/s).
    """

    mass: Scalar
    xcg: Scalar
    Iyy: Scalar
    Iyy_dot: Scalar


class MassModel(eqx.Module):
    """Component mass model.

    **Fields:**

    - `fixed`: shape `(n, 3)`, mass (kg), centroid station (m), length (m) of the
      components that do not change during the first-stage burn.
    - `case`: shape `(3,)`, the same for the first-stage motor case (burnout mass).
    - `propellant_station`, `propellant_length`: m.
    - `mass_scale`: multiplies every mass (Monte Carlo perturbation), default 1.
    - `cg_shift`: added to the CG station, m (Monte Carlo perturbation), default 0.
    """

    fixed: Float[Array, "n 3"] = eqx.field(
        default_factory=lambda: jnp.asarray(list(FIXED_COMPONENTS.values()))
    )
    case: Float[Array, "3"] = eqx.field(default_factory=lambda: jnp.asarray(MOTOR_CASE))
    propellant_station: ScalarLike = PROPELLANT_STATION
    propellant_length: ScalarLike = PROPELLANT_LENGTH
    mass_scale: ScalarLike = 1.0
    cg_shift: ScalarLike = 0.0

    def _properties(self, t: ScalarLike, motor: SolidMotor) -> tuple[Scalar, ...]:
        propellant = motor.motor_mass(t) - self.case[0]
        parts = jnp.concatenate(
            [
                self.fixed,
                self.case[None],
                jnp.stack(
                    [propellant, self.propellant_station, self.propellant_length]
                )[None],
            ]
        )
        m = parts[:, 0] * self.mass_scale
        x = parts[:, 1]
        length = parts[:, 2]
        mass = jnp.sum(m)
        xcg = jnp.sum(m * x) / mass
        iyy = jnp.sum(m * (length**2 / 12 + (x - xcg) ** 2))
        return mass, xcg + self.cg_shift, iyy

    def at(self, t: ScalarLike, motor: SolidMotor) -> MassProperties:
        """Mass properties at time `t` (s after drop) for the given motor."""
        (mass, xcg, iyy), (_, _, iyy_dot) = jax.jvp(
            lambda s: self._properties(s, motor), (jnp.asarray(t, float),), (1.0,)
        )
        return MassProperties(mass=mass, xcg=xcg, Iyy=iyy, Iyy_dot=iyy_dot)


def total_fixed_mass() -> float:
    """Mass of everything but the first-stage motor, kg."""
    return float(np.sum([c[0] for c in FIXED_COMPONENTS.values()]))
