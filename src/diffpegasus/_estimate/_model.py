"""Moved to the package root (`diffpegasus._model`): the model contract sits below every layer that uses it."""

from .._model import Model as Model, Record as Record  # noqa: F401
