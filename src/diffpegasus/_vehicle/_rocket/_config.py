"""A rocket's facts from its `rocket.toml`: masses, motor, launch rail, site, drag.

The file is the documented template (see the rockets guide); only these keys are
read, every other key is kept for people:

    [rocket]  mass_without_motor_kg, radius_m
    [motor]   thrust_file, propellant_initial_mass_kg (default: a RASP file's
              header), dry_mass_kg (default 0),
              holddown_time_s (default 0: the motor lifts off as soon as thrust
              exceeds weight)
    [geometry] nose, fins (trapezoidal, elliptical or free-form: see `_barrowman`
              and `_fins`), tail or transition, motor_center_of_mass_m (m, the
              loaded motor's centre of mass), motor_inertia_kgm2 (optional), with
              [rocket] I11_kgm2, center_of_mass_without_motor_m and the top-level
              coordinate_system: the attitude (see `_barrowman`); optional
    [aero]    power_off_drag_file, power_on_drag_file (optional; the team's curves),
              air_brakes_actuation_file (optional, time s / deployment 0-1),
              air_brakes_table (optional, deployment 0-1 / Mach / CD rows: the
              team's drag with the brakes out)
    [launch]  elevation_m, rail_length_m, inclination_deg (from horizontal),
              heading_deg (from north), latitude_deg (optional: gravity)
    [atmosphere] surface_temperature_K (or a notebook_surface_conditions text
              "T 299.96 K, ..." or era5_near_surface_temperature_K); optional
    [results] recorded_apogee_agl_m, preflight_simulated_apogee_agl_m (optional)
    [[parachutes]] cd_s_m2 (or cd_s_m2_design), trigger_altitude_agl_m (optional,
              a main's deployment height), lag_s (optional, s from the event to
              the canopy full, as RocketPy's), in deployment order; optional

Paths are relative to the file's folder.
"""

import pathlib
import re
import tomllib

import equinox as eqx
import numpy as np

from ..._errors import LogError
from .._atmosphere import G0
from ._barrowman import Airframe, read_airframe
from ._drag import read_drag_curve
from ._motor import Motor, read_motor
from ._rows import read_rows


class Rocket(eqx.Module):
    """One rocket on one launch: the facts the model needs.

    **Fields:**

    - `name`.
    - `dry_mass`: kg, the rocket with its empty motor casing.
    - `motor`: the [`Motor`][] (propellant mass, thrust curve).
    - `radius`: m, reference radius (reference area `pi radius^2`).
    - `holddown`: s from ignition to release (a liquid engine on a hold-down).
    - `elevation`: m above sea level of the pad.
    - `rail_length`: m the rocket travels along the rail before it is free: the
      rail's length, less the upper rail button's distance from the nozzle where the
      file gives both (`[rocket] rail_buttons_m`, `[geometry] nozzle_position_m`: the
      rocket leaves the rail when that button does, as in RocketPy);
      `inclination`: deg from horizontal; `heading`: deg from north.
    - `surface_temperature`: K at the pad, or `None` (then the standard atmosphere's
      at the pad's pressure).
    - `team_drag_off`, `team_drag_on`: the team's `(mach, cd)` tables or `None`.
    - `airbrakes`: `(time s, deployment 0-1)` schedule or `None`.
    - `airbrake_table`: the team's air-brake drag, `(deployment (d,), increment
      (d,))`: the CD the brakes add at each deployment, averaged over the table's
      Mach numbers (`CD(d, Mach) - CD(0, Mach)`), or `None`.
    - `recorded_apogee`, `preflight_apogee`: m AGL from the team, or `None`.
    - `folder`: where the file was.
    - `airframe`: the [`Airframe`][] (surfaces and mass distribution) when the
      file gives one, else `None` (the rocket points along its air-relative velocity).
    - `latitude`: deg, the pad's geodetic latitude (gravity from the WGS84 ellipsoid
      there), or `None` (standard gravity, 9.80665 m/s^2 at sea level).
    - `parachutes`: `((CdS m^2 or None, deployment height m AGL or None), ...)`
      in the file's order (the drogue first), `()` without.
    - `parachute_lags`: s from each stage's event to its canopy full (`lag_s`), or
      `None` where the file gives none, in the same order.
    """

    name: str = eqx.field(static=True)
    dry_mass: float = eqx.field(static=True)
    motor: Motor
    radius: float = eqx.field(static=True)
    holddown: float = eqx.field(static=True)
    elevation: float = eqx.field(static=True)
    rail_length: float = eqx.field(static=True)
    inclination: float = eqx.field(static=True)
    heading: float = eqx.field(static=True)
    surface_temperature: float | None = eqx.field(static=True)
    team_drag_off: tuple | None
    team_drag_on: tuple | None
    airbrakes: tuple | None
    recorded_apogee: float | None = eqx.field(static=True)
    preflight_apogee: float | None = eqx.field(static=True)
    folder: str = eqx.field(static=True, default=".")
    latitude: float | None = eqx.field(static=True, default=None)
    airframe: Airframe | None = None
    airbrake_table: tuple | None = None
    parachutes: tuple = eqx.field(static=True, default=())
    parachute_lags: tuple = eqx.field(static=True, default=())

    @property
    def loaded_mass(self) -> float:
        """kg at ignition."""
        return self.dry_mass + self.motor.propellant_mass

    @property
    def area(self) -> float:
        """m^2, the reference area."""
        return float(np.pi * self.radius**2)


