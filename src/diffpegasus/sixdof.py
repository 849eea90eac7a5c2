"""Six degrees of freedom: the rigid-body equations, the generic aircraft with its
linear aerodynamics (a business jet built in), trim, linearisation and simulation.
The lateral-directional models built on them are in `diffpegasus.lateral`."""

from ._lazy import attach_stub


# the public names are listed once, in the stub beside this file, and load on first use
__getattr__, __dir__, __all__ = attach_stub(__name__, __file__)
