from ._engine import Layout as Layout, RESULTS as RESULTS, Solution as Solution
from ._fit import (
    Fit as Fit,
    fit as fit,
    MultipleShooting as MultipleShooting,
    simulate as simulate_model,  # noqa: F401
    SingleShooting as SingleShooting,
)
from ._model import Model as Model, Record as Record
