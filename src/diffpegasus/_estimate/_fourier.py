"""The finite Fourier transform at chosen frequencies, in one batch or sample by sample.

For a signal `x_i`, `i = 0 .. n-1`, sampled every `dt` from `t_0` the transform at the
frequency `f` (Hz) is the finite Fourier integral over the record by the trapezoidal
rule,

    X(f) = dt * sum_i x_i e_i - dt/2 (x_0 e_0 + x_(n-1) e_(n-1)),  e_i = exp(-2 pi j f (t_i - t_0))

(Klein & Morelli, *Aircraft System Identification*, section 7.1; the sum is what the
chirp-z transform computes). Only the
frequencies the estimators use are computed: a few dozen bins in the band of the
manoeuvre, not the whole FFT.

**Biases vanish on the grid.** On the frequencies `f_k = k / ((n - 1) dt)`, `k = 1, 2, ...`
(the grid of [`frequency_grid`][]) the transform of a constant is exactly zero, so sensor
and trim offsets drop out of every equation without being estimated: omitting 0 Hz
removes them. A slow drift does not vanish but its transform falls as 1/f.

**The recursive transform** ([`fourier_init`][], [`fourier_update`][]) adds one sample's
term to the running sum: Morelli's recursive Fourier transform for real-time
estimation. With a forgetting factor `lam` the sum is weighted by `lam^(k - i)`, so the
estimate follows slowly changing dynamics.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Complex, Float


def frequency_grid(
    samples: int, dt: float, band: tuple[float, float], *, every: int = 1
) -> np.ndarray:
    """The grid frequencies `k / ((samples - 1) dt)` in `band`, Hz, `(frequencies,)`.

    **Arguments:**

    - `samples`, `dt`: the record's length and sample interval (s).
    - `band`: `(low, high)` Hz; the grid starts at `1 / ((samples - 1) dt)` whatever `low`
      says (0 Hz is never used: that is where biases live).
    - `every`: keep every `every`-th grid frequency (coarser grids cost less and stay
      independent).

    **Returns:** the frequencies, Hz, ascending.
    """
    low, high = (float(b) for b in band)
    span = (samples - 1) * dt
    nyquist = 0.5 / dt
    if not high > low or high <= 0:
        raise ValueError(f"frequency band {band} Hz: give (low, high) with high > low")
    if high > nyquist:
        raise ValueError(
            f"frequency band up to {high:g} Hz is above the Nyquist frequency "
            f"{nyquist:g} Hz of samples every {dt:g} s"
        )
    k = np.arange(max(1, int(np.ceil(low * span - 1e-9))), int(high * span + 1e-9) + 1)
    k = k[:: max(1, int(every))]
    if len(k) == 0:
        raise ValueError(
            f"no grid frequency (multiples of {1 / span:.4g} Hz) in the band {band} "
            f"Hz: a {span:g} s record resolves {1 / span:.4g} Hz"
        )
    return k / span


@jax.jit
def finite_fourier(
    x: Float[Array, "samples ..."], dt: float, frequencies: Float[Array, " f"]
) -> Complex[Array, "f ..."]:
    """The finite Fourier transform of `x` at `frequencies`.

    **Arguments:** `x` sampled every `dt` s along its leading axis (any trailing
    shape); `frequencies` in Hz.

    **Returns:** `(frequencies, ...)` complex, units of `x` times seconds.
    """
    x = jnp.asarray(x)
    n = x.shape[0]
    phase = (
        -2j * jnp.pi * jnp.asarray(frequencies)[:, None] * (jnp.arange(n) * dt)[None, :]
    )
    kernel = jnp.exp(phase)
    # the trapezoidal rule: half weight on the first and last samples
    kernel = kernel.at[:, 0].multiply(0.5).at[:, -1].multiply(0.5)
    flat = x.reshape(n, -1).astype(kernel.dtype)
    return (dt * kernel @ flat).reshape(len(frequencies), *x.shape[1:])


class FourierState(eqx.Module):
    """The running transform of [`fourier_update`][].

    **Fields:** `sums` `(frequencies, channels)` complex, the running transforms
    (units of the channels times s); `rotation` `(frequencies,)` the factor
    `exp(-2 pi j f dt)` of one step; `phasor` `(frequencies,)`, `exp(-2 pi j f t)` at
    the next sample; `weight`, the forgetting factor's running product (to weight
    the first sample's end term).
    """

    sums: Complex[Array, "f channels"]
    rotation: Complex[Array, " f"]
    phasor: Complex[Array, " f"]
    weight: Float[Array, ""]


def fourier_init(
    frequencies: Float[Array, " f"], channels: int, dt: float
) -> FourierState:
    """A running transform of `channels` signals at `frequencies` (Hz), sampled every
    `dt` s, before its first sample."""
    f = jnp.asarray(frequencies, float)
    rotation = jnp.exp(-2j * jnp.pi * f * dt)
    return FourierState(
        sums=jnp.zeros((len(f), channels), rotation.dtype),
        rotation=rotation,
        phasor=jnp.ones_like(rotation),
        weight=jnp.ones(()),
    )


def fourier_update(
    state: FourierState, x: Float[Array, " channels"], dt: float, forgetting=1.0
) -> FourierState:
    """Add the sample `x` to the running transform: `X <- lam X + dt x e^(-j w t)`.

    The phasor is advanced by one complex multiplication per frequency; it is
    renormalised to unit modulus so that rounding does not accumulate over hours of
    samples.
    """
    sums = forgetting * state.sums + dt * state.phasor[:, None] * x[None, :]
    phasor = state.phasor * state.rotation
    phasor = phasor / jnp.abs(phasor)
    return FourierState(
        sums=sums,
        rotation=state.rotation,
        phasor=phasor,
        weight=state.weight * forgetting,
    )
