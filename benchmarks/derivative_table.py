"""CPU seconds of the `compare` command's derivative table on two launch-vehicle
logs of one shape in one process: the first compiles its program, the second
should compile nothing. Writes `benchmarks/results/derivative_table.json`.

    python benchmarks/derivative_table.py

Run from the repository root, without a persistent compilation cache (the default
here), so the first table pays its compilation.
"""

import json
import os
import pathlib
import resource


os.environ.setdefault("DIFFPEGASUS_NO_CACHE", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import jax  # noqa: E402


jax.config.update("jax_enable_x64", True)

import diffpegasus as dp  # noqa: E402
from diffpegasus.discrepancy import derivative_table, fit_log, vehicle_entry  # noqa: E402


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main():
    entry = vehicle_entry("pegasus")
    rows = []
    for seed in (5, 6):  # two 10 s flights at 50 Hz: one log shape
        config = dp.pegasus.PegasusConfig(t_final=10.0, sample_rate=50.0)
        log = dp.pegasus.flight_to_log(
            dp.pegasus.simulate(config, jax.random.key(seed))
        )
        ff = fit_log(entry, log)
        start = _cpu()
        table = derivative_table(ff)
        rows.append({"seed": seed, "cpu_s": _cpu() - start, "table": table})
        print(f"seed {seed}: derivative table {rows[-1]['cpu_s']:.2f} CPU-s")
    out = pathlib.Path(__file__).parent / "results" / "derivative_table.json"
    out.write_text(json.dumps({"tables": rows}, indent=1))


if __name__ == "__main__":
    main()
