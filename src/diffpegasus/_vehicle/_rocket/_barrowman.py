"""A rocket's normal force and its centre of pressure from its geometry (Barrowman).

Each aerodynamic surface (nose, fins, tail or transition) contributes a normal-force
slope `CN_alpha` (per radian, on the reference area `pi radius^2`) at its own centre
of pressure; the attitude motion in the model takes the force of each at its station
with the local angle of attack, so the restoring moment and the pitch damping (the
rotation's contribution to each station's angle of attack) come from one set of
numbers.

- Nose: `CN_alpha = 2` at `k length` behind the tip, `k` by kind (Barrowman's and
  the usual values: conical 2/3, ogive and tangent 0.466, von Karman, parabolic and
  power 1/2 0.5, LV-Haack 0.437, elliptical 1/3).
- Fins (trapezoidal, elliptical or free-form: see `_fins`, one strip integration
  that is Barrowman's closed form for a trapezoid): per pair `2 pi AR (Af/Aref) /
  (2 + sqrt(4 + (beta AR / cos G)^2))` (Diederich's planform correlation), `AR =
  2 span^2 / Af`, `G` the mid-chord sweep; `n/2` pairs (fewer for 5 to 8 fins);
  the body interference `1 + R / (span + R)`; centre of pressure at the mean
  aerodynamic chord's quarter chord. `beta` is `sqrt(1 - M^2)` below Mach 0.8, its
  Mach 0.8 value to 1.1, `sqrt(M^2 - 1)` above.
- Tail or transition from diameter `d1` (forward) to `d2`: `CN_alpha = 2 ((d2/d)^2
  - (d1/d)^2)` at `L/3 (1 + (1 - r) / (1 - r^2))` behind its forward end, `r = d1/d2`.

Positions in the file are along the rocket's axis in its `coordinate_system`
(`"tail_to_nose"`: larger is further forward; `"nose_to_tail"`: larger is further
aft); here every position is turned into metres *forward* (the tail-to-nose sense).
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._errors import LogError
from ._fins import (
    ellipse_strips,
    fin_constants,
    polygon_strips,
    trapezoid_strips,
)


NOSE_K = {
    "conical": 2 / 3,
    "cone": 2 / 3,
    "ogive": 0.466,
    "tangent": 0.466,
    "vonkarman": 0.5,
    "parabolic": 0.5,
    "powerseries": 0.5,
    "lvhaack": 0.437,
    "elliptical": 1 / 3,
}


def nose_cp(kind: str, length: float) -> float:
    """m behind the tip, the nose's centre of pressure for a nose of `kind`."""
    key = "".join(c for c in kind.lower() if c.isalpha())
    if key not in NOSE_K:
        raise ValueError(f"nose kind {kind!r}: not one of {sorted(NOSE_K)}")
    return NOSE_K[key] * length


def beta(mach):
    """Prandtl-Glauert factor as RocketPy and Barrowman take it (see the module)."""
    sub = jnp.sqrt(jnp.clip(1 - jnp.minimum(mach, 0.8) ** 2, 1e-9, None))
    sup = jnp.sqrt(jnp.clip(mach**2 - 1, 1e-9, None))
    return jnp.where(mach < 1.1, sub, sup)


class Airframe(eqx.Module):
    """A rocket's aerodynamic surfaces and mass distribution along its axis.

    **Fields** (positions m forward, in the file's origin):

    - `stations` `(k,)`: each surface's centre of pressure.
    - `cn_const` `(k,)`: each surface's Mach-independent `CN_alpha` (nose, tails);
      `fin_a`, `fin_b` `(k,)`: the fins' Diederich constants (0 for other surfaces).
    - `cg_rocket`: the rocket without motor's centre of mass; `inertia`: kg m^2 its
      lateral moment of inertia there; `motor_cg`: the motor's (casing and
      propellant) centre of mass; `motor_inertia`: kg m^2 the loaded motor's lateral
      inertia about its own centre of mass (its propellant part falls with the
      propellant mass).
    """

    stations: tuple = eqx.field(static=True)
    cn_const: tuple = eqx.field(static=True)
    fin_a: tuple = eqx.field(static=True)
    fin_b: tuple = eqx.field(static=True)
    cg_rocket: float = eqx.field(static=True)
    inertia: float = eqx.field(static=True)
    motor_cg: float = eqx.field(static=True)
    motor_inertia: float = eqx.field(static=True, default=0.0)

    def cn_alpha(self, mach):
        """`(k,)` each surface's `CN_alpha` per radian at `mach`."""
        b = beta(mach)
        fb = jnp.asarray(self.fin_b)
        fins = jnp.asarray(self.fin_a) / (2 + jnp.sqrt(4 + (b * fb) ** 2))
        return jnp.asarray(self.cn_const) + fins

    def center_of_pressure(self, mach) -> float:
        """m forward, the whole rocket's centre of pressure at `mach`."""
        c = self.cn_alpha(mach)
        return float(jnp.sum(c * jnp.asarray(self.stations)) / jnp.sum(c))