# deg: the lowest rail the logs' readers take (an accelerometer on it reads 0.6 g)
RAIL_LOWEST = 37.0
# m: a radius above the widest rockets flown (Saturn V and Starship, 5.05 and 4.5 m)
RADIUS_WIDEST = 6.0


def _number(table, key, path, section, default=None, positive=True):
    if key not in table:
        if default is not None:
            return default
        raise LogError(f"{path}: [{section}] needs {key}")
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, int | float):
        # a value given is read, never replaced by the default
        raise LogError(f"{path}: [{section}] {key} = {v!r} is not a number")
    v = float(v)
    if not np.isfinite(v):
        raise LogError(f"{path}: [{section}] {key} = {v!r} is not a finite number")
    if positive and v <= 0:
        raise LogError(f"{path}: [{section}] {key} = {v!r} must be positive")
    return v


def _optional(table, key, path=None, section=""):
    """The number at `key`, or `None` where the file gives none or a note (text such
    as "not given"). Text that reads as a number (`"2789"`) is refused rather than
    dropped: the file meant a number."""
    v = table.get(key)
    if isinstance(v, str) and path is not None:
        try:
            float(v)
        except ValueError:
            return None
        raise LogError(
            f"{path}: [{section}] {key} = {v!r} is text; write the number without "
            "quotes"
        )
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else None


# the keys read from each table (every other key is a note for people), so that a
# misspelt one is refused instead of silently ignored
KEYS = {
    "rocket": (
        "mass_without_motor_kg",
        "radius_m",
        "I11_kgm2",
        "center_of_mass_without_motor_m",
        "rail_buttons_m",
    ),
    "motor": (
        "thrust_file",
        "propellant_initial_mass_kg",
        "dry_mass_kg",
        "holddown_time_s",
    ),
    "aero": (
        "power_off_drag_file",
        "power_on_drag_file",
        "air_brakes_actuation_file",
        "air_brakes_table",
    ),
    "launch": (
        "elevation_m",
        "rail_length_m",
        "inclination_deg",
        "heading_deg",
        "latitude_deg",
    ),
    "atmosphere": ("surface_temperature_K", "era5_near_surface_temperature_K"),
    "results": ("recorded_apogee_agl_m", "preflight_simulated_apogee_agl_m"),
    "geometry": (
        "nose",
        "fins",
        "tail",
        "transition",
        "nozzle_position_m",
        "motor_center_of_mass_m",
        "motor_inertia_kgm2",
    ),
}
# the keys read from each [[parachutes]] stage
PARACHUTE_KEYS = ("cd_s_m2", "cd_s_m2_design", "trigger_altitude_agl_m", "lag_s")
# m: the pad's elevation, from the Dead Sea shore to the highest ground
ELEVATION_RANGE = (-500.0, 9000.0)


