"""The sensor model: white noise and biases on the measured channels.

Accelerometers measure specific force (non-gravitational force over mass) at the CG
in body axes. Default noise standard deviations, per 1 kHz sample, roughly those of a
tactical-grade IMU and a flight-test air-data boom:

| channel | sigma | | channel | sigma |
|---|---|---|---|---|
| ax, az | 0.05 m/s^2 | | alpha | 0.1 deg |
| q | 0.1 deg/s | | theta | 0.05 deg |
| qdot | 1 deg/s^2 | | V | 0.5 m/s |
| h | 5 m | | mach | 0.002 |
| qbar | 50 Pa | | de | 0.02 deg |

Bookkeeping channels (thrust, mass, Iyy, Iyy_dot, xcg, xcp) and the truth columns are
noise-free. The thesis puts noise on the accelerations only: `SensorModel.thesis()`.
"""

import zlib

import equinox as eqx
import jax
import numpy as np
from jaxtyping import Array, Float, PRNGKeyArray


DEFAULT_SIGMA = {
    "ax": 0.05,
    "az": 0.05,
    "q": float(np.deg2rad(0.1)),
    "qdot": float(np.deg2rad(1.0)),
    "alpha": float(np.deg2rad(0.1)),
    "theta": float(np.deg2rad(0.05)),
    "V": 0.5,
    "h": 5.0,
    "mach": 0.002,
    "qbar": 50.0,
    "de": float(np.deg2rad(0.02)),
}


class SensorModel(eqx.Module):
    """White noise (standard deviation per sample, SI units) and constant biases.

    **Fields:** `sigma` and `bias`, dicts from channel name to value.
    """

    sigma: dict[str, float] = eqx.field(default_factory=lambda: dict(DEFAULT_SIGMA))
    bias: dict[str, float] = eqx.field(default_factory=dict)

    @classmethod
    def noise_free(cls) -> "SensorModel":
        """No noise and no bias."""
        return cls(sigma={}, bias={})

    @classmethod
    def thesis(cls) -> "SensorModel":
        """Noise on the accelerometers only, as in the thesis."""
        return cls(sigma={"ax": DEFAULT_SIGMA["ax"], "az": DEFAULT_SIGMA["az"]})

    def apply(
        self, channels: dict[str, Float[Array, " time"]], key: PRNGKeyArray
    ) -> dict[str, Float[Array, " time"]]:
        """Add bias and white noise to the named channels (others pass through)."""
        out = dict(channels)
        for name in sorted(set(self.sigma) | set(self.bias)):
            # One stream per channel name, so adding a channel leaves the others alone.
            k = jax.random.fold_in(key, zlib.crc32(name.encode()) & 0x7FFFFFFF)
            if name not in out:
                raise ValueError(f"sensor model names unknown channel {name!r}")
            x = out[name] + self.bias.get(name, 0.0)
            sigma = self.sigma.get(name, 0.0)
            out[name] = x + sigma * jax.random.normal(k, x.shape, x.dtype)
        return out
