"""Orion 50S first-stage solid motor: vacuum thrust trace and ambient-pressure loss.

The public sources give no thrust-time trace, so the vacuum thrust is a documented
solid-motor shape: a 0.6 s smooth rise after ignition, a slightly regressive plateau
(thrust falling linearly by 22% of its initial value over the burn) and a 6 s smooth
tail-off ending at burnout, scaled so that its integral is the catalogue total impulse.
Net thrust is the standard relation `T = T_vac - A_e p_ambient` (the thesis's eq. 2.10,
`T_vac + A (p0 - p)`, is not); the pressure loss is applied in proportion to the
rise/tail-off envelope so that a motor that is not burning gives no thrust at all.
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..._custom_types import Scalar, ScalarLike
from ..._inputs import smoothstep as smoothstep


class SolidMotor(eqx.Module):
    """A solid rocket motor firing along the body x axis through the CG.

    **Fields:**

    - `ignition_time`: s after drop (default 5 s).
    - `burn_time`: s from ignition to burnout (default 75.3 s, the catalogue burn time,
      counted from ignition, so burnout is 80.3 s after drop).
    - `total_impulse`: vacuum total impulse, N s (default 35.4e6).
    - `exit_area`: nozzle exit area, m^2 (default for a 1.42 m exit diameter).
    - `motor_mass_initial`, `motor_mass_burnout`: motor mass (case plus propellant)
      at ignition and burnout, kg; it falls linearly in between.
    - `rise_time`, `tailoff_time`: s; `regression`: fractional plateau fall.
    - `thrust_scale`: multiplies the vacuum and the net thrust (Monte Carlo
      perturbation), default 1.
    """

    ignition_time: float = eqx.field(static=True, default=5.0)
    burn_time: float = eqx.field(static=True, default=75.3)
    total_impulse: float = eqx.field(static=True, default=35.4e6)
    exit_area: float = eqx.field(static=True, default=float(np.pi * 1.42**2 / 4))
    motor_mass_initial: float = eqx.field(static=True, default=13_405.0)
    motor_mass_burnout: float = eqx.field(static=True, default=952.0)
    rise_time: float = eqx.field(static=True, default=0.6)
    tailoff_time: float = eqx.field(static=True, default=6.0)
    regression: float = eqx.field(static=True, default=0.22)
    thrust_scale: ScalarLike = 1.0

    @property
    def burnout_time(self) -> float:
        """Time of burnout after drop, s."""
        return self.ignition_time + self.burn_time

    def envelope(self, t: ScalarLike) -> Scalar:
        """Rise and tail-off envelope in [0, 1]."""
        rise = smoothstep((t - self.ignition_time) / self.rise_time)
        fall = smoothstep((self.burnout_time - t) / self.tailoff_time)
        return rise * fall

    def _shape(self, t: ScalarLike) -> Scalar:
        tau = jnp.clip((t - self.ignition_time) / self.burn_time, 0.0, 1.0)
        return self.envelope(t) * (1.0 - self.regression * tau)

    @property
    def peak_vacuum_thrust(self) -> float:
        """Vacuum thrust at the start of the plateau (before `thrust_scale`), N."""
        return self.total_impulse / _shape_integral(self.without_scale())

    def without_scale(self) -> "SolidMotor":
        """The same motor with `thrust_scale = 1` (hashable: all fields static)."""
        return eqx.tree_at(lambda m: m.thrust_scale, self, 1.0)

    def vacuum_thrust(self, t: ScalarLike) -> Scalar:
        """Vacuum thrust at time `t` (s after drop), N."""
        return self.thrust_scale * self.peak_vacuum_thrust * self._shape(t)

    def net_thrust(self, t: ScalarLike, ambient_pressure: ScalarLike) -> Scalar:
        """Net thrust along body +x at time `t` and ambient pressure (Pa), N."""
        loss = self.exit_area * ambient_pressure * self.envelope(t)
        return self.vacuum_thrust(t) - self.thrust_scale * loss

    def motor_mass(self, t: ScalarLike) -> Scalar:
        """Motor mass (case plus remaining propellant), kg."""
        frac = jnp.clip((t - self.ignition_time) / self.burn_time, 0.0, 1.0)
        return self.motor_mass_initial + frac * (
            self.motor_mass_burnout - self.motor_mass_initial
        )


@functools.lru_cache(maxsize=16)
def _shape_integral(motor: SolidMotor) -> float:
    """Integral of the unscaled thrust shape over the burn, s (trapezoid, 0.4 ms)."""
    with jax.ensure_compile_time_eval():
        t = np.linspace(motor.ignition_time, motor.burnout_time, 200_001)
        shape = np.asarray(motor._shape(jnp.asarray(t)))
    return float(np.sum(0.5 * (shape[1:] + shape[:-1]) * np.diff(t)))
