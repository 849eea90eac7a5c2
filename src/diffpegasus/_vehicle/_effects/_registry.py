"""Canonical names to effect classes, and `NAME=VALUE` parsing for the CLI."""

from ._aerodynamic import (
    AlphaDotDamping,
    DragAlphaSquared,
    DragOffset,
    LiftAlphaSquared,
    LiftOffset,
    MomentAlphaSquared,
    MomentOffset,
    PitchDamping,
)
from ._base import AbstractEffect
from ._other import (
    AccelerometerOffset,
    ActuatorDelay,
    SensorBias,
    ThrustMisalignment,
    VerticalWind,
)
from ._turbulence import Turbulence


EFFECTS: dict[str, type[AbstractEffect]] = {
    cls.name: cls
    for cls in (
        PitchDamping,
        AlphaDotDamping,
        LiftOffset,
        DragOffset,
        MomentOffset,
        LiftAlphaSquared,
        DragAlphaSquared,
        MomentAlphaSquared,
        ThrustMisalignment,
        AccelerometerOffset,
        SensorBias,
        ActuatorDelay,
        VerticalWind,
    )
}
# Random effects: plantable by `--hidden` but not deterministic candidates of the
# diagnosis (a gust realisation is process noise, estimated by the filter-error
# method, not a term to add to the model).
RANDOM_EFFECTS: dict[str, type[AbstractEffect]] = {Turbulence.name: Turbulence}


def effect_names() -> list[str]:
    """Canonical names (`sensor_bias` takes a channel: `sensor_bias:az`)."""
    names = [n if n != "sensor_bias" else "sensor_bias:<channel>" for n in EFFECTS]
    return names + list(RANDOM_EFFECTS)


def make_effect(spec: str, value: float = 0.0) -> AbstractEffect:
    """The effect `spec` (a canonical name, `sensor_bias:<channel>` for a bias)
    with its main parameter set to `value` (SI units)."""
    name, _, channel = spec.partition(":")
    if name not in EFFECTS and name not in RANDOM_EFFECTS:
        raise ValueError(f"unknown effect {spec!r}; known: {', '.join(effect_names())}")
    cls = EFFECTS.get(name) or RANDOM_EFFECTS[name]
    if name == "sensor_bias":
        if not channel:
            raise ValueError("sensor_bias needs a channel, e.g. sensor_bias:az")
        return SensorBias(channel=channel, bias=value)
    if channel:
        raise ValueError(f"effect {name!r} takes no ':<channel>' suffix")
    return cls(**{cls.parameter: value})


def parse_assignment(text: str) -> AbstractEffect:
    """Parse `NAME=VALUE` (as in `--hidden sensor_bias:az=0.2`) into an effect."""
    spec, sep, value = text.partition("=")
    if not sep:
        raise ValueError(f"expected NAME=VALUE, got {text!r}")
    try:
        number = float(value)
    except ValueError:
        raise ValueError(f"{spec}: value {value!r} is not a number") from None
    return make_effect(spec.strip(), number)
