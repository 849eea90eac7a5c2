"""Inverse-square gravity over a flat, non-rotating Earth frame."""

from .._custom_types import Scalar, ScalarLike


GRAVITATIONAL_CONSTANT = 6.67428e-11  # m^3 / (kg s^2)
EARTH_MASS = 5.9722e24  # kg
EARTH_RADIUS = 6_378_100.0  # m


def gravity(h: ScalarLike) -> Scalar:
    """Gravitational acceleration `G Me / (Re + h)^2` (m/s^2) at altitude `h` (m).

    It acts along the inertial +z axis (down).
    """
    return GRAVITATIONAL_CONSTANT * EARTH_MASS / (EARTH_RADIUS + h) ** 2
