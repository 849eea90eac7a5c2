"""Where one launch-vehicle diagnosis spends its time, stage by stage: the baseline
fit, the score test and each bootstrap calibration of the decision rule, each with
its wall and CPU seconds and JAX's tracing, lowering and XLA-compilation seconds
and number of compilations (from `jax.monitoring`), for a first (compiling) and a
repeated diagnosis of one log of the independent generator (`tests/`). Writes
`benchmarks/results/diagnose_stages.json`.

    python benchmarks/diagnose_stages.py SEED RATE [REPEATS]   # e.g. 3 50 2

Run from the repository root, without a persistent compilation cache (the default
here) to see what a fresh process pays.
"""

import collections  # noqa: E402
import os  # noqa: E402
import pathlib  # noqa: E402
import resource  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402


os.environ.setdefault("DIFFPEGASUS_NO_CACHE", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ["XLA_FLAGS"] = "--xla_force_host_platform_device_count=2"
import jax  # noqa: E402
from jax import monitoring  # noqa: E402


jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")
S = collections.defaultdict(float)
C = collections.Counter()
EV = {
    "/jax/core/compile/jaxpr_trace_duration": "trace",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
    "/jax/core/compile/backend_compile_duration": "xla",
}


def listen(event, d, **_):
    if event in EV:
        S[EV[event]] += d
        C[EV[event]] += 1


monitoring.register_event_duration_secs_listener(listen)
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
from tests import independent_generator as gen  # noqa: E402

import diffpegasus as dp  # noqa: E402
import diffpegasus._diagnose._candidates as CA  # noqa: E402
import diffpegasus._diagnose._rule as R  # noqa: E402
from diffpegasus.discrepancy import diagnose, fit_log, vehicle_entry  # noqa: E402


def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


stage_stack = []
rows = []


def timed(label, fn):
    def w(*a, **k):
        s0, c0, t0, w0 = dict(S), dict(C), cpu(), time.time()
        out = fn(*a, **k)
        jax.block_until_ready(jax.tree.leaves(out)) if False else None
        rows.append(
            (
                label,
                time.time() - w0,
                cpu() - t0,
                *(S[x] - s0.get(x, 0) for x in ("trace", "lower", "xla")),
                C["xla"] - c0.get("xla", 0),
            )
        )
        return out

    return w


R.calibrate = timed("  calibrate(bootstrap)", R.calibrate)
CA.score = timed("  score test", CA.score)
CA.score_linearised = timed("  score test", CA.score_linearised)
seed, rate = int(sys.argv[1]), float(sys.argv[2])
folder = pathlib.Path(tempfile.mkdtemp())
t0 = time.time()
c0 = cpu()
lg = dp.read_log(gen.make_log(folder / "clean.csv", seed, rate, 30.0, None))
rows.append(("log", time.time() - t0, cpu() - c0, 0, 0, 0, 0))
entry = vehicle_entry("pegasus")


def run(label, fn, *a, **k):
    return timed(label, fn)(*a, **k)


for rep in range(int(sys.argv[3]) if len(sys.argv) > 3 else 1):
    base = run(
        f"fit_log baseline #{rep}",
        lambda: (lambda f: (f.cost, f))(fit_log(entry, lg))[1],
    )
    d = run(f"diagnose #{rep}", diagnose, base)
print("significant", d["significant"], "thr", d["rule"])
print(
    f"{'stage':32s} {'wall':>7s} {'cpu':>7s} {'trace':>6s} {'lower':>6s} {'xla':>6s} {'#xla':>5s}"
)
for r in rows:
    print(
        f"{r[0]:32s} {r[1]:7.1f} {r[2]:7.1f} {r[3]:6.1f} {r[4]:6.1f} {r[5]:6.1f} {r[6]:5d}"
    )

import json  # noqa: E402


out = pathlib.Path(__file__).with_name("results") / "diagnose_stages.json"
out.parent.mkdir(exist_ok=True)
keys = ("stage", "wall_s", "cpu_s", "trace_s", "lower_s", "xla_s", "xla_compilations")
out.write_text(
    json.dumps(
        {
            "seed": seed,
            "rate": rate,
            "threshold": d["rule"]["threshold"],
            "stages": [dict(zip(keys, r, strict=True)) for r in rows],
        },
        indent=1,
    )
    + "\n"
)
