"""Monte Carlo comparison of LSE, NN+LSE and OEM (see the
thesis-reproduction tutorial in the documentation)."""

from ._campaign._montecarlo import (
    Campaign as Campaign,
    coverage as coverage,
    draws as draws,
    flight_mse as flight_mse,
    load_results as load_results,
    METHODS as METHODS,
    run_campaign as run_campaign,
    training_logs as training_logs,
)
