from ._engine import Layout as Layout, RESULTS as RESULTS, Solution as Solution
from ._fit import (
    fit as fit,
    Fit as Fit,
    MultipleShooting as MultipleShooting,
    simulate as simulate_model,
    SingleShooting as SingleShooting,
)
from ._model import Model as Model, Record as Record
