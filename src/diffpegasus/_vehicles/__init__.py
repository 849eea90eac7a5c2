from ._hfb320 import hfb320_model as hfb320_model
