"""The `diffpegasus` command line, one module per group of commands."""

import sys

import typer

from .._errors import LogError
from . import _campaign, _diagnose, _estimate, _fit, _simulate  # noqa: F401 (registers)
from ._common import _os_error, app


# `diffpegasus --help` lists the panels in the order their first command comes,
# and the commands in this order inside each; commands not named here (and their
# panels) follow in the order they were registered.
_ORDER = (
    "demo",
    "fit",
    "compare",
    "diagnose",
    "check",
    "simulate",
    "estimate",
    "montecarlo",
    "design-input",
    "vehicles",
    "effects",
)


def _rank(info) -> int:
    name = info.name or info.callback.__name__.replace("_", "-")
    return _ORDER.index(name) if name in _ORDER else len(_ORDER)


app.registered_commands.sort(key=_rank)


def main() -> None:
    """Entry point of the `diffpegasus` script."""
    import os

    from .._cache import enable_cache

    # `--no-cache` anywhere on the line (before a `--`) is the same as
    # DIFFPEGASUS_NO_CACHE=1: no persistent compilation cache for this run
    args = sys.argv[1:]
    end = args.index("--") if "--" in args else len(args)
    if "--no-cache" in args[:end]:
        sys.argv = [sys.argv[0], *(a for a in args[:end] if a != "--no-cache")]
        sys.argv += args[end:]
        os.environ["DIFFPEGASUS_NO_CACHE"] = "1"
    enable_cache()
    try:
        app()
    except LogError as e:
        typer.echo(f"error: {e}", err=True)
        sys.exit(2)
    except OSError as e:
        # a file the command reads or writes that the checks could not foresee
        typer.echo(f"error: {_os_error(e)}", err=True)
        sys.exit(2)
