"""The descent under parachutes: a point mass falling under each stage's drag area.

From the first canopy's opening the rocket is a point mass of its burned-out mass
under the canopy's drag `-1/2 rho CdS |v_air| v_air` and gravity, drifting with
the wind (`v_air` the velocity relative to the air); each later stage (the main)
replaces the drag area from its opening. A stage opens its opening time after its
event (RocketPy's parachute `lag`, ejection to the canopy full): until then the
rocket flies as before (the ascent's dynamics before the drogue, the drogue's drag
before the main). The switch is a ramp `FILL` s wide centred on the opening (never
before the event), so that the fit has a derivative for the opening time; the
filling of a real canopy over a second or so and the added mass of the air it
carries are not modelled. Its fall rate tends to the terminal velocity
`sqrt(2 m g / (rho CdS))`.

Parameters (name: unit, meaning): `cds_drogue`, `cds_main` (m^2): each stage's
drag area, the drag coefficient times the reference area of the canopy (and the
airframe tumbling under it); the drag uses its magnitude, so that a fit stepping
through zero sees a free fall, not a drag pushing the rocket down that grows
without bound. `open_drogue`, `open_main` (s): each stage's opening time after
its event, 0 or above (`NONNEGATIVE` in `_model`: no start below 0, no fit's step).
"""

import equinox as eqx
import jax.numpy as jnp


STAGE_NAMES = ("cds_drogue", "cds_main")
OPEN_NAMES = ("open_drogue", "open_main")
FILL = 0.2  # s: the opening's ramp (four steps of the descent's 20 Hz grid)


class Descent(eqx.Module):
    """When each parachute stage opens.

    **Fields:** `deploy`: s, log time of each stage's event (its ejection), `(stages,)`
    ascending (the drogue's first; at most two stages). `names`: the stages'
    drag-area parameter names (`cds_drogue`, then `cds_main`); `openings`: their
    opening-time parameter names (`open_drogue`, then `open_main`).
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

    @property
    def openings(self) -> tuple[str, ...]:
        return OPEN_NAMES[: len(self.deploy)]

    def opened(self, k, t, p):
        """0-1: how far stage `k`'s canopy is open at log time `t` s: 0 before its
        event, a ramp `FILL` s wide centred on the event plus its opening time
        (parameter `open_<stage>`), then 1."""
        centre = self.deploy[k] + p[OPEN_NAMES[k]]
        ramp = jnp.clip((t - centre) / FILL + 0.5, 0.0, 1.0)
        return jnp.where(t >= self.deploy[k], ramp, 0.0)

    def active(self, t):
        """Whether the drogue's event has passed at log time `t` s (the record's
        accelerometer and gyros end there)."""
        return t >= self.deploy[0]

    def drag_area(self, t, p):
        """m^2: the drag area of the open stages at log time `t` s (parameters
        `p`): the drogue's, blended into each later stage's as it opens."""
        cds = jnp.abs(p[self.names[0]])
        for k in range(1, len(self.deploy)):
            cds = cds + self.opened(k, t, p) * (jnp.abs(p[self.names[k]]) - cds)
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
