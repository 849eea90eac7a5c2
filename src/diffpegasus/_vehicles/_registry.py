"""The built-in vehicles, by name, and vehicle files."""

import pathlib

from .._identify._modelfile import load_model_file, ModelSpec
from .._log import LogError


VEHICLES = {
    "pegasus": "Pegasus XL first stage, drop to burnout (3-DOF pitch plane, Orion 50S "
    "motor, thesis aerodynamic database): simulate, estimate, compare, diagnose, fit",
    "hfb320": "HFB-320 business jet, longitudinal (Jategaonkar test case 4: 11 "
    "aerodynamic derivatives, thrust from the log, real DLR flight record): fit",
}


def vehicle_spec(name_or_file: str) -> ModelSpec:
    """The model of a built-in vehicle other than Pegasus, or of a vehicle/model
    file (`.py`)."""
    if name_or_file == "hfb320":
        from ._hfb320 import COLUMNS, hfb320_model, X0

        return ModelSpec(model=hfb320_model(), name="hfb320", columns=COLUMNS, x0=X0)
    if name_or_file.endswith(".py") or pathlib.Path(name_or_file).is_file():
        return load_model_file(name_or_file)
    raise LogError(
        f"unknown vehicle {name_or_file!r}; built in: {', '.join(VEHICLES)} "
        "(or give a model file, FILE.py)"
    )