def _edits(a: str, b: str) -> int:
    """Levenshtein distance between two short strings."""
    row = list(range(len(b) + 1))
    for i, ca in enumerate(a, 1):
        prev, row[0] = row[0], i
        for j, cb in enumerate(b, 1):
            prev, row[j] = row[j], min(row[j] + 1, row[j - 1] + 1, prev + (ca != cb))
    return row[-1]


_DATUMS = {"agl", "asl", "msl"}


def _near(key: str, known: str) -> bool:
    """`key` (not `known` itself) is `known` in other letter case, or one or two
    letters from it and not a sibling quantity: one that differs only in its digits
    (`I33_kgm2` beside `I11_kgm2`), in its unit (`elevation_ft` beside
    `elevation_m`, `surface_temperature_C`) or in its datum (`..._asl_m` beside
    `..._agl_m`), which a note may well be."""
    a, b = key.lower(), known.lower()
    if a == b:
        return True
    strip = str.maketrans("", "", "0123456789")
    if a.translate(strip) == b.translate(strip) or _edits(a, b) > 2:
        return False
    ta, tb = a.split("_"), b.split("_")
    if len(ta) == len(tb):
        differ = [i for i, (x, y) in enumerate(zip(ta, tb, strict=True)) if x != y]
        if differ == [len(ta) - 1] or (
            len(differ) == 1 and {ta[differ[0]], tb[differ[0]]} <= _DATUMS
        ):
            return False
    return True


def _tables(doc, path) -> dict:
    """The tables the model reads (`{}` where absent), each checked to be a table,
    and none holding a key one or two letters from a key it reads (a misspelling
    would leave the value unread, or a default in its place)."""
    out = {}
    for section, keys in KEYS.items():
        table = doc.get(section, {})
        if not isinstance(table, dict):
            raise LogError(
                f"{path}: {section} = {table!r} is not a table (write [{section}] "
                "with its keys below it)"
            )
        _misspelt(table, keys, path, f"[{section}]")
        out[section] = table
    return out


def _lifts(motor, loaded: float, holddown: float, path) -> None:
    """Refuse a rocket its motor cannot lift off once released: the peak thrust
    from the release on (the hold-down's end, else ignition) against the weight
    then (the propellant burned on the hold-down gone)."""
    t, f, burned = motor.tables()
    after = np.r_[np.interp(holddown, t, f), f[t > holddown]]
    mass = loaded - motor.propellant_mass * float(np.interp(holddown, t, burned))
    if not np.max(after) > mass * G0:
        when = "at ignition" if holddown == 0 else f"after its {holddown:g} s hold-down"
        raise LogError(
            f"{path}: the motor's peak thrust {np.max(after):g} N {when} "
            f"({motor.name}) does not lift the {mass:g} kg rocket (its weight is "
            f"{mass * G0:g} N): a mass in grams ([rocket] mass_without_motor_kg), a "
            "thrust curve in other units, or a hold-down past the burn?"
        )


def _misspelt(table: dict, keys, path, where: str) -> None:
    """Refuse a key of `table` one or two letters from one of `keys` (see `_near`)."""
    for key in table:
        if key in keys:
            continue
        near = [k for k in keys if _near(key, k)]
        if near:
            raise LogError(
                f"{path}: {where} {key} is not a key the rocket is read from; did "
                f"you mean {near[0]}? (rename a note so it is not one or two "
                "letters from a key)"
            )


def _file(table, key, folder, path, section) -> pathlib.Path:
    """The file `table[key]` names, relative to the rocket file's folder."""
    v = table[key]
    if not isinstance(v, str) or not v.strip():
        raise LogError(f"{path}: [{section}] {key} = {v!r} is not a file name")
    return folder / v


def _latitude(table, path):
    # optional, but a value given is a number of degrees, never silently dropped
    if "latitude_deg" not in table:
        return None
    v = _number(table, "latitude_deg", path, "launch", positive=False)
    if abs(v) > 90.0:
        raise LogError(f"{path}: [launch] latitude_deg = {v!r} is not in -90..90")
    return v


