"""The Pegasus first stage: the reference vehicle of the thesis this package began
with. Its simulator and aerodynamic database, its lateral fin model, and the thesis's
window-by-window estimators (least squares, neural model plus least squares, output
error) with their results.

The generic vocabulary (models, records, the estimation entry, vehicles from parts,
the diagnosis) is at the top level, `diffpegasus`; this namespace holds what only the
Pegasus vehicle and the thesis reproduction use.
"""

from ._lazy import attach_stub


# the public names are listed once, in the stub beside this file, and load on first use
__getattr__, __dir__, __all__ = attach_stub(__name__, __file__)
