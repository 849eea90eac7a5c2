"""mkdocs hook: the Python API reference, generated from the package's public names.

A page holding `<!-- api-reference -->` gets one mkdocstrings entry per name in
`diffpegasus.__all__`, grouped by the part of the package that defines it, and one
section per public namespace module (`dp.pegasus`, `dp.montecarlo`, ...) with the
names of its own `__all__`. The entries point at where each object is defined (the
package loads its names lazily, which a static reader cannot follow), under the
name a user types. The page follows the public surface as it changes.
"""

import importlib
import inspect
import pathlib
import pkgutil
import re
import types


MARKER = "<!-- api-reference -->"
TITLES = {  # in the order of the pipeline: vehicle -> simulate -> log -> estimate ...
    "_model": "Models and records",
    "_vehicle": "Vehicles and effects",
    "_inputs": "Inputs",
    "_simulate": "Simulation",
    "_rk4": "Integration",
    "_log": "Logs and files",
    "_errors": "Errors",
    "_estimate": "Estimation",
    "_diagnose": "Finding missing terms",
    "_campaign": "Campaigns",
    "_report": "Reports",
}


def _all_modules(package):
    mods = [package]
    for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
        if info.name.endswith("__main__"):  # importing it runs the command line
            continue
        try:
            mods.append(importlib.import_module(info.name))
        except Exception:  # an optional dependency missing: not documented here
            continue
    return mods


def _where(name, obj, modules, package):
    """`(module, attribute)` where `obj` is defined (not merely imported)."""
    if inspect.isclass(obj) or inspect.isfunction(obj):
        module = getattr(obj, "__module__", "") or ""
        qual = getattr(obj, "__qualname__", obj.__name__)
        if module.startswith(package) and "<" not in qual:
            return module, qual
    # a value (an instance, a dict, a constant): the deepest module holding it
    holders = [
        m.__name__
        for m in modules
        if any(v is obj for k, v in vars(m).items() if not k.startswith("__"))
        and not m.__name__.endswith("__init__")
    ]
    holders = [h for h in holders if h != package]
    if not holders:
        return None
    module = max(holders, key=lambda h: h.count("."))
    attr = next(k for k, v in vars(importlib.import_module(module)).items() if v is obj)
    return module, attr


def _static(module: str, attr: str) -> bool:
    """Whether a static reader (griffe) finds `attr` in `module`'s source: a
    top-level class, function or assignment of that name."""
    source = inspect.getsource(importlib.import_module(module))
    head = re.escape(attr.split(".")[0])
    return bool(re.search(rf"^(class|def)\s+{head}\b|^{head}\s*[:=]", source, re.M))


def _entry(public: str, located, level: int) -> list[str]:
    module, attr = located
    short = public.rsplit(".", 1)[-1]
    if not _static(module, attr):
        # made at run time (e.g. a class built on first use): its docstring only
        obj = getattr(importlib.import_module(module), attr.split(".")[0])
        doc = inspect.getdoc(obj) or ""
        anchor = f"[](){{#{short}}} " if _claim(short) else ""
        return [
            f"{'#' * level} {public}",
            "",
            f"{anchor}`{module}.{attr}`",
            "",
            doc,
            "",
        ]
    # the docstrings cross-reference names bare (`[Model][]`, `[Fit.table][]`):
    # anchor the name and a class's members here
    anchors = [short]
    obj = getattr(importlib.import_module(module), attr.split(".")[0])
    if inspect.isclass(obj):
        anchors += [f"{short}.{m}" for m in vars(obj) if not m.startswith("_")]
    return [
        " ".join(f"[](){{#{a}}}" for a in anchors if _claim(a)),
        "",
        f"::: {module}.{attr}",
        "    options:",
        f'      heading: "{public}"',
        f'      toc_label: "{public.rsplit(".", 1)[-1]}"',
        f"      heading_level: {level}",
        "      show_root_heading: true",
        "",
    ]


_CLAIMED: set[str] = set()


def _claim(anchor: str) -> bool:
    """True the first time an anchor is asked for (ids must be unique on a page)."""
    if anchor in _CLAIMED:
        return False
    _CLAIMED.add(anchor)
    return True


