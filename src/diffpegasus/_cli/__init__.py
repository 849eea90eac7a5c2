"""The `diffpegasus` command line, one module per group of commands."""

import sys

import typer

from .._errors import LogError
from . import (  # noqa: F401 (registers)
    _campaign,
    _diagnose,
    _estimate,
    _fit,
    _recursive,  # noqa: F401 (registers `replay`)
    _rocket,  # noqa: F401 (registers)
    _simulate,
)
from ._common import _os_error, app


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
