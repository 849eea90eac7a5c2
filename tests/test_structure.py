"""The package's structure, drawn from its imports: every arrow points down the
layers and no two modules import each other, directly or round a cycle.

The layers, bottom to top: the shared contracts at the package root (`_model`,
`_inputs`, `_rk4`, `_errors`, ...), then `_vehicle` -> `_log` -> `_simulate` ->
`_estimate` -> `_registry` (the vehicles by name: each entry builds its model, reads
its logs, runs its simulator) -> `_design` -> `_diagnose` -> `_report` -> `_rocket`
(the rocket workflow) -> `_campaign` -> `_cli`, then the public namespaces
(`diffpegasus`, `diffpegasus.pegasus`, ...). The log format sits below the simulator
because the simulator writes logs.
"""

import ast
import pathlib

import pytest


PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "src" / "diffpegasus"
LAYERS = (
    "_vehicle",
    "_log",
    "_simulate",
    "_estimate",
    "_registry",
    "_design",
    "_diagnose",
    "_report",
    "_rocket",
    "_campaign",
    "_cli",
)


def _module(path: pathlib.Path) -> tuple[str, ...]:
    parts = path.relative_to(PACKAGE).with_suffix("").parts
    return parts[:-1] if parts[-1] == "__init__" else parts


def _imports(path: pathlib.Path) -> set[tuple[str, ...]]:
    """Modules of the package that `path` imports (anywhere in the file, lazy
    imports inside functions included), as tuples of names below the package."""
    here = _module(path)
    package = here if path.name == "__init__.py" else here[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - (node.level - 1)]
            elif node.module and node.module.split(".")[0] == "diffpegasus":
                base = ()
            else:
                continue
            mod = node.module or ""
            if not node.level:
                mod = mod.removeprefix("diffpegasus").lstrip(".")
            target = base + tuple(p for p in mod.split(".") if p)
            found.add(target)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "diffpegasus":
                    found.add(tuple(alias.name.split(".")[1:]))
    return {t for t in found if t}


def _rank(module: tuple[str, ...]) -> int:
    """0 for the root's shared contracts, 1.. for the layers, above them the public
    namespaces."""
    top = module[0] if module else ""
    if top in LAYERS:
        return 1 + LAYERS.index(top)
    if len(module) == 1 and top.startswith("_") and not top.startswith("__"):
        return 0
    return len(LAYERS) + 1


GRAPH = {_module(p): _imports(p) for p in sorted(PACKAGE.rglob("*.py"))}


def test_no_import_runs_up_the_layers():
    upward = sorted(
        f"{'.'.join(src)} imports {'.'.join(dst)}"
        for src, targets in GRAPH.items()
        for dst in targets
        if _rank(dst) > _rank(src)
    )
    assert upward == []


@pytest.mark.parametrize("kind", ["layer", "module"])
def test_no_cycle(kind):
    def node(m):
        return m[:1] if kind == "layer" and _rank(m) > 0 else m

    edges: dict[tuple, set] = {}
    for src, targets in GRAPH.items():
        for dst in targets:
            a, b = node(src), node(dst)
            # a package's __init__ importing its own modules is not an arrow
            if a != b and not (kind == "module" and b[: len(a)] == a):
                edges.setdefault(a, set()).add(b)
    state: dict[tuple, int] = {}
    cycles = []

    def visit(n, path):
        state[n] = 1
        for m in edges.get(n, ()):
            if state.get(m) == 1:
                cycles.append(path[path.index(m) :] + [m])
            elif m not in state:
                visit(m, path + [m])
        state[n] = 2

    for n in list(edges):
        if n not in state:
            visit(n, [n])
    assert cycles == []
