"""The Pegasus first stage: its aerodynamic database, Orion 50S motor, mass model and
the simulator's dynamics on the one flight model."""
