"""Rocket flights: identification, prediction, diagnosis and reports."""
