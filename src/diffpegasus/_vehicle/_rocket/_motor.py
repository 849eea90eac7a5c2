"""A rocket motor: thrust against time and the propellant it has burned.

The thrust curve comes from a RASP `.eng` file (the format of thrustcurve.org and
OpenRocket) or a two-column CSV (time s, thrust N; an optional header row). The
propellant mass falls in proportion to the impulse delivered so far, the usual
assumption when only the thrust curve is known (constant effective exhaust velocity).
"""

import pathlib

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._errors import LogError
from .._atmosphere import G0
from ._rows import read_rows


# negative thrust read as a load cell's zero drift (no thrust) up to this fraction
# of the peak
_DRIFT = 0.05
# s: specific impulses of rocket motors, from the weakest sugar propellants
# (about 100 s; the shipped flights 135-256 s) to hydrogen-oxygen in vacuum (465 s)
ISP_RANGE = (60.0, 500.0)
# N: more than any motor flown (a Saturn V's first stage, 35 MN; Starship's 75 MN)
THRUST_LARGEST = 1e8


class Motor(eqx.Module):
    """A motor's thrust curve and masses.

    **Fields:**

    - `time` `(points,)`: s from ignition, increasing.
    - `thrust` `(points,)`: N at `time`; zero before the first and after the last point.
    - `propellant_mass`: kg at ignition.
    - `dry_mass`: kg of the casing (0 when the rocket's dry mass includes it).
    - `name`: what reports call it.
    """

    time: np.ndarray
    thrust: np.ndarray
    propellant_mass: float = eqx.field(static=True)
    dry_mass: float = eqx.field(static=True, default=0.0)
    name: str = eqx.field(static=True, default="motor")

    def __check_init__(self):
        if len(self.time) < 2 or np.any(np.diff(self.time) <= 0):
            raise ValueError(f"{self.name}: thrust-curve times must increase")
        if np.any(self.thrust < 0):
            raise ValueError(f"{self.name}: negative thrust in the curve")

    @property
    def total_impulse(self) -> float:
        """N s, the trapezoidal integral of the curve (with the zero ends)."""
        t, f = self._closed()
        return float(np.trapezoid(f, t))

    @property
    def burn_time(self) -> float:
        """s from ignition to the last point of the curve."""
        return float(self.time[-1])

    def _closed(self):
        """The curve with zero thrust added at ignition and after the end."""
        t, f = np.asarray(self.time, float), np.asarray(self.thrust, float)
        if t[0] > 0:
            t, f = np.r_[0.0, t], np.r_[0.0 if f[0] > 0 else f[0], f]
            t, f = t, f
        if f[-1] != 0:
            t, f = np.r_[t, t[-1] + 1e-3], np.r_[f, 0.0]
        return t, f

    def tables(self):
        """`(time, thrust, burned)` arrays of the closed curve: `burned` the fraction
        of the total impulse delivered by `time` (0 to 1)."""
        t, f = self._closed()
        impulse = np.r_[0.0, np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(t))]
        return t, f, impulse / impulse[-1]


def motor_at(tables, t, stretch=1.0):
    """Thrust (N) and burned impulse fraction at `t` s from ignition (jax, scalar)
    of the curve stretched in time by `stretch` (burn time over the curve's): the
    thrust `F(t / stretch) / stretch`, the impulse kept, and the fraction burned
    `B(t / stretch)`. A solid motor's grain temperature does this: a cold motor
    burns longer at lower thrust, a hot one shorter and harder, at nearly the same
    impulse."""
    time, thrust, burned = tables
    tc = t / stretch
    f = jnp.interp(tc, time, thrust, left=0.0, right=0.0) / stretch
    b = jnp.interp(tc, time, burned, left=0.0, right=1.0)
    return f, b


def read_motor(path, *, propellant_mass=None, dry_mass=0.0) -> Motor:
    """Read a thrust curve from a RASP `.eng` file or a two-column CSV.

    **Arguments:**

    - `path`: the file.
    - `propellant_mass`: kg; by default the `.eng` header's (a CSV needs it given).
    - `dry_mass`: kg of the empty casing.

    Thrust below zero by at most 5 % of the peak (a static fire's load cell drifting
    below its zero at ignition or tail-off) is read as 0.

    **Returns:** a [`Motor`][]. A malformed file raises a `LogError` naming the file,
    row and value.
    """
    path = pathlib.Path(path)
    a, _, header = read_rows(
        path,
        ("time s", "thrust N"),
        "the thrust curve",
        header_first=path.suffix.lower() == ".eng",
    )
    if len(a) < 2:
        raise LogError(f"{path}: fewer than two thrust points")
    t, f = a[:, 0], a[:, 1]
    if np.any(np.diff(t) <= 0):
        i = int(np.argmax(np.diff(t) <= 0)) + 1
        raise LogError(
            f"{path}: thrust-curve time does not increase at point {i + 1} "
            f"(t = {t[i]:g} s)"
        )
    if np.any(f < 0):
        # a static fire's load cell drifts below its zero at ignition and tail-off
        # by a few percent of the peak: no thrust there. A larger negative is a
        # wrong column or sign.
        i = int(np.argmin(f))
        if -f[i] > _DRIFT * f.max():
            raise LogError(
                f"{path}: negative thrust {f[i]:g} N at t = {t[i]:g} s, more than "
                f"{_DRIFT:.0%} of the peak {f.max():g} N (a load cell's drift is "
                "less): check the columns and the sign"
            )
        f = np.maximum(f, 0.0)
    if not np.any(f > 0):
        raise LogError(f"{path}: every thrust point is 0 N: the curve has no impulse")
    if np.max(f) > THRUST_LARGEST:
        i = int(np.argmax(f))
        raise LogError(
            f"{path}: thrust {f[i]:g} N at t = {t[i]:g} s is more than any motor "
            f"gives ({THRUST_LARGEST:g} N); give newtons"
        )
    if propellant_mass is None:
        mass = _header_number(header, 4) if path.suffix.lower() == ".eng" else None
        if mass is None or not mass > 0:
            raise LogError(
                f"{path}: give the propellant mass (the file has none"
                + ("" if header is None else f"; header {' '.join(header)!r}")
                + ")"
            )
        propellant_mass = mass
    motor = Motor(t, f, float(propellant_mass), float(dry_mass), path.name)
    isp = motor.total_impulse / (float(propellant_mass) * G0)
    if not ISP_RANGE[0] <= isp <= ISP_RANGE[1]:
        raise LogError(
            f"{path}: the curve's impulse {motor.total_impulse:.6g} N s over the "
            f"propellant's weight ({float(propellant_mass):g} kg) is a specific "
            f"impulse of {isp:.4g} s; motors give {ISP_RANGE[0]:g}-{ISP_RANGE[1]:g} "
            "s: a thrust in lbf or kN, times in ms, or the propellant mass in other "
            "units?"
        )
    return motor


def _header_number(header, i) -> float | None:
    """The `i`-th field of a RASP header as a finite number, else `None`."""
    try:
        v = float(header[i])
    except (TypeError, IndexError, ValueError):
        return None
    return v if np.isfinite(v) else None
