"""The units a report shows a channel or an effect's parameter in.

A channel is shown in the unit its log gave it (the column map's `unit`, e.g. degrees
where the map said `deg`), else in the unit a person reads that kind of channel in
(angles in degrees, altitude in km), else in SI units. Numbers inside the package are
SI; `factor` converts them: `shown = factor * si`.
"""

import math
import re


# the unit a person reads each common channel in: (unit, factor from SI)
_USUAL = {
    "ax": ("m/s^2", 1.0),
    "ay": ("m/s^2", 1.0),
    "az": ("m/s^2", 1.0),
    "p": ("deg/s", math.degrees(1.0)),
    "q": ("deg/s", math.degrees(1.0)),
    "r": ("deg/s", math.degrees(1.0)),
    "pdot": ("deg/s^2", math.degrees(1.0)),
    "qdot": ("deg/s^2", math.degrees(1.0)),
    "rdot": ("deg/s^2", math.degrees(1.0)),
    "alpha": ("deg", math.degrees(1.0)),
    "beta": ("deg", math.degrees(1.0)),
    "theta": ("deg", math.degrees(1.0)),
    "phi": ("deg", math.degrees(1.0)),
    "psi": ("deg", math.degrees(1.0)),
    "de": ("deg", math.degrees(1.0)),
    "da": ("deg", math.degrees(1.0)),
    "dr": ("deg", math.degrees(1.0)),
    "V": ("m/s", 1.0),
    "h": ("km", 1e-3),
    "mach": ("-", 1.0),
    "qbar": ("kPa", 1e-3),
    "thrust": ("kN", 1e-3),
    "t": ("s", 1.0),
}


def channel_units(names, columns=None) -> dict[str, tuple[str, float]]:
    """`{channel: (unit, factor from SI)}` for every name in `names`.

    **Arguments:** `names`, channel names; `columns`, the column map the log was read
    through (a dict, a JSON/TOML path or `None`): a channel it gives a unit is shown
    in that unit.
    """
    mapped = {}
    if columns is not None:
        try:
            from .._log._columns import load_columns, UNITS

            for ch, col in load_columns(columns).items():
                unit = (col.unit or "").strip()
                if unit and unit.lower() not in ("", "1", "-", "si"):
                    mapped[ch] = (unit, 1.0 / UNITS[unit.lower()])
        except Exception:  # a report never fails on its units: fall back to SI
            mapped = {}
    return {n: mapped.get(n) or _USUAL.get(n) or ("SI", 1.0) for n in names}


def effect_unit(effect: str) -> str:
    """The unit of a library effect's parameter as its description states it
    (`"... by tau (s)"` gives `"s"`); `""` for a dimensionless coefficient, and
    `"channel units"` for a sensor bias."""
    from .._vehicle._effects import EFFECTS

    cls = EFFECTS.get(effect.split(":", 1)[0])
    if cls is None:
        return ""
    found = re.search(
        rf"\b{re.escape(cls.parameter)}\s*\(([^)]+)\)", cls.description
    ) or re.search(r"\(([^)]*units?)\)", cls.description)
    return found.group(1) if found else ""


def with_unit(value: float, unit: str, fmt: str = ".4g") -> str:
    """`value` and its unit as a person writes them (no unit when dimensionless)."""
    text = format(value, fmt)
    return f"{text} {unit}" if unit and unit != "-" else text
