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


# `diffpegasus --help` lists the panels in the order their first command comes,
# and the commands in this order inside each; commands not named here (and their
# panels) follow in the order they were registered.
_ORDER = (
    "demo",
    "fit",
    "compare",
    "diagnose",
    "replay",
    "rocket",
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


# commands whose module names no panel: the panel they belong in
_PANELS = {"replay": "Fit and diagnose", "rocket": "Fit and diagnose"}

app.registered_commands.sort(key=_rank)
for _info in [*app.registered_commands, *app.registered_groups]:
    _name = _info.name or (_info.callback and _info.callback.__name__)
    if not isinstance(_info.rich_help_panel, str) and _name in _PANELS:
        _info.rich_help_panel = _PANELS[_name]


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
