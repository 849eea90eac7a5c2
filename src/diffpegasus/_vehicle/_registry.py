"""The built-in vehicles, by name, and vehicle files."""

import dataclasses
import pathlib

from .._estimate._modelfile import load_model_file, ModelSpec
from .._log._format import LogError


VEHICLES = {
    "pegasus": "Pegasus XL first stage, drop to burnout (3-DOF pitch plane, Orion 50S "
    "motor, thesis aerodynamic database): simulate, estimate, compare, diagnose, fit",
    "hfb320": "HFB-320 business jet, longitudinal (Jategaonkar test case 4: 11 "
    "aerodynamic derivatives, thrust from the log, real DLR flight record): simulate, fit, compare, diagnose",
}


def vehicle_spec(
    name_or_file: str, add: tuple[str, ...] = (), candidates: bool = False
) -> ModelSpec:
    """The model of a built-in vehicle other than Pegasus, or of a vehicle/model
    file (`.py`).

    **Arguments:** `add`: library effects to estimate with the vehicle's model;
    `candidates`: also compose every effect the vehicle supports, held at zero, as
    the candidates of `diagnose`.
    """
    if name_or_file == "hfb320":
        from ._hfb320 import CANDIDATES, COLUMNS, effect_parameter, hfb320_model, X0

        unknown = [a for a in add if a not in CANDIDATES]
        if unknown:
            raise LogError(
                f"effects {unknown} do not compose with hfb320; it takes "
                f"{', '.join(CANDIDATES)}"
            )
        # one order for every call, so diagnose and each --add share a program
        effects = tuple(dict.fromkeys((CANDIDATES if candidates else ()) + add))
        return ModelSpec(
            model=hfb320_model(effects=effects, free=add),
            name="hfb320",
            columns=COLUMNS,
            x0=X0,
            candidates=tuple(effect_parameter(e) for e in effects if e not in add),
        )
    if name_or_file.endswith(".py") or pathlib.Path(name_or_file).is_file():
        spec = load_model_file(name_or_file)
        if spec.vehicle is None:
            if add:
                raise LogError(
                    f"{name_or_file}: --add composes library effects with a vehicle "
                    "(`vehicle = dp.FlightVehicle(...)` in the file); with a bare "
                    "`model`, write the term into it (held terms to test go in "
                    "`candidates`)"
                )
            return spec
        from ._parts import effect_parameter, PITCH_PLANE_EFFECTS, vehicle_model

        effects = tuple(
            dict.fromkeys((PITCH_PLANE_EFFECTS if candidates else ()) + add)
        )
        return dataclasses.replace(
            spec,
            model=vehicle_model(spec.vehicle, effects=effects, free=add),
            candidates=spec.candidates
            + tuple(effect_parameter(e) for e in effects if e not in add),
        )
    raise LogError(
        f"unknown vehicle {name_or_file!r}; built in: {', '.join(VEHICLES)} "
        "(or give a model file, FILE.py)"
    )
