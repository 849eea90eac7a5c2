"""Propulsion, sensor, actuator and atmosphere effects."""

import equinox as eqx
import jax.numpy as jnp

from ..._custom_types import ScalarLike
from ._base import AbstractEffect


class ThrustMisalignment(AbstractEffect):
    """Thrust line offset from the CG: pitching moment = thrust x `offset`.

    `offset` (m) is the thrust line's distance below the CG (positive: nose-up).
    """

    offset: ScalarLike = 0.0
    name = "thrust_misalignment"
    description = "thrust line not through the CG, moment = thrust x offset (m)"
    parameter = "offset"

    def moment(self, c):
        return self.offset * c.thrust


class AccelerometerOffset(AbstractEffect):
    """IMU `dx` metres forward of the CG: it also senses rotation.

    ax_imu = ax_cg - q^2 dx, az_imu = az_cg - qdot dx.
    """

    dx: ScalarLike = 0.0
    name = "accelerometer_offset"
    description = "accelerometers dx (m) forward of the CG sense -q^2 dx and -qdot dx"
    parameter = "dx"

    def measure(self, channels, c):
        out = dict(channels)
        out["ax"] = channels["ax"] - c.q**2 * self.dx
        out["az"] = channels["az"] - c.qdot * self.dx
        return out


class SensorBias(AbstractEffect):
    """A constant bias on one measured channel (canonical name `sensor_bias:<channel>`)."""

    channel: str = eqx.field(static=True, default="az")
    bias: ScalarLike = 0.0
    name = "sensor_bias"
    description = "constant bias on one measured channel (channel units)"
    parameter = "bias"

    def measure(self, channels, c):
        del c
        if self.channel not in channels:
            raise ValueError(f"sensor_bias: unknown channel {self.channel!r}")
        out = dict(channels)
        out[self.channel] = channels[self.channel] + self.bias
        return out


class ActuatorDelay(AbstractEffect):
    """The surface follows the command `tau` seconds late."""

    tau: ScalarLike = 0.0
    name = "actuator_delay"
    description = "elevator deflection lags the recorded command by tau (s)"
    parameter = "tau"

    def elevator_delay(self):
        return self.tau


class VerticalWind(AbstractEffect):
    """A steady vertical wind of `w_up` m/s (positive up) in the inertial frame."""

    w_up: ScalarLike = 0.0
    name = "vertical_wind"
    description = "steady updraft w_up (m/s) changing the air-relative alpha and V"
    parameter = "w_up"

    def wind(self, t, theta):
        del t
        return self.w_up * jnp.sin(theta), -self.w_up * jnp.cos(theta)
