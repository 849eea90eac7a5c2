"""Simulation: input schedules, one diffrax solve per flight, sensors, and the
gradient-optimal input design that chooses what to fly."""
