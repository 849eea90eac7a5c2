"""Public names of a package loaded on first use (PEP 562).

A command line run imports only the modules it runs: `diffpegasus fit` on the
HFB-320 log needs the engine and one vehicle, not the Pegasus campaign, the neural
model or the diagnosis (0.3 s of imports on a 2-core machine, against a 1.2 s fit).
"""

import ast
import importlib
import importlib.util
import pathlib
import sys
import warnings


def attach(
    package: str,
    public: dict[str, tuple[str, ...]],
    moved: dict[str, str] | None = None,
):
    """`(__getattr__, __dir__, __all__)` for the package named `package` whose
    public names live in its submodules: `public` maps a submodule (relative to the
    package, e.g. `"_fit"` or `"_vehicle._atmosphere"`) to the names it provides
    (`"public=name"` where the package renames one).
    `moved` maps names that left this namespace to where they live now (a dotted
    path below the package, e.g. `"pegasus.simulate"`): they still resolve, for one
    release, with a `DeprecationWarning`, and are not listed.
    A submodule that is not a public name is still an attribute once asked for
    (`package._fit`), as with an eager `__init__`."""
    where = {}
    for module, names in public.items():
        for entry in names:
            name, _, source = entry.partition("=")
            where[name] = (module, source or name)
    moved = moved or {}
    # a package's names are relative to itself, a plain module's to its package
    here = sys.modules[package]
    anchor = package if hasattr(here, "__path__") else package.rpartition(".")[0]

    def __getattr__(name):
        if name in where:
            module, source = where[name]
            value = getattr(importlib.import_module(f".{module}", anchor), source)
            setattr(sys.modules[package], name, value)  # later lookups skip this
            return value
        if name in moved:
            module, _, source = moved[name].rpartition(".")
            warnings.warn(
                f"{package}.{name} is now {package}.{moved[name]}",
                DeprecationWarning,
                stacklevel=2,
            )
            return getattr(importlib.import_module(f".{module}", anchor), source)
        if (
            not name.startswith("__")
            and anchor == package
            and importlib.util.find_spec(f"{package}.{name}")
        ):
            return importlib.import_module(f".{name}", package)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__():
        return sorted(where)

    return __getattr__, __dir__, sorted(where)


def attach_stub(package: str, file: str, moved: dict[str, str] | None = None):
    """[`attach`][] with the public names read from the stub beside `file` (the
    module's `__init__.pyi`, or `name.pyi` for a module `name.py`): one list of
    `from .module import Name as Name` lines that type checkers read and this
    function turns into the lazy map, so the two never disagree."""
    stub = pathlib.Path(file).with_suffix(".pyi")
    public: dict[str, list[str]] = {}
    for node in ast.parse(stub.read_text()).body:
        # `from . import sub` names a submodule, which loads on first use anyway
        if isinstance(node, ast.ImportFrom) and node.level and node.module:
            # relative to this module's package: "." is a sibling, ".." its parent
            module = "." * (node.level - 1) + (node.module or "")
            for alias in node.names:
                public.setdefault(module, []).append(
                    alias.name
                    if (alias.asname or alias.name) == alias.name
                    else f"{alias.asname}={alias.name}"
                )
    return attach(package, {m: tuple(n) for m, n in public.items()}, moved)
