"""The sidecar's metadata: each key the flight-log format lists, of the right type and range,
and numbers written as a user reads them."""

import math
from typing import Any

from ._checks import CHECKS


def _is_real(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _positive(v) -> bool:
    return _is_real(v) and v > 0


def _str(v) -> bool:
    return isinstance(v, str)


def _int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _real_map(v) -> bool:
    return isinstance(v, dict) and all(_is_real(x) for x in v.values())


def _sigma_map(v) -> bool:
    return isinstance(v, dict) and all(_is_real(x) and x >= 0 for x in v.values())


def _checks_list(v) -> bool:
    return isinstance(v, list) and all(x in CHECKS for x in v)


# key: (test, what it must be)
_SIDECAR_KEYS = {
    "S_ref": (_positive, "a positive number of m^2"),
    "c_ref": (_positive, "a positive number of m"),
    "sample_rate_hz": (_positive, "a positive number of Hz"),
    "vehicle": (_str, "a string"),
    "input": (_str, "a string"),
    "simulator": (_str, "a string"),
    "seed": (_int, "an integer"),
    "noise_sigmas": (_sigma_map, "an object of channel: non-negative number"),
    "hidden_effects": (_real_map, "an object of effect: number"),
    "perturbation": (_real_map, "an object of name: number"),
    "skip_checks": (_checks_list, f"a list of check names from {', '.join(CHECKS)}"),
}


def check_sidecar(meta: dict[str, Any], where: str) -> None:
    """Raise `ValueError` naming the first sidecar key of the wrong type or range.

    Keys the format does not list are kept as they are (the writer's business).
    """
    for key, (ok, what) in _SIDECAR_KEYS.items():
        if key in meta and not ok(meta[key]):
            raise ValueError(
                f"{where}: {key} must be {what}, got {json_repr(meta[key])}"
            )


def json_repr(v) -> str:
    import json

    try:
        return json.dumps(v)
    except (TypeError, ValueError):
        return repr(v)