def fin_strips(fins: dict, num):
    """The strips (see `_fins`) of a `[geometry] fins` table: `shape_points_m` (a
    free-form outline), `kind` naming an ellipse (`root_chord_m`, `span_m`), else a
    trapezoid (`root_chord_m`, `tip_chord_m`, `span_m`, optional `sweep_length_m`
    or `sweep_angle_deg`; default the trailing edge square to the body). `num(key)`
    reads one number. A planform that cannot be built raises `ValueError`."""
    kind = "".join(c for c in str(fins.get("kind", "")).lower() if c.isalpha())
    if "shape_points_m" in fins:
        try:
            points = np.asarray(fins["shape_points_m"], dtype=float)
        except (TypeError, ValueError):
            raise ValueError(
                f"shape_points_m = {fins['shape_points_m']!r} is not a list of "
                "[x, y] pairs of numbers"
            ) from None
        try:
            return polygon_strips(points)
        except ValueError as e:
            raise ValueError(f"shape_points_m: {e}") from None
    if kind.startswith("freeform"):
        raise ValueError(f"kind = {fins['kind']!r} needs shape_points_m")
    root, span = num("root_chord_m"), num("span_m")
    if not (root > 0 and span > 0):
        raise ValueError(
            f"root_chord_m = {root:g} and span_m = {span:g}: both must be positive"
        )
    if kind.startswith("ellip"):
        return ellipse_strips(root, span)
    if kind and not kind.startswith("trapez"):
        raise ValueError(
            f"kind = {fins['kind']!r} is not trapezoidal, elliptical or free-form"
        )
    tipc = num("tip_chord_m")
    if not tipc >= 0:
        raise ValueError(f"tip_chord_m = {tipc:g} is negative")
    if "sweep_length_m" in fins:
        sweep = num("sweep_length_m")
    elif "sweep_angle_deg" in fins:
        angle = num("sweep_angle_deg")
        if not abs(angle) < 90:
            raise ValueError(f"sweep_angle_deg = {angle:g} is not within -90..90")
        sweep = span * np.tan(np.radians(angle))
    else:
        sweep = root - tipc  # trailing edge square to the body
    return trapezoid_strips(root, tipc, span, sweep)


def read_airframe(doc: dict, path, radius: float) -> Airframe | None:
    """The [`Airframe`][] of a parsed `rocket.toml` `doc`, or `None` when it lacks
    the keys the attitude needs ([geometry] nose and fins, [rocket] `I11_kgm2` and
    `center_of_mass_without_motor_m`, [geometry] `motor_center_of_mass_m`)."""
    geo, rk = doc.get("geometry", {}), doc.get("rocket", {})
    need = ("nose" in geo, "fins" in geo, "motor_center_of_mass_m" in geo)
    if not all(need) or "I11_kgm2" not in rk:
        return None
    if "center_of_mass_without_motor_m" not in rk:
        return None
    system = doc.get("coordinate_system", "tail_to_nose")
    if system not in ("tail_to_nose", "nose_to_tail"):
        raise LogError(
            f"{path}: coordinate_system = {system!r} is not "
            "'tail_to_nose' or 'nose_to_tail'"
        )
    s = 1.0 if system == "tail_to_nose" else -1.0

    def num(table, key, where):
        v = table.get(key)
        if isinstance(v, bool) or not isinstance(v, int | float) or v != v:
            raise LogError(f"{path}: [{where}] {key} = {v!r} is not a number")
        if abs(v) == float("inf"):
            raise LogError(f"{path}: [{where}] {key} = {v!r} is not finite")
        return float(v)

    nose, fins = geo["nose"], geo["fins"]
    stations, const, fa, fb = [], [], [], []
    tip = s * num(nose, "position_m", "geometry.nose")
    try:
        back = nose_cp(
            str(nose.get("kind", "")), num(nose, "length_m", "geometry.nose")
        )
    except ValueError as e:
        raise LogError(f"{path}: [geometry.nose] {e}") from None
    stations.append(tip - back)
    const.append(2.0)
    fa.append(0.0)
    fb.append(0.0)
    n = num(fins, "n", "geometry.fins")
    if not (np.isfinite(n) and n >= 1 and n == int(n)):
        raise LogError(f"{path}: [geometry.fins] n = {fins['n']!r} is not a count")
    try:
        a, b, cp = fin_constants(
            fin_strips(fins, lambda k: num(fins, k, "geometry.fins")),
            n,
            float(fins.get("radius_m", radius)),
            radius,
        )
    except LogError:
        raise
    except ValueError as e:
        raise LogError(f"{path}: [geometry.fins] {e}") from None
    stations.append(s * num(fins, "position_m", "geometry.fins") - cp)
    const.append(0.0)
    fa.append(float(a))
    fb.append(float(b))
    for key in ("tail", "transition"):
        if key in geo:
            t = geo[key]
            d1 = num(t, "top_radius_m", f"geometry.{key}")
            d2 = num(t, "bottom_radius_m", f"geometry.{key}")
            length = num(t, "length_m", f"geometry.{key}")
            r = d1 / d2
            back = length / 3 * (1 + (1 - r) / (1 - r**2)) if r != 1 else length / 2
            stations.append(s * num(t, "position_m", f"geometry.{key}") - back)
            const.append(2 * ((d2 / radius) ** 2 - (d1 / radius) ** 2))
            fa.append(0.0)
            fb.append(0.0)
    return Airframe(
        stations=tuple(stations),
        cn_const=tuple(const),
        fin_a=tuple(fa),
        fin_b=tuple(fb),
        cg_rocket=s * num(rk, "center_of_mass_without_motor_m", "rocket"),
        inertia=num(rk, "I11_kgm2", "rocket"),
        motor_cg=s * num(geo, "motor_center_of_mass_m", "geometry"),
        motor_inertia=float(geo.get("motor_inertia_kgm2", 0.0)),
    )
