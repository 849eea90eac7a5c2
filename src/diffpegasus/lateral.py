"""Lateral-directional motion: the linear lateral model of the HFB-320 and ATTAS
records, the six-degree-of-freedom lateral model, their channel names and derivatives.
"""

from ._lazy import attach_stub


# the public names are listed once, in the stub beside this file, and load on first use
__getattr__, __dir__, __all__ = attach_stub(__name__, __file__)
