"""The per-window result every estimator returns, and its JSON/CSV forms."""

import csv
import math
import os
from typing import Any

import equinox as eqx
import numpy as np
from jaxtyping import Array, Bool, Float

from .._vehicle._pegasus._aerodynamics import DERIVATIVE_NAMES


class Estimates(eqx.Module):
    """Per-window derivative estimates from one flight (or a batch, leading axis).

    **Fields:**

    - `method`: `"lse"`, `"nn"` or `"oem"`.
    - `window_start`, `window_end`: s, shape `(windows,)`; a window covers
      [start, end).
    - `values`: shape `(windows, 6)`, `CLa, CLde, CDa, CDde, CMa, CMde` in 1/rad; NaN
      for a window without an estimate.
    - `stderr`: same shape, standard errors (1/rad), or `None`.
    - `valid`: shape `(windows,)`, whether the window has an estimate of its own
      (not held from an earlier window, not NaN).
    - `flags`: method-specific per-window arrays (e.g. `rank_deficient`, `rank_A`).
    - `truth`: shape `(windows, 6)`, the true derivatives averaged over each window
      (1/rad), when the log has `true_*` columns; else `None`.
    """

    method: str = eqx.field(static=True)
    window_start: Float[Array, " windows"]
    window_end: Float[Array, " windows"]
    values: Float[Array, "windows 6"]
    stderr: Float[Array, "windows 6"] | None
    valid: Bool[Array, " windows"]
    flags: dict[str, Array]
    truth: Float[Array, "windows 6"] | None = None

    def to_dict(self, units: str = "deg") -> dict[str, Any]:
        """The JSON object of the estimates (`None` for windows without an estimate)."""
        scale = _scale(units)

        def column(a, j):
            return [
                None if not math.isfinite(x) else x * scale
                for x in np.asarray(a)[:, j].tolist()
            ]

        out = {
            "method": self.method,
            "units": f"1/{units}",
            "window_start": np.asarray(self.window_start).tolist(),
            "window_end": np.asarray(self.window_end).tolist(),
            "estimates": {
                n: column(self.values, j) for j, n in enumerate(DERIVATIVE_NAMES)
            },
            "stderr": None
            if self.stderr is None
            else {n: column(self.stderr, j) for j, n in enumerate(DERIVATIVE_NAMES)},
            "flags": {k: np.asarray(v).tolist() for k, v in self.flags.items()},
        }
        if self.truth is not None:
            out["truth"] = {
                n: column(self.truth, j) for j, n in enumerate(DERIVATIVE_NAMES)
            }
        return out

    def write_csv(self, path: str | os.PathLike, units: str = "deg") -> None:
        """One row per window: times, estimates, standard errors, truth, flags."""
        d = self.to_dict(units)
        names = list(DERIVATIVE_NAMES)
        header = ["window_start", "window_end", *names]
        header += [f"stderr_{n}" for n in names] if d["stderr"] else []
        header += [f"true_{n}" for n in names] if "truth" in d else []
        header += list(d["flags"])
        from .._files import atomic_write

        def write(f):
            w = csv.writer(f)
            w.writerow(header)
            for i in range(len(d["window_start"])):
                row = [d["window_start"][i], d["window_end"][i]]
                row += [d["estimates"][n][i] for n in names]
                row += [d["stderr"][n][i] for n in names] if d["stderr"] else []
                row += [d["truth"][n][i] for n in names] if "truth" in d else []
                row += [d["flags"][k][i] for k in d["flags"]]
                w.writerow(["" if x is None else x for x in row])

        atomic_write(path, write)

    def mse(self, units: str = "deg", t_min: float | None = None) -> dict[str, float]:
        """Mean-squared error against the window-mean truth, per derivative, in
        (1/units)^2, over the valid windows (starting at or after `t_min` s)."""
        if self.truth is None:
            raise ValueError("the log has no true_* columns to compare with")
        scale = _scale(units)
        valid = np.asarray(self.valid)
        if t_min is not None:
            valid = valid & (np.asarray(self.window_start) >= t_min - 1e-9)
        err = (np.asarray(self.values) - np.asarray(self.truth))[valid] * scale
        return {
            n: float(np.mean(err[:, j] ** 2)) for j, n in enumerate(DERIVATIVE_NAMES)
        }


def _scale(units: str) -> float:
    if units == "deg":
        return math.pi / 180.0
    if units == "rad":
        return 1.0
    raise ValueError(f"units must be 'deg' or 'rad', got {units!r}")
