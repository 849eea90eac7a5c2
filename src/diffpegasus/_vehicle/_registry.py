"""The built-in vehicles, by name, and vehicle files."""

import dataclasses
import pathlib

from .._errors import LogError
from .._estimate._modelfile import load_model_file, ModelSpec


VEHICLES = {
    "pegasus": "Pegasus XL first stage, drop to burnout (3-DOF pitch plane, Orion 50S "
    "motor, thesis aerodynamic database): simulate, estimate, compare, diagnose, fit",
    "hfb320": "HFB-320 business jet, longitudinal (Jategaonkar test case 4: 11 "
    "aerodynamic derivatives, thrust from the log, real DLR flight record): simulate, fit, compare, diagnose",
    "hfb320-lateral": "lateral-directional motion, the textbooks' linear model "
    "(Jategaonkar test cases 1 and 34: 15 derivatives, state and output biases, 22 "
    "parameters; several logs are several manoeuvres, each with its own state "
    "biases), the HFB-320 record's lateral columns mapped: fit, diagnose (aileron "
    "and rudder delay); simulate flies the 6-DOF business jet",
}


def vehicle_spec(
    name_or_file: str,
    add: tuple[str, ...] = (),
    candidates: bool = False,
    manoeuvres: int = 1,
) -> ModelSpec:
    """The model of a built-in vehicle other than Pegasus, or of a vehicle/model
    file (`.py`).

    **Arguments:** `add`: library effects to estimate with the vehicle's model;
    `candidates`: also compose every effect the vehicle supports, held at zero, as
    the candidates of `diagnose`; `manoeuvres`: how many logs are fitted together
    (`hfb320-lateral` gives each its own state biases, selected by the model inputs
    `manoeuvre_k` that the CLI sets to 1 on the k-th log).
    """
    if name_or_file == "hfb320-lateral":
        from ._lateral import LATERAL_COLUMNS, LATERAL_EFFECTS, lateral_model

        unknown = [a for a in add if a not in LATERAL_EFFECTS]
        if unknown:
            raise LogError(
                f"effects {unknown} do not compose with hfb320-lateral; it takes "
                f"{', '.join(LATERAL_EFFECTS)}"
            )
        effects = tuple(
            dict.fromkeys((tuple(LATERAL_EFFECTS) if candidates else ()) + add)
        )
        return ModelSpec(
            model=lateral_model(manoeuvres=manoeuvres, effects=effects, free=add),
            name="hfb320-lateral",
            columns={ch: {"column": col} for ch, col in LATERAL_COLUMNS.items()},
            # the book's x0 = 0, held: the lumped biases absorb the initial rates
            x0=(0.0, 0.0),
            candidates=tuple(f"{e}.tau" for e in effects if e not in add),
        )
    if name_or_file == "hfb320":
        from ._hfb320 import (
            CANDIDATES,
            COLUMNS,
            effect_parameter,
            hfb320_model,
            PROCESS_NOISE,
            X0,
        )

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
            process_noise=dict(PROCESS_NOISE),
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
