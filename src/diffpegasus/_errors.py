"""The error every layer raises for input that cannot give correct numbers."""


class LogError(ValueError):
    """A flight log (or a file, option or model that goes with it) that cannot be
    used, with a one-line explanation naming the file, column, row and value."""
