"""Benchmark: two processes started together, each a first launch-vehicle fit and
diagnosis (a 30 s flight of the independent generator at 50 Hz, seeds 3 and 13),
sharing one empty persistent compilation cache: what two test workers, or two
commands started at once, pay for the programs they both need. Each process's CPU
seconds, its diagnosis's threshold and largest statistic (the numbers must not
depend on which process compiled).

Writes `benchmarks/results/concurrent_diagnoses.json`. Run from the repository
root: `python benchmarks/concurrent_diagnoses.py`.
"""

import json
import os
import pathlib
import subprocess
import sys
import tempfile


HERE = pathlib.Path(__file__).resolve().parent
SEEDS = (3, 13)


def child(seed: int) -> dict:
    import resource

    import jax

    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_numpy_rank_promotion", "raise")
    from diffpegasus._cache import enable_cache

    enable_cache()
    sys.path.insert(0, str(HERE.parent))
    from tests import independent_generator as gen

    import diffpegasus as dp
    from diffpegasus.discrepancy import diagnose, fit_log, vehicle_entry

    folder = pathlib.Path(tempfile.mkdtemp())
    lg = dp.read_log(gen.make_log(folder / "f.csv", seed, 50.0, 30.0, None))
    d = diagnose(fit_log(vehicle_entry("pegasus"), lg))
    r = resource.getrusage(resource.RUSAGE_SELF)
    return {
        "seed": seed,
        "cpu_s": r.ru_utime + r.ru_stime,
        "threshold": d["rule"]["threshold"],
        "largest_statistic": max(row["statistic"] for row in d["ranking"]),
    }


def main():
    cache = tempfile.mkdtemp(prefix="concurrent-diagnoses-")
    env = dict(
        os.environ,
        JAX_COMPILATION_CACHE_DIR=cache,
        XLA_FLAGS="--xla_force_host_platform_device_count=2",
        OPENBLAS_NUM_THREADS="1",
    )
    env.pop("DIFFPEGASUS_NO_CACHE", None)
    procs = [
        subprocess.Popen(
            [sys.executable, __file__, "--child", str(s)],
            env=env,
            stdout=subprocess.PIPE,
            text=True,
        )
        for s in SEEDS
    ]
    rows = [json.loads(p.communicate()[0].strip().splitlines()[-1]) for p in procs]
    out = {
        "processes": rows,
        "cpu_s_total": sum(r["cpu_s"] for r in rows),
        "load_average_1min_at_end": os.getloadavg()[0],
    }
    path = HERE / "results" / "concurrent_diagnoses.json"
    path.write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--child":
        print(json.dumps(child(int(sys.argv[2]))))
    else:
        main()
