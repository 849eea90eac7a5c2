"""Window bookkeeping shared by the estimators.

A record of `n` samples at `rate` Hz is cut into consecutive windows of
`round(window * rate)` samples from its first sample. A trailing partial window is
kept when it holds at least half a window, and dropped otherwise. Windows are stored
as a padded `(windows, samples_per_window, ...)` array with a 0/1 mask, so every
window has the same shape and a batch of them solves in one vmapped call.
"""

import dataclasses

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float


@dataclasses.dataclass(frozen=True)
class WindowLayout:
    """How a record is cut into windows (all Python ints: static under jit).

    **Fields:** `n_samples` in the record, `per_window` samples in a full window,
    `count` of windows, `last` samples in the last window (`per_window` unless it is
    a partial one), `rate` (Hz).
    """

    n_samples: int
    per_window: int
    count: int
    last: int
    rate: float

    @classmethod
    def make(cls, n_samples: int, rate: float, window: float) -> "WindowLayout":
        """Layout for `n_samples` at `rate` Hz in windows of `window` s."""
        per = int(round(window * rate))
        if per < 3:
            raise ValueError(
                f"a {window} s window holds only {per} samples at {rate:g} Hz; "
                "use a longer window"
            )
        full, rest = divmod(n_samples, per)
        if full == 0:
            raise ValueError(
                f"the record has {n_samples} samples, fewer than one {window} s window "
                f"({per} samples)"
            )
        if 2 * rest >= per:
            return cls(n_samples, per, full + 1, rest, rate)
        return cls(n_samples, per, full, per, rate)

    @property
    def used(self) -> int:
        """Samples that fall in some window."""
        return (self.count - 1) * self.per_window + self.last

    def times(self, t0: float) -> tuple[np.ndarray, np.ndarray]:
        """Start and end (s) of every window; a window covers [start, end)."""
        start = t0 + np.arange(self.count) * self.per_window / self.rate
        sizes = np.full(self.count, self.per_window)
        sizes[-1] = self.last
        return start, start + sizes / self.rate

    def mask(self) -> Float[Array, "windows per"]:
        """1 for real samples, 0 for padding."""
        m = np.ones((self.count, self.per_window))
        m[-1, self.last :] = 0.0
        return jnp.asarray(m)

    def split(self, x: Float[Array, "n ..."]) -> Float[Array, "windows per ..."]:
        """Cut an array whose leading axis is time into padded windows."""
        x = x[: self.used]
        pad = self.count * self.per_window - self.used
        x = jnp.concatenate([x, jnp.zeros((pad, *x.shape[1:]), x.dtype)])
        return x.reshape(self.count, self.per_window, *x.shape[1:])

    def window_mean(self, x: Float[Array, " n"]) -> Float[Array, " windows"]:
        """Mean of a channel over each window (e.g. the truth a window estimates)."""
        m = self.mask()
        return jnp.sum(self.split(x) * m, axis=1) / jnp.sum(m, axis=1)