_REF = re.compile(r"\[`?([A-Za-z_][\w.]*)`?\]\[\]|\]\[([A-Za-z_][\w.]*)\]")


def _others(modules) -> list[str]:
    """Names the docstrings cross-reference that are not public (building blocks,
    constants): a line each, anchored, so every reference lands somewhere."""
    root = pathlib.Path(modules[0].__file__).parent
    wanted = set()
    for path in root.rglob("*.py"):
        for a, b in _REF.findall(path.read_text(encoding="utf-8")):
            wanted.add(a or b)
    wanted = sorted(
        w
        for w in wanted
        if w not in _CLAIMED
        and not w.startswith("diffpegasus")
        and w not in ("None", "True", "False")
    )
    lines = []
    for name in wanted:
        head = name.split(".")[0]
        where, doc = None, ""
        for m in modules:
            obj = vars(m).get(head)
            if obj is None:
                continue
            defined = getattr(obj, "__module__", None) == m.__name__ or not (
                inspect.isclass(obj) or inspect.isfunction(obj) or inspect.ismodule(obj)
            )
            if defined and (where is None or m.__name__.count(".") > where.count(".")):
                where = m.__name__
                target = obj
                for part in name.split(".")[1:]:
                    target = getattr(target, part, None)
                raw = (
                    inspect.getdoc(target)
                    if callable(target) or inspect.isclass(target)
                    else ""
                )
                doc = (raw or "").split("\n\n")[0].replace("\n", " ")
                doc = re.sub(r"\[([^\]]*)\]\[[^\]]*\]", r"\1", doc)
        if not _claim(name):
            continue
        text = f"`{where}.{name}`" if where else f"`{name}`"
        lines += [f"[](){{#{name}}} {text}" + (f": {doc}" if doc else ""), ""]
    if not lines:
        return []
    return [
        "## Other names in the docstrings",
        "",
        "Building blocks and constants that the docstrings above mention, where they "
        "live; they are not part of the public surface and may change.",
        "",
        *lines,
    ]


def _section(pkg, prefix: str, modules, level: int) -> list[str]:
    groups: dict[str, list[str]] = {}
    namespaces = []
    for name in sorted(getattr(pkg, "__all__", []), key=str.lower):
        obj = getattr(pkg, name)
        if isinstance(obj, types.ModuleType):
            namespaces.append((name, obj))
            continue
        located = _where(name, obj, modules, "diffpegasus")
        if located is None:
            continue
        part = located[0].split(".")[1] if located[0].count(".") else "_"
        title = TITLES.get(part, part.strip("_").replace("_", " ").capitalize())
        groups.setdefault(title, []).extend(
            _entry(f"{prefix}.{name}", located, level + 1)
        )
    out = []
    order = list(TITLES.values())
    for title in sorted(
        groups, key=lambda g: (order.index(g) if g in order else 99, g)
    ):
        out += [f"{'#' * level} {title}", "", *groups[title]]
    return out, namespaces


def api_reference() -> str:
    import diffpegasus

    _CLAIMED.clear()
    modules = _all_modules(diffpegasus)
    out, namespaces = _section(diffpegasus, "dp", modules, 2)
    # the public namespaces: modules of the package without a leading underscore
    listed = {name for name, _ in namespaces}
    for info in pkgutil.iter_modules(diffpegasus.__path__):
        if info.name.startswith("_") or info.name in listed:
            continue
        module = importlib.import_module(f"diffpegasus.{info.name}")
        if getattr(module, "__all__", None):
            namespaces.append((info.name, module))
    for name, module in namespaces:
        out += [f"## `dp.{name}`", ""]
        if module.__doc__:
            out += [inspect.cleandoc(module.__doc__).split("\n\n")[0], ""]
        inner, _ = _section(module, f"dp.{name}", modules, 3)
        out += inner
    out += _others(modules)
    return "\n".join(out)


def on_page_markdown(markdown, page, config, files):
    del page, config, files
    if MARKER in markdown:
        return markdown.replace(MARKER, api_reference())
    return markdown
