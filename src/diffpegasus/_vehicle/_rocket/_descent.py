"""The descent under parachutes: a point mass falling under each stage's drag area.

From the first deployment (the drogue, at apogee) the rocket is a point mass of its
burned-out mass under the open canopy's drag `-1/2 rho CdS |v_air| v_air` and
gravity, drifting with the wind (`v_air` the velocity relative to the air); each
later stage (the main) replaces the drag area from its deployment time. Its fall
rate tends to the terminal velocity `sqrt(2 m g / (rho CdS))`. Canopy inflation
and the added mass of the air it carries are not modelled (an opening transient of
a second or two).

Parameters (name: unit, meaning): `cds_drogue`, `cds_main` (m^2): each stage's
drag area, the drag coefficient times the reference area of the canopy (and the
airframe tumbling under it).
"""

import equinox as eqx
import jax.numpy as jnp


STAGE_NAMES = ("cds_drogue", "cds_main")


class Descent(eqx.Module):
    """When each parachute stage opens.

    **Fields:** `deploy`: s, log time each stage opens, `(stages,)` ascending (the
    drogue's first; at most two stages). `names`: the stages' drag-area parameter
    names (`cds_drogue`, then `cds_main`).
    """

    deploy: tuple[float, ...] = eqx.field(static=True)

    def __check_init__(self):
        if not 1 <= len(self.deploy) <= len(STAGE_NAMES):
            raise ValueError(f"one or two parachute stages, got {self.deploy}")
        if list(self.deploy) != sorted(self.deploy):
            raise ValueError(f"deployment times must ascend, got {self.deploy}")

    @property
    def names(self) -> tuple[str, ...]:
        return STAGE_NAMES[: len(self.deploy)]

    def active(self, t):
        """Whether the rocket is under a canopy at log time `t` s."""
        return t >= self.deploy[0]

    def drag_area(self, t, p):
        """m^2: the open stage's drag area at log time `t` s (parameters `p`)."""
        cds = p[self.names[0]]
        for time, name in zip(self.deploy[1:], self.names[1:], strict=True):
            cds = jnp.where(t >= time, p[name], cds)
        return cds


def parachute_acceleration(vel, wind, rho, g, mass, cds):
    """m/s^2 `(3,)` east-north-up of a point mass `mass` kg at velocity `vel`
    `(3,)` m/s in a `wind` `(3,)` m/s, air density `rho` kg/m^3, gravity `g` m/s^2,
    under a drag area `cds` m^2."""
    air = vel - wind
    speed = jnp.sqrt(jnp.sum(air**2) + 1e-6)
    drag = -0.5 * rho * cds * speed * air / mass
    return drag + jnp.stack([0.0, 0.0, -g])


def terminal_velocity(mass, g, rho, cds):
    """m/s: the steady fall rate `sqrt(2 m g / (rho CdS))` in still air."""
    return jnp.sqrt(2.0 * mass * g / (rho * cds))


def drag_area_for_rate(mass, g, rho, rate):
    """m^2: the drag area `2 m g / (rho v^2)` that makes `rate` m/s the terminal
    velocity (the inverse of [`terminal_velocity`][])."""
    return 2.0 * mass * g / (rho * rate**2)