def _button_offset(rk, geometry, path) -> float:
    """m from the nozzle to the upper (furthest from it) rail button, 0 unless the
    file gives `[rocket] rail_buttons_m` and `[geometry] nozzle_position_m`."""
    buttons, nozzle = rk.get("rail_buttons_m"), geometry.get("nozzle_position_m")
    if buttons is None or nozzle is None:
        return 0.0
    try:
        far = max(abs(float(b) - float(nozzle)) for b in buttons)
    except (TypeError, ValueError):
        raise LogError(
            f"{path}: [rocket] rail_buttons_m = {buttons!r} and [geometry] "
            f"nozzle_position_m = {nozzle!r} must be numbers"
        ) from None
    return far


def _airbrake_table(folder, ae, path) -> tuple | None:
    """The team's air-brake table (rows deployment 0-1, Mach, CD; a header row
    allowed) as `(deployment, increment)`: the CD the brakes add at each
    deployment over the closed brakes' at the same Mach, averaged over Mach."""
    if "air_brakes_table" not in ae:
        return None
    file = _file(ae, "air_brakes_table", folder, path, "aero")
    a, lines, _ = read_rows(
        file, ("deployment 0-1", "Mach", "CD"), "the air-brake table"
    )
    _deployments_within_0_1(file, a[:, 0], lines)
    for level in (0.0, 1.0):
        if not np.any(a[:, 0] == level):
            raise LogError(
                f"{file}: no rows at deployment {level:g} (the closed brakes' CD and "
                "the fully deployed brakes' are both needed)"
            )
    levels = np.unique(a[:, 0])
    inc = []
    for d in levels:
        rows = a[a[:, 0] == d]
        closed = a[a[:, 0] == 0]
        base = np.interp(rows[:, 1], *closed[np.argsort(closed[:, 1]), 1:3].T)
        inc.append(float(np.mean(rows[:, 2] - base)))
    if inc[-1] <= 0:
        raise LogError(
            f"{file}: the fully deployed brakes add CD {inc[-1]:g} over the closed "
            "ones (averaged over Mach): not a drag increase"
        )
    return levels, np.asarray(inc)


def _deployments_within_0_1(file, deployment, lines):
    bad = np.flatnonzero((deployment < 0) | (deployment > 1))
    if len(bad):
        j = bad[0]
        raise LogError(
            f"{file}: row {lines[j]}: deployment {deployment[j]:g} is not within 0-1"
        )


def read_toml(path: pathlib.Path) -> dict:
    """A `rocket.toml`'s tables (UTF-8, with or without a byte-order mark); a file
    that cannot be read, is not UTF-8 or not TOML raises a `LogError` in one line."""
    try:
        return tomllib.loads(path.read_bytes().decode("utf-8-sig"))
    except OSError as e:
        raise LogError(f"{path}: cannot read ({e.strerror})") from None
    except UnicodeDecodeError as e:
        raise LogError(
            f"{path}: not UTF-8 text (byte {e.start + 1} is 0x{e.object[e.start]:02x}"
            "; a Latin-1 or Windows-1252 file, or not a text file): save it as UTF-8"
        ) from None
    except tomllib.TOMLDecodeError as e:
        raise LogError(f"{path}: not valid TOML ({e})") from None


