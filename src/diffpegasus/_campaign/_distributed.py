"""Several processes and hosts on one campaign: JAX's multi-controller runtime, a
local launcher, and the chunk counter of its coordination service."""

import os
import sys
import time

import jax


class _Processes:
    """This process's share of a campaign: its index among the processes, the next
    chunk to compute (a counter shared through JAX's coordination service when
    there are several processes) and barriers."""

    # a barrier waits for the slowest process's chunks: up to a week
    TIMEOUT_MS = 7 * 24 * 3600 * 1000

    def __init__(self):
        self.count = jax.process_count()
        self.index = jax.process_index()
        self._next = 0
        self._client = None
        if self.count > 1:
            from jax._src import distributed

            self._client = distributed.global_state.client

    def next_chunk(self) -> int:
        if self._client is None:
            self._next += 1
            return self._next - 1
        return self._client.key_value_increment("diffpegasus/campaign/next", 1) - 1

    def barrier(self, name: str) -> None:
        if self._client is not None:
            self._client.wait_at_barrier(
                f"diffpegasus/campaign/{name}", self.TIMEOUT_MS
            )


def _note(message: str) -> None:
    sys.stderr.write(f"{message}\n")
    sys.stderr.flush()


def _warn(message: str) -> None:
    _note(f"warning: {message}")


def start_distributed(
    coordinator: str | None, num_processes: int | None, process_id: int | None
) -> None:
    """`jax.distributed.initialize` for a campaign run by several processes (call
    before JAX's first computation); nothing when all three are `None`.

    **Arguments:** `coordinator`, `HOST:PORT` of process 0's coordination service
    (the same for every process; on `127.0.0.1` or `localhost` it listens there
    only), or `auto` to take all three from the cluster's environment (SLURM, Open
    MPI, ...; see `jax.distributed.initialize`); `num_processes`; `process_id` in
    `0 .. num_processes - 1`.
    """
    if coordinator is None and num_processes is None and process_id is None:
        return
    if coordinator == "auto":
        jax.distributed.initialize()
        return
    if coordinator is None or num_processes is None or process_id is None:
        raise ValueError(
            "several processes need all of --coordinator HOST:PORT, "
            "--num-processes N and --process-id I (or --coordinator auto)"
        )
    host, _, port = coordinator.rpartition(":")
    if not host or not port.isdigit():
        raise ValueError(f"--coordinator must be HOST:PORT, got {coordinator!r}")
    if num_processes < 1 or not 0 <= process_id < num_processes:
        raise ValueError(
            f"--process-id must be in 0..{num_processes - 1} with --num-processes "
            f"{num_processes}, got {process_id}"
        )
    local = host in ("127.0.0.1", "localhost")
    jax.distributed.initialize(
        coordinator_address=coordinator,
        num_processes=num_processes,
        process_id=process_id,
        coordinator_bind_address=f"127.0.0.1:{port}" if local else None,
    )


def launch_local(argv: list[str], processes: int) -> None:
    """Run `diffpegasus <argv>` as `processes` coordinated processes on this machine
    (coordination service on 127.0.0.1, the CPU cores shared out unless `XLA_FLAGS`
    sets the device count) and wait for all of them; if one fails the others are
    stopped and `ValueError` says which (a rerun resumes the campaign)."""
    import socket
    import subprocess

    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    env = dict(os.environ)
    if "xla_force_host_platform_device_count" not in env.get("XLA_FLAGS", ""):
        per = max(1, (os.cpu_count() or 1) // processes)
        flag = f"--xla_force_host_platform_device_count={per}"
        env["XLA_FLAGS"] = f"{env.get('XLA_FLAGS', '')} {flag}".strip()
    children = [
        subprocess.Popen(
            [
                sys.executable,
                "-m",
                "diffpegasus",
                *argv,
                f"--coordinator=127.0.0.1:{port}",
                f"--num-processes={processes}",
                f"--process-id={i}",
            ],
            env=env,
            stdout=subprocess.DEVNULL,  # process 0's summary is printed by the caller
        )
        for i in range(processes)
    ]
    failed = None
    try:
        while failed is None and any(p.poll() is None for p in children):
            failed = next(
                (i for i, p in enumerate(children) if p.poll() not in (None, 0)), None
            )
            time.sleep(0.2)
        if failed is None:
            failed = next((i for i, p in enumerate(children) if p.returncode), None)
    finally:
        for p in children:
            if p.poll() is None:
                p.terminate()
        for p in children:
            p.wait()
    if failed is not None:
        raise ValueError(
            f"campaign process {failed} of {processes} failed (exit code "
            f"{children[failed].returncode}, messages above); the others were "
            "stopped; run the same command again to resume"
        )
