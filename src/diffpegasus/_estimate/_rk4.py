"""Moved to the package root (`diffpegasus._rk4`)."""

from .._rk4 import RK4 as RK4, rk4_scan as rk4_scan  # noqa: F401