def read_rocket(path, *, attitude: bool = False) -> Rocket:
    """Read a `rocket.toml` (see the module docstring for its keys).

    `attitude=True` reads the [geometry] section into an [`Airframe`][]: the
    rocket then weathercocks with Barrowman's normal force (six more states; a fit
    takes about 20 times as long). By default, and where the file lacks those keys,
    the rocket points along its air-relative velocity.

    **Returns:** a [`Rocket`][]. A missing or implausible value raises a `LogError`
    naming the file, section and key.
    """
    path = pathlib.Path(path)
    doc = read_toml(path)
    folder = path.parent
    tables = _tables(doc, path)
    rk, mo, ae = tables["rocket"], tables["motor"], tables["aero"]
    la, at, rs = tables["launch"], tables["atmosphere"], tables["results"]
    if "thrust_file" not in mo:
        raise LogError(f"{path}: [motor] needs thrust_file")
    thrust_file = _file(mo, "thrust_file", folder, path, "motor")
    prop = None  # a RASP file's header gives it where the key is absent
    if "propellant_initial_mass_kg" in mo or thrust_file.suffix.lower() != ".eng":
        prop = _number(mo, "propellant_initial_mass_kg", path, "motor")
    motor_dry = _number(mo, "dry_mass_kg", path, "motor", default=0.0, positive=False)
    if motor_dry < 0:
        raise LogError(f"{path}: [motor] dry_mass_kg = {motor_dry:g} is negative")
    try:
        motor = read_motor(thrust_file, propellant_mass=prop, dry_mass=motor_dry)
    except LogError as e:
        if prop is None and "give the propellant mass" in str(e):
            raise LogError(
                f"{path}: [motor] needs propellant_initial_mass_kg: {e}"
            ) from None
        if prop is not None and "specific impulse" in str(e):
            raise LogError(
                f"{path}: [motor] propellant_initial_mass_kg = {prop:g} with {e}"
            ) from None
        raise
    prop = motor.propellant_mass
    rocket_mass = _number(rk, "mass_without_motor_kg", path, "rocket")
    holddown = _number(
        mo, "holddown_time_s", path, "motor", default=0.0, positive=False
    )
    if holddown < 0:
        raise LogError(f"{path}: [motor] holddown_time_s = {holddown:g} is negative")
    _lifts(motor, rocket_mass + motor_dry + prop, holddown, path)
    inclination = _number(la, "inclination_deg", path, "launch")
    if not 0 < inclination <= 90:
        raise LogError(
            f"{path}: [launch] inclination_deg = {inclination:g} must be "
            "in (0, 90] degrees from horizontal"
        )
    if inclination < RAIL_LOWEST:
        # the logs' readers take rails 37-90 degrees up (an axial accelerometer on
        # the pad reads 0.6-1 g); an angle this low is more likely one from the
        # vertical, as OpenRocket's launch rod angle is
        raise LogError(
            f"{path}: [launch] inclination_deg = {inclination:g} puts the rail "
            f"{inclination:g} deg above the ground (below {RAIL_LOWEST:g}); it is "
            f"degrees from horizontal: a rail {inclination:g} deg from the vertical "
            f"(OpenRocket's launch rod angle) is inclination_deg = {90 - inclination:g}"
        )
    radius = _number(rk, "radius_m", path, "rocket")
    if radius > RADIUS_WIDEST:
        raise LogError(
            f"{path}: [rocket] radius_m = {radius:g} m is wider than any rocket "
            f"flown ({RADIUS_WIDEST:g} m); give metres ({radius:g} mm is "
            f"{radius / 1000:g} m)"
        )
    temperature = _optional(at, "surface_temperature_K", path, "atmosphere")
    if temperature is None:
        text = str(at.get("notebook_surface_conditions", ""))
        m = re.search(r"\bT\s*([0-9.]+)\s*K", text)
        temperature = (
            float(m.group(1))
            if m
            else _optional(at, "era5_near_surface_temperature_K", path, "atmosphere")
        )
    if temperature is not None and not 180 < temperature < 340:
        raise LogError(
            f"{path}: [atmosphere] surface temperature {temperature:g} K "
            "is not plausible (give kelvin)"
        )

    def drag(key):
        if key not in ae:
            return None
        return read_drag_curve(_file(ae, key, folder, path, "aero"))

    elevation = _number(la, "elevation_m", path, "launch", default=0.0, positive=False)
    if not ELEVATION_RANGE[0] <= elevation <= ELEVATION_RANGE[1]:
        raise LogError(
            f"{path}: [launch] elevation_m = {elevation:g} is not a pad's elevation "
            f"({ELEVATION_RANGE[0]:g} to {ELEVATION_RANGE[1]:g} m above sea level; "
            "give metres)"
        )
    brakes = None
    if "air_brakes_actuation_file" in ae:
        file = _file(ae, "air_brakes_actuation_file", folder, path, "aero")
        a, lines, _ = read_rows(
            file, ("time s", "deployment 0-1"), "the air-brake schedule"
        )
        if len(a) < 2:
            raise LogError(
                f"{file}: one row: a schedule needs rows from the brakes' first "
                "command to their last (closed before the first and after the last)"
            )
        back = np.flatnonzero(np.diff(a[:, 0]) < 0)
        if len(back):
            j = back[0] + 1
            raise LogError(
                f"{file}: row {lines[j]}: time {a[j, 0]:g} s is before the row "
                f"above's {a[j - 1, 0]:g} s"
            )
        _deployments_within_0_1(file, a[:, 1], lines)
        brakes = (a[:, 0], a[:, 1])
    return Rocket(
        name=str(doc.get("name", path.parent.name)),
        dry_mass=rocket_mass + motor_dry,
        motor=motor,
        radius=radius,
        holddown=holddown,
        elevation=elevation,
        rail_length=_number(la, "rail_length_m", path, "launch")
        - _button_offset(rk, doc.get("geometry", {}), path),
        inclination=inclination,
        heading=_number(la, "heading_deg", path, "launch", default=0.0, positive=False),
        surface_temperature=temperature,
        team_drag_off=drag("power_off_drag_file"),
        team_drag_on=drag("power_on_drag_file"),
        airbrakes=brakes,
        recorded_apogee=_optional(rs, "recorded_apogee_agl_m", path, "results"),
        preflight_apogee=_optional(
            rs, "preflight_simulated_apogee_agl_m", path, "results"
        ),
        folder=str(folder),
        latitude=_latitude(la, path),
        airframe=read_airframe(doc, path, radius) if attitude else None,
        airbrake_table=_airbrake_table(folder, ae, path),
        parachutes=_parachutes(doc, path),
        parachute_lags=_parachute_lags(doc, path),
    )


