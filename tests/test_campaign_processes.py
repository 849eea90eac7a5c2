"""A campaign run by two coordinated processes (jax.distributed on 127.0.0.1, one
CPU device each) gives the same files as the same campaign in one process."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest


ARGS = [
    "montecarlo",
    "--samples=4",
    "--batch=1",
    # the OEM compiles for minutes in each of the three processes on 2 busy cores;
    # the chunk sharing, the barriers and the single summary are the same for it
    "--methods=lse",
    "--duration=10",
    "--sample-rate=200",
]


def _run(out, *extra):
    env = dict(os.environ)
    # one CPU device per process, in the reference run too, so that every chunk is
    # the same program on the same device count and must give the same bits
    env["XLA_FLAGS"] = "--xla_force_host_platform_device_count=1"
    done = subprocess.run(
        [sys.executable, "-m", "diffpegasus", *ARGS, f"--out={out}", *extra],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return done


@pytest.mark.slow
def test_two_processes_equal_one(tmp_path):
    one, two = tmp_path / "one", tmp_path / "two"
    _run(one)
    done = _run(two, "--processes=2")
    # both processes took chunks, and process 0 alone printed the tables
    assert "process 0: chunk" in done.stderr and "process 1: chunk" in done.stderr
    assert done.stdout.count("Means of the per-flight MSE") == 1
    for method in ("lse",):
        for c in range(4):
            a = np.load(one / "chunks" / method / f"{c:04d}.npz")
            b = np.load(two / "chunks" / method / f"{c:04d}.npz")
            assert set(a.files) == set(b.files)
            for k in a.files:
                if k != "seconds":
                    np.testing.assert_array_equal(
                        a[k], b[k], err_msg=f"{method} {c} {k}"
                    )
    assert (one / "mse.csv").read_text() == (two / "mse.csv").read_text()
    s1 = json.loads((one / "summary.json").read_text())
    s2 = json.loads((two / "summary.json").read_text())
    assert s1["means"] == s2["means"]
    assert s2["times"]["processes"] == 2 and s1["times"]["processes"] == 1
    # the second process's wall times are kept beside process 0's
    assert (two / "timings-p1.jsonl").exists()
