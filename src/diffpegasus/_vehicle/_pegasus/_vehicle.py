"""The Pegasus first-stage vehicle: geometry, aerodynamics, motor and mass model."""

import equinox as eqx
import jax.numpy as jnp

from ..._custom_types import Scalar, ScalarLike
from ._aerodynamics import AeroDatabase, load_database
from ._mass import MassModel
from ._propulsion import smoothstep, SolidMotor


S_REF = 13.5  # reference area, m^2
C_REF = 2.48  # moment reference length (mean aerodynamic chord), m


class Vehicle(eqx.Module):
    """A winged launch-vehicle stack in the pitch plane.

    **Fields:**

    - `aero`: the aerodynamic database (derivatives per rad over alpha and Mach).
    - `motor`: the first-stage motor.
    - `mass`: the component mass model.
    - `s_ref` (m^2), `c_ref` (m, moment reference length: mean aerodynamic chord),
      `span`, `length`, `diameter` (m).
    - `cp_fraction`: `(subsonic, hypersonic)` centre-of-pressure station as a fraction
      of the length from the nose. The thesis quotes 31% to 29% of the length; read
      from the tail (from the nose it would put the cp ahead of the CG and make the
      vehicle unstable) that is 69% to 71% from the nose. The cp moves aft smoothly
      between Mach 0.8 and 8.
    """

    aero: AeroDatabase = eqx.field(default_factory=load_database)
    motor: SolidMotor = eqx.field(default_factory=SolidMotor)
    mass: MassModel = eqx.field(default_factory=MassModel)
    s_ref: float = eqx.field(static=True, default=S_REF)
    c_ref: float = eqx.field(static=True, default=C_REF)
    span: float = eqx.field(static=True, default=6.7)
    length: float = eqx.field(static=True, default=15.0)
    diameter: float = eqx.field(static=True, default=1.27)
    cp_fraction: tuple[float, float] = eqx.field(static=True, default=(0.69, 0.71))

    def xcp(self, mach: ScalarLike) -> Scalar:
        """Centre-of-pressure station from the nose, positive aft, m."""
        lo, hi = self.cp_fraction
        blend = smoothstep((mach - 0.8) / (8.0 - 0.8))
        return self.length * (lo + (hi - lo) * blend)

    def perturbed(
        self,
        lift: ScalarLike = 1.0,
        drag: ScalarLike = 1.0,
        moment: ScalarLike = 1.0,
        mass: ScalarLike = 1.0,
        thrust: ScalarLike = 1.0,
        cg_shift: ScalarLike = 0.0,
    ) -> "Vehicle":
        """A copy with scaled CL/CD/CM tables, mass and thrust, and a CG shift (m)."""
        return eqx.tree_at(
            lambda v: (
                v.aero,
                v.mass.mass_scale,
                v.mass.cg_shift,
                v.motor.thrust_scale,
            ),
            self,
            (
                self.aero.scaled(lift, drag, moment),
                jnp.asarray(mass, float),
                jnp.asarray(cg_shift, float),
                jnp.asarray(thrust, float),
            ),
        )