def _parachutes(doc, path) -> tuple:
    """`((CdS or None, deployment height or None), ...)` from `[[parachutes]]`, in
    stage order. A single `[parachutes]` table without a stage's keys (a note that
    the flight had none) gives none; a number that is not one is refused."""
    chutes = doc.get("parachutes", [])
    keys = PARACHUTE_KEYS
    if isinstance(chutes, dict):
        if any(k in chutes for k in keys):
            raise LogError(
                f"{path}: [parachutes] is one table; write each stage as its own "
                "[[parachutes]] (drogue first)"
            )
        return ()
    if not isinstance(chutes, list):
        raise LogError(f"{path}: parachutes = {chutes!r} is not a list of stages")
    out = []
    for k, c in enumerate(chutes, 1):
        if not isinstance(c, dict):
            raise LogError(f"{path}: [[parachutes]] entry {k} = {c!r} is not a table")
        _misspelt(c, keys, path, f"[[parachutes]] entry {k}:")
        for key in keys:
            v = c.get(key)
            if v is not None and (
                isinstance(v, bool)
                or not isinstance(v, int | float)
                or not np.isfinite(v)
            ):
                raise LogError(
                    f"{path}: [[parachutes]] entry {k}: {key} = {v!r} is not a number"
                )
        cds = _optional(c, "cd_s_m2")
        if cds is None:
            cds = _optional(c, "cd_s_m2_design")
        if cds is not None and not cds > 0:
            raise LogError(
                f"{path}: [[parachutes]] entry {k}: cd_s_m2 = {cds:g} must be > 0"
            )
        height = _optional(c, "trigger_altitude_agl_m")
        if height is not None and not height > 0:
            raise LogError(
                f"{path}: [[parachutes]] entry {k}: trigger_altitude_agl_m = "
                f"{height:g} must be above the pad (> 0)"
            )
        out.append((cds, height))
    return tuple(out)


def _parachute_lags(doc, path) -> tuple:
    """s per stage from `[[parachutes]]`' `lag_s` (`None` where not given); the
    entries are checked by [`_parachutes`][] first."""
    chutes = doc.get("parachutes", [])
    if not isinstance(chutes, list):
        return ()
    out = []
    for k, c in enumerate(chutes, 1):
        lag = _optional(c, "lag_s")
        if lag is not None and lag < 0:
            raise LogError(
                f"{path}: [[parachutes]] entry {k}: lag_s = {lag:g} must be >= 0 "
                "(s from the event to the canopy full)"
            )
        out.append(lag)
    return tuple(out)
