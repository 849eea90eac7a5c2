"""A pytest plugin counting JAX's compilations test by test.

For each test: its CPU seconds (the process's and its subprocesses'), the number
of XLA compilations and their seconds (JAX's monitoring events: tracing, lowering,
XLA; wall seconds, so a loaded machine inflates them), persistent-cache hits, and
every compiled program's name with its argument shapes (JAX's compile log), which
shows programs compiled again only because a shape differed. Run one test file in
one process:

    PYTHONPATH=src:benchmarks python -m pytest -p no:xdist -p compile_census \
        tests/test_lateral.py

Writes `benchmarks/results/compile_census.json` (or the file `CENSUS_OUT` names),
then a summary per file: `python benchmarks/compile_census.py FILE.json`.
"""

import collections
import json
import logging
import os
import pathlib
import re
import resource
import sys


_EVENTS = {
    "/jax/core/compile/jaxpr_trace_duration": "trace_s",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower_s",
    "/jax/core/compile/backend_compile_duration": "xla_s",
}
_COMPILING = re.compile(
    r"Compiling (\S+) with global shapes and types (.*?)\. Argument mapping", re.S
)
_current = {"id": "<collection>"}
_data: dict = collections.defaultdict(
    lambda: dict(
        trace_s=0.0, lower_s=0.0, xla_s=0.0, compiles=0, cache_hits=0, programs=[]
    )
)


def _cpu() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def _on_duration(event, duration, **_):
    key = _EVENTS.get(event)
    if key:
        row = _data[_current["id"]]
        row[key] += duration
        row["compiles"] += key == "xla_s"


def _on_event(event, **_):
    if "cache_hits" in event and "original" not in event:
        _data[_current["id"]]["cache_hits"] += 1


class _CompileLog(logging.Handler):
    def emit(self, record):
        match = _COMPILING.search(record.getMessage())
        if match:
            _data[_current["id"]]["programs"].append([match[1], match[2][:600]])


def pytest_configure(config):
    import jax
    from jax import monitoring

    jax.config.update("jax_log_compiles", True)
    monitoring.register_event_duration_secs_listener(_on_duration)
    monitoring.register_event_listener(_on_event)
    handler = _CompileLog(logging.DEBUG)
    for name in ("jax._src.interpreters.pxla", "jax._src.dispatch"):
        logger = logging.getLogger(name)
        logger.addHandler(handler)
        logger.propagate = False  # the compile log is counted, not printed


def pytest_runtest_protocol(item, nextitem):
    _current["id"] = item.nodeid
    _data[item.nodeid]["cpu_start"] = _cpu()


def pytest_runtest_logfinish(nodeid, location):
    row = _data[nodeid]
    row["cpu_s"] = _cpu() - row.pop("cpu_start", _cpu())
    _current["id"] = "<between tests>"


def pytest_sessionfinish(session):
    default = pathlib.Path(__file__).parent / "results" / "compile_census.json"
    out = pathlib.Path(os.environ.get("CENSUS_OUT", default))
    out.write_text(json.dumps(_data, indent=1) + "\n")


def summary(path) -> dict:
    """Per file: tests' CPU seconds, compilations, their seconds, and the programs
    compiled at more than one set of argument shapes."""
    data = json.loads(pathlib.Path(path).read_text())
    shapes = collections.defaultdict(set)
    for row in data.values():
        for name, args in row["programs"]:
            shapes[name].add(args)
    tests = [row for key, row in data.items() if "::" in key]
    return dict(
        tests_cpu_s=round(sum(r.get("cpu_s", 0.0) for r in tests), 1),
        compiles=sum(r["compiles"] for r in data.values()),
        xla_s=round(sum(r["xla_s"] for r in data.values()), 1),
        trace_and_lower_s=round(
            sum(r["trace_s"] + r["lower_s"] for r in data.values()), 1
        ),
        programs_at_several_shapes={
            name: len(s) for name, s in sorted(shapes.items()) if len(s) > 1
        },
    )


if __name__ == "__main__":
    for arg in sys.argv[1:]:
        print(arg, json.dumps(summary(arg), indent=1))
