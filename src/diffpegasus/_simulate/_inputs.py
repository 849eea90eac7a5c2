"""Moved to the package root (`diffpegasus._inputs`): input signals sit below every layer that uses them."""

from .._inputs import *  # noqa: F401,F403
from .._inputs import AbstractInput as AbstractInput, NoInput as NoInput  # noqa: F401
