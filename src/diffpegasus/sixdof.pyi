"""The six-degree-of-freedom namespace, for type checkers and for the lazy loader."""

from ._vehicle._sixdof import (
    Aircraft as Aircraft,
    body_to_earth as body_to_earth,
    business_jet as business_jet,
    Controls as Controls,
    euler_rates as euler_rates,
    inertia_tensor as inertia_tensor,
    linearise as linearise,
    rigid_body_rates as rigid_body_rates,
    simulate_sixdof as simulate_sixdof,
    sixdof_evaluate as sixdof_evaluate,
    sixdof_rates as sixdof_rates,
    Trim as Trim,
    trim as trim,
)
