"""Where a launch-vehicle diagnosis test's time goes: compilation against running,
and whether a second flight of the same log shape, and a refit with an effect
added, compile anything new.

In one process (as one pytest-xdist worker runs `tests/test_discrepancy.py`):
30 s flights at 50 Hz of the package's simulator (clean seed 5, a planted q bias,
planted pitch damping), each fitted with the registry entry's defaults and
diagnosed, and refitted with the planted effect added. For every step: the
process's CPU seconds, and JAX's tracing, lowering and XLA-compilation seconds and
number of XLA compilations (from `jax.monitoring`). Writes
`benchmarks/results/suite_programs.json`.

    python benchmarks/suite_programs.py

Start it without a persistent compilation cache (`DIFFPEGASUS_NO_CACHE=1`, the
default here) to see what a fresh worker pays.
"""

import collections
import json
import os
import pathlib
import resource
import time


os.environ.setdefault("DIFFPEGASUS_NO_CACHE", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import jax  # noqa: E402
from jax import monitoring  # noqa: E402


jax.config.update("jax_enable_x64", True)

import diffpegasus as dp  # noqa: E402
from diffpegasus.discrepancy import diagnose, fit_log, vehicle_entry  # noqa: E402


_SECONDS: dict[str, float] = collections.defaultdict(float)
_COUNTS: collections.Counter = collections.Counter()
_EVENTS = {
    "/jax/core/compile/jaxpr_trace_duration": "trace_s",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower_s",
    "/jax/core/compile/backend_compile_duration": "xla_s",
}


def _listen(event, duration, **_):
    if event in _EVENTS:
        _SECONDS[_EVENTS[event]] += duration
        _COUNTS[_EVENTS[event]] += 1


monitoring.register_event_duration_secs_listener(_listen)


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _flight(hidden=(), seed=5):
    effects = tuple(dp.parse_assignment(h) for h in hidden)
    config = dp.pegasus.PegasusConfig(t_final=30.0, sample_rate=50.0, effects=effects)
    return dp.pegasus.flight_to_log(dp.pegasus.simulate(config, jax.random.key(seed)))


def _fitted(entry, log, add=(), start=None):
    out = fit_log(entry, log, add, start=start)
    out.cost  # noqa: B018  (the fit's arrays made concrete inside the step)
    return out


def main():
    entry = vehicle_entry("pegasus")
    rows = []

    def step(label, fn, *args, **kwargs):
        seconds, counts = dict(_SECONDS), dict(_COUNTS)
        cpu, wall = _cpu(), time.time()
        out = fn(*args, **kwargs)
        row = {"step": label, "cpu_s": round(_cpu() - cpu, 2)}
        row["wall_s"] = round(time.time() - wall, 2)
        for name in _EVENTS.values():
            row[name] = round(_SECONDS[name] - seconds.get(name, 0.0), 2)
        row["xla_compilations"] = _COUNTS["xla_s"] - counts.get("xla_s", 0)
        rows.append(row)
        print(json.dumps(row), flush=True)
        return out

    for label, hidden, effect in (
        ("clean", (), None),
        ("q bias", ("sensor_bias:q=0.002",), "sensor_bias:q"),
        ("pitch damping", ("pitch_damping=-10.0",), "pitch_damping"),
    ):
        log = step(f"simulate {label}", _flight, hidden)
        base = step(f"fit {label}", _fitted, entry, log)
        step(f"diagnose {label}", diagnose, base)
        if effect is not None:
            step(f"refit {label} + {effect}", _fitted, entry, log, (effect,), base)
    out = pathlib.Path(__file__).parent / "results" / "suite_programs.json"
    out.write_text(json.dumps({"load_after": os.getloadavg(), "steps": rows}, indent=2))


if __name__ == "__main__":
    main()
