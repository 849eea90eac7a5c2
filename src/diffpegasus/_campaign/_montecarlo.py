"""Monte Carlo comparison of LSE, NN+LSE and OEM (thesis chapter 6), resumable.

A campaign draws `samples` perturbed flights (thesis Table 6.1, uniform, seeded) and
works through them in chunks of `batch` flights. Per chunk the flights are simulated
in one vmapped call and every method runs batched over the chunk, the batch axis
sharded over the devices (`jax.sharding`, see `_sharding.py`). Each result is saved
as `chunks/<method>/<chunk>.npz` the moment it exists, so an interrupted campaign
resumes where it stopped and a rerun with the same settings recomputes nothing; the
draws depend on the seed and the flight index only (not on `batch`), so the same seed
gives the same numbers. A chunk file that cannot be read back (truncated, garbage, or
from another campaign) is reported on stderr with its path and computed again.

Several processes (on one machine or many hosts, after `jax.distributed.initialize()`)
run one campaign into a shared folder: process 0 checks the folder and trains the
network, every process then takes the next chunk not yet taken (a counter in JAX's
coordination service) and computes it on its own devices, and process 0 writes the
summary once all chunks exist.

MSE of a flight and method: the mean over the counted windows with an estimate of
their own of (estimate - truth)^2 per degree, truth being the true derivative
averaged over the window (the `true_*` columns, which include the flight's
perturbation). Counted windows start at or after `ignition` and have a mean measured
dynamic pressure of at least `min_qbar` (high in the climb the aerodynamic forces
vanish into the noise: a +20% thrust flight is at 88 km and 30 Pa at burnout).
"""

import dataclasses
import functools
import json
import math
import os
import pathlib
import sys
import time
import zipfile

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._estimate._lse import lse_arrays, window_truth, windowed_least_squares
from .._estimate._nn import (
    load_network,
    network_inputs,
    save_network,
    train_network,
)
from .._estimate._pegasus_oem import oem_setup, windowed_lift_drag
from .._estimate._windowed_oem import fit_windowed_oem
from .._estimate._windows import WindowLayout
from .._simulate._solve import (
    elevator_command,
    flight_to_log,
    PegasusConfig,
    Perturbation,
    simulate,
    simulate_batch,
)
from .._vehicle._pegasus._aerodynamics import DERIVATIVE_NAMES
from ._sharding import map_over_devices, shard_batch


METHODS = ("lse", "nn", "oem")
# Fixed settings of the estimators in a campaign (part of its identity on disk).
ESTIMATOR_SETTINGS = {
    "lse": {"window_s": 0.5, "tol": 1e-2},
    "nn": {"width": 10, "depth": 1, "derivatives": "lse"},
    "oem": {"parameters": "linear", "start": "lse", "axes": "body", "rtol": 1e-5},
}
LABELS = {"lse": "LSE", "nn": "NN+LSE", "oem": "OEM"}
# Thesis Tables 6.2 and 6.3 (per degree squared).
THESIS_MEANS = {
    "lse": (4.25e-5, 1.78e-6, 1.19e-5, 3.41e-6, 1.98e-5, 1.09e-5),
    "nn": (4.01e-5, 2.03e-6, 1.30e-5, 3.14e-6, 3.07e-5, 1.10e-5),
    "oem": (5.07e-6, 8.92e-7, 1.55e-6, 3.40e-7, 2.59e-6, 9.16e-7),
}
THESIS_STD = {
    "lse": (5.52e-6, 3.56e-7, 6.75e-6, 2.54e-6, 3.83e-6, 3.10e-6),
    "nn": (3.74e-6, 6.93e-7, 5.06e-6, 1.49e-6, 2.23e-5, 3.75e-6),
    "oem": (1.55e-6, 7.28e-7, 6.10e-7, 3.07e-7, 1.45e-6, 2.36e-7),
}
# Thesis run times per 100 flights, s (section 6.3 / SPEC section 4).
THESIS_SECONDS = {"lse": 360.0, "nn": 720.0, "nn_training": 3600.0, "oem": 131_400.0}


@dataclasses.dataclass(frozen=True)
class Campaign:
    """Settings of a Monte Carlo campaign (all part of its identity on disk).

    **Fields:** `samples` flights; `methods`; `seed`; `batch` flights per chunk (a
    multiple of the device count to shard); flight `t_final` (s) and `sample_rate`
    (Hz); OEM `decimate`, `window` and `node_interval` (s); `ignition` (s, windows
    before it do not count); `nn_epochs` for training the network.
    """

    samples: int = 100
    methods: tuple[str, ...] = METHODS
    seed: int = 0
    batch: int = 10
    t_final: float = 80.3
    sample_rate: float = 1000.0
    decimate: int = 5
    window: float = 0.5
    node_interval: float = 2.0
    ignition: float = 5.0
    min_qbar: float = 2000.0
    nn_epochs: int = 1000

    def __post_init__(self):
        unknown = [m for m in self.methods if m not in METHODS]
        if unknown or not self.methods:
            raise ValueError(
                f"methods must be a non-empty subset of {','.join(METHODS)}, "
                f"got {','.join(self.methods) or 'nothing'}"
            )
        if self.samples < 1 or self.batch < 1:
            raise ValueError("samples and batch must be positive")

    @property
    def config(self) -> PegasusConfig:
        return PegasusConfig(t_final=self.t_final, sample_rate=self.sample_rate)

    @property
    def chunks(self) -> int:
        return math.ceil(self.samples / self.batch)

    def identity(self) -> dict:
        """Everything that changes the numbers (`methods` only adds files): the
        settings, the fixed estimator settings and the package version."""
        from importlib.metadata import version

        d = dataclasses.asdict(self)
        d.pop("methods")
        d["estimators"] = ESTIMATOR_SETTINGS
        d["diffpegasus"] = version("diffpegasus")
        return d

    def flight_indices(self, chunk: int) -> np.ndarray:
        """The flights of a chunk; the last chunk is padded with repeats of its last
        flight so every chunk has one shape (one compilation)."""
        idx = np.arange(chunk * self.batch, (chunk + 1) * self.batch)
        return np.minimum(idx, self.samples - 1)


def draws(campaign: Campaign) -> tuple[jax.Array, Perturbation]:
    """Noise keys `(samples,)` and perturbations of every flight of the campaign;
    flight `i`'s draws depend on the seed and `i` only (not on the campaign size)."""
    key = jax.random.key(campaign.seed)
    k_noise, k_pert = jax.random.split(key)
    index = jnp.arange(campaign.samples)
    noise = jax.vmap(lambda i: jax.random.fold_in(k_noise, i))(index)
    pert = jax.vmap(lambda i: Perturbation.sample(jax.random.fold_in(k_pert, i)))(index)
    return noise, pert


def training_logs(t_final: float = 80.3, sample_rate: float = 1000.0):
    """Three simulated training flights for the network (nominal vehicle; pulse,
    3-2-1-1 and multisine excitation; seeds 11-13)."""
    return [
        flight_to_log(
            simulate(
                PegasusConfig(
                    elevator=elevator_command(name),
                    t_final=t_final,
                    sample_rate=sample_rate,
                ),
                jax.random.key(seed),
            )
        )
        for name, seed in (("pulse", 11), ("3211", 12), ("multisine", 13))
    ]


@jax.jit
def _take(tree, idx):
    return jax.tree_util.tree_map(lambda x: x[idx], tree)


@functools.partial(jax.jit, static_argnames=("layout", "s_ref", "c_ref"))
def _lse_chunk(channels, layout, s_ref, c_ref):
    def one(c):
        out = lse_arrays(c, layout, s_ref=s_ref, c_ref=c_ref)
        return out["values"], out["stderr"], ~out["rank_deficient"]

    return jax.vmap(one)(channels)


@eqx.filter_jit
def _nn_chunk(net, channels, layout):
    deg = 180.0 / jnp.pi

    def one(c):
        coeffs = jax.vmap(net)(network_inputs(c))
        a = layout.split(jnp.stack([c["alpha"], c["de"]], axis=-1))
        theta, stderr, _, _, ok = windowed_least_squares(
            a, layout.split(coeffs), layout.mask(), column_scale=jnp.array([deg, deg])
        )
        values = jnp.swapaxes(theta, 1, 2).reshape(layout.count, 6)
        sd = jnp.swapaxes(stderr, 1, 2).reshape(layout.count, 6)
        return values, sd, ok

    return jax.vmap(one)(channels)


def _oem_chunk(setups):
    def one(s):
        fit = fit_windowed_oem(
            s.problem, s.theta0, s.nodes0, linear=s.linear, active=s.active
        )
        values, sd, ok, flags = windowed_lift_drag(fit, s.alpha, "body")
        return values, sd, ok, flags["converged"][0], flags["iterations"][0]

    return jax.vmap(one)(setups)


def _save(path: pathlib.Path, **arrays) -> None:
    """Write atomically: a chunk file either exists complete or not at all."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, **{k: np.asarray(v) for k, v in arrays.items()})
    os.replace(tmp, path)


def _check_manifest(out: pathlib.Path, campaign: Campaign, create: bool = True) -> None:
    path = out / "campaign.json"
    ident = campaign.identity()
    if path.exists():
        try:
            old = json.loads(path.read_text())
            if not isinstance(old, dict):
                raise ValueError("not a JSON object")
        except (OSError, UnicodeDecodeError, ValueError) as e:
            raise ValueError(
                f"{path} is damaged ({e}), so the results beside it cannot be checked "
                "against the settings; use another --out, or delete the folder to "
                "start the campaign again"
            ) from None
        if old != ident:
            diff = {k: (old.get(k), v) for k, v in ident.items() if old.get(k) != v}
            raise ValueError(
                f"{out} holds a campaign with other settings {diff} (old, new); "
                "use another --out or delete it"
            )
    elif not create:
        raise ValueError(f"{path} is missing (process 0 writes it)")
    else:
        if (out / "chunks").exists():
            raise ValueError(
                f"{out} holds campaign results but no campaign.json to check them "
                "against; use another --out or delete it"
            )
        out.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(ident, indent=2))
        os.replace(tmp, path)


# Errors numpy raises on a chunk file that is not a complete .npz of plain arrays.
_READ_ERRORS = (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile)
_CHUNK_KEYS = {
    "lse": ("values", "stderr", "valid", "seconds", "flight", "truth", "qbar"),
    "nn": ("values", "stderr", "valid", "seconds", "flight", "truth", "qbar"),
    "oem": (
        "values",
        "stderr",
        "valid",
        "seconds",
        "flight",
        "truth",
        "qbar",
        "converged",
        "iterations",
    ),
}


def _read_chunk(path: pathlib.Path, method: str) -> dict[str, np.ndarray]:
    """The arrays of a chunk file; `ValueError` naming the file if it is damaged
    (never unpickles: a chunk holds plain arrays only)."""
    try:
        with open(path, "rb") as f:
            if f.read(4) != b"PK\x03\x04":
                # numpy would take it for a pickle and suggest loading it unsafely
                raise ValueError("not an .npz archive")
        with np.load(path, allow_pickle=False) as f:
            arrays = {k: f[k] for k in f.files}
    except _READ_ERRORS as e:
        reason = str(e) if "pickle" not in str(e) else "not arrays only"
        raise ValueError(f"{path}: damaged campaign chunk ({reason})") from None
    missing = [k for k in _CHUNK_KEYS[method] if k not in arrays]
    if missing:
        raise ValueError(
            f"{path}: damaged campaign chunk (no {', '.join(missing)})"
        ) from None
    return arrays


def _chunk_problem(
    path: pathlib.Path, method: str, campaign: Campaign, c: int, windows: int
) -> str | None:
    """Why the chunk file `path` cannot be used (`None` if it can)."""
    try:
        arrays = _read_chunk(path, method)
    except ValueError as e:
        return str(e).split(": ", 1)[1]
    shape = (campaign.batch, windows, 6)
    if arrays["values"].shape != shape or arrays["stderr"].shape != shape:
        return f"values of shape {arrays['values'].shape}, expected {shape}"
    if not np.array_equal(arrays["flight"], campaign.flight_indices(c)):
        return f"flights {arrays['flight'].tolist()} are not those of chunk {c}"
    return None


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


def _network(campaign: Campaign, out: pathlib.Path, record):
    """The campaign's network: read from `network.eqx`, else trained and saved
    (also when the file is damaged: training is seeded, so it gives the same one)."""
    net_path = out / "network.eqx"
    if net_path.exists():
        try:
            return load_network(net_path)
        except Exception as e:  # any failure to read it back: train it again
            _warn(f"{net_path} is damaged ({type(e).__name__}: {e}); training again")
    t0 = time.perf_counter()
    net, _ = train_network(
        training_logs(campaign.t_final, campaign.sample_rate),
        jax.random.key(campaign.seed),
        max_epochs=campaign.nn_epochs,
    )
    save_network(net_path, net)
    record("nn_training", time.perf_counter() - t0)
    return net


def run_campaign(
    campaign: Campaign, out: str | os.PathLike, *, progress: bool = True
) -> dict:
    """Run (or resume) a campaign into `out` and write its tables and figures.

    Run by several processes after `jax.distributed.initialize()` (all with the same
    `campaign` and a shared `out`), each computes the chunks it takes on its own
    devices and process 0 writes the reports.

    **Returns:** the summary dict also written as `summary.json`.
    """
    from tqdm.auto import tqdm

    group = _Processes()
    out = pathlib.Path(out)
    if group.index == 0:
        _check_manifest(out, campaign)
    group.barrier("manifest")
    if group.index != 0:
        _check_manifest(out, campaign, create=False)
    keys, perturbations = draws(campaign)
    config = campaign.config
    n_samples = len(config.times)
    layout = WindowLayout.make(n_samples, campaign.sample_rate, campaign.window)
    s_ref, c_ref = config.vehicle.s_ref, config.vehicle.c_ref
    timings = out / (
        "timings.jsonl" if group.index == 0 else f"timings-p{group.index}.jsonl"
    )

    def record(stage, seconds):
        # appended as it happens, so the wall times survive interruptions and resumes
        with open(timings, "a") as f:
            f.write(json.dumps({"stage": stage, "seconds": seconds}) + "\n")

    net = None
    if "nn" in campaign.methods:
        if group.index == 0:
            net = _network(campaign, out, record)
        group.barrier("network")
        if group.index != 0:
            net = load_network(out / "network.eqx")

    def chunk_path(method, c):
        return out / "chunks" / method / f"{c:04d}.npz"

    def usable(method, c):
        path = chunk_path(method, c)
        if not path.exists():
            return False
        problem = _chunk_problem(path, method, campaign, c, layout.count)
        if problem is None:
            return True
        _warn(f"damaged campaign chunk {path} ({problem}); computing it again")
        path.unlink()
        return False

    def finish(method, c, t0, values, stderr, valid, **arrays):
        seconds = time.perf_counter() - t0
        record(method, seconds)
        _save(
            chunk_path(method, c),
            values=values,
            stderr=stderr,
            valid=valid,
            seconds=seconds,
            **arrays,
        )
        bars[method].update()

    stages = ("simulate", *campaign.methods)
    bars = {
        s: tqdm(
            total=campaign.chunks,
            desc=f"{s:>8s}",
            unit="chunk",
            position=i,
            disable=not progress or group.count > 1,
            leave=True,
        )
        for i, s in enumerate(stages)
    }
    while (c := group.next_chunk()) < campaign.chunks:
        missing = [m for m in campaign.methods if not usable(m, c)]
        for m in campaign.methods:
            if m not in missing:
                bars[m].update()
        if not missing:
            bars["simulate"].update()
            continue
        idx = campaign.flight_indices(c)
        t0 = time.perf_counter()
        flights = simulate_batch(
            config,
            shard_batch(keys[idx]),
            shard_batch(_take(perturbations, jnp.asarray(idx))),
        )
        channels = jax.block_until_ready(dict(flights.channels))
        record("simulate", time.perf_counter() - t0)
        bars["simulate"].update()
        truth = jax.vmap(lambda ch: window_truth(ch, layout))(channels)
        qbar = jax.vmap(layout.window_mean)(channels["qbar"])
        common = dict(flight=idx, truth=truth, qbar=qbar)
        lse_values = None
        if "lse" in missing or "oem" in missing:
            if "lse" not in missing and "lse" in campaign.methods:
                lse_values = _read_chunk(chunk_path("lse", c), "lse")["values"]
            else:
                t0 = time.perf_counter()
                v, sd, ok = jax.block_until_ready(
                    _lse_chunk(channels, layout, s_ref, c_ref)
                )
                lse_values = np.asarray(v)
                if "lse" in campaign.methods:
                    finish("lse", c, t0, v, sd, ok, **common)
        if "nn" in missing:
            t0 = time.perf_counter()
            v, sd, ok = jax.block_until_ready(_nn_chunk(net, channels, layout))
            finish("nn", c, t0, v, sd, ok, **common)
        if "oem" in missing:
            t0 = time.perf_counter()
            setups = []
            for i in range(len(idx)):
                log = flight_to_log(_take(flights, i))
                setup, _ = oem_setup(
                    log,
                    window=campaign.window,
                    node_interval=campaign.node_interval,
                    decimate=campaign.decimate,
                    min_qbar=campaign.min_qbar,
                    lse=lse_values[i],
                    parameters=ESTIMATOR_SETTINGS["oem"]["parameters"],
                )
                setups.append(setup)
            stacked = jax.tree_util.tree_map(lambda *x: jnp.stack(x), *setups)
            v, sd, ok, conv, its = jax.block_until_ready(
                map_over_devices(_oem_chunk, stacked)
            )
            finish("oem", c, t0, v, sd, ok, converged=conv, iterations=its, **common)
        if group.count > 1:
            _note(f"process {group.index}: chunk {c} of {campaign.chunks} done")
        del flights, channels
    for b in bars.values():
        b.close()
    group.barrier("chunks")
    if group.index == 0:
        start, _ = layout.times(0.0)
        summary = write_reports(campaign, out, np.asarray(start))
    group.barrier("reports")
    if group.index != 0:
        summary = json.loads((out / "summary.json").read_text())
    return summary


def load_results(campaign: Campaign, out: pathlib.Path) -> dict[str, dict]:
    """Per method: arrays over all flights (chunk padding removed)."""
    results = {}
    for m in campaign.methods:
        parts = [
            _read_chunk(out / "chunks" / m / f"{c:04d}.npz", m)
            for c in range(campaign.chunks)
        ]
        merged = {
            k: np.concatenate([p[k] for p in parts]) for k in parts[0] if k != "seconds"
        }
        merged["seconds"] = np.array([float(p["seconds"]) for p in parts])
        keep = np.arange(campaign.samples)
        results[m] = {k: (v[keep] if k != "seconds" else v) for k, v in merged.items()}
    return results


def counted(r: dict, window_start, campaign: Campaign) -> np.ndarray:
    """`(flights, windows)`: the windows that count for the MSE and the coverage."""
    return (
        r["valid"]
        & (window_start[None, :] >= campaign.ignition - 1e-9)
        & (r["qbar"] >= campaign.min_qbar)
    )


def flight_mse(values, truth, use) -> np.ndarray:
    """`(flights, 6)` MSE per degree squared over the windows `use` (NaN for a
    flight without any)."""
    err2 = ((values - truth) * (np.pi / 180.0)) ** 2
    err2 = np.where(use[..., None], err2, 0.0)
    n = use.sum(axis=1)[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, err2.sum(axis=1) / n, np.nan)


def coverage(values, truth, stderr, use, k=2.0):
    """Fraction of the windows `use` whose truth lies within +/- k standard errors,
    per derivative `(6,)` and overall."""
    inside = np.abs(values - truth) <= k * stderr
    per = np.array([inside[..., j][use].mean() for j in range(6)])
    return per, float(inside[use].mean())


def write_reports(campaign, out, window_start) -> dict:
    """mse.csv, the tables, the figures, times.json and summary.json from the chunk
    files in `out`."""
    import csv

    from .._report._plotting import plot_campaign

    results = load_results(campaign, out)
    mse = {
        m: flight_mse(r["values"], r["truth"], counted(r, window_start, campaign))
        for m, r in results.items()
    }
    with open(out / "mse.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["flight", "method", *DERIVATIVE_NAMES])
        for m in campaign.methods:
            for i in range(campaign.samples):
                w.writerow([i, m, *(f"{x:.6e}" for x in mse[m][i])])
    means = {m: np.nanmean(v, axis=0) for m, v in mse.items()}
    stds = {
        m: np.nanstd(v, axis=0, ddof=1) if len(v) > 1 else v[0] * np.nan
        for m, v in mse.items()
    }
    tables = {}
    for name, ours, thesis in (
        ("means", means, THESIS_MEANS),
        ("std", stds, THESIS_STD),
    ):
        cols = [f"{LABELS[m]} ours" for m in campaign.methods] + [
            f"{LABELS[m]} thesis" for m in campaign.methods
        ]
        rows = [
            [
                d,
                *(ours[m][j] for m in campaign.methods),
                *(thesis[m][j] for m in campaign.methods),
            ]
            for j, d in enumerate(DERIVATIVE_NAMES)
        ]
        with open(out / f"mse_{name}.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["derivative", *cols])
            for r in rows:
                w.writerow([r[0], *(f"{x:.3e}" for x in r[1:])])
        md = [
            "| derivative | " + " | ".join(cols) + " |",
            "|---" * (len(cols) + 1) + "|",
        ]
        md += [
            "| " + r[0] + " | " + " | ".join(f"{x:.3g}" for x in r[1:]) + " |"
            for r in rows
        ]
        tables[name] = "\n".join(md)
    title = {
        "means": "Means of the per-flight MSE, (1/deg)^2 (thesis Table 6.2)",
        "std": "Standard deviations of the per-flight MSE, (1/deg)^2 (thesis Table 6.3)",
    }
    dropped = {m: int(np.sum(np.all(np.isnan(v), axis=1))) for m, v in mse.items()}
    note = "Flights without any counted estimate (left out of the means): " + ", ".join(
        f"{LABELS[m]} {n}" for m, n in dropped.items()
    )
    (out / "tables.md").write_text(
        "\n\n".join(f"{title[k]}\n\n{v}" for k, v in tables.items()) + f"\n\n{note}\n"
    )
    plot_campaign(mse, out)
    summary = {
        "campaign": dataclasses.asdict(campaign),
        "mse_definition": (
            "per flight and derivative: mean over the windows from ignition on, with "
            "a mean measured dynamic pressure >= min_qbar and an estimate of their "
            "own, of (estimate - window-mean truth)^2, (1/deg)^2"
        ),
        "means": {
            m: dict(zip(DERIVATIVE_NAMES, map(float, v), strict=True))
            for m, v in means.items()
        },
        "std": {
            m: dict(zip(DERIVATIVE_NAMES, map(float, v), strict=True))
            for m, v in stds.items()
        },
        "flights_without_estimate": {
            m: int(np.sum(np.all(np.isnan(v), axis=1))) for m, v in mse.items()
        },
    }
    if "oem" in results:
        r = results["oem"]
        per, overall = coverage(
            r["values"],
            r["truth"],
            r["stderr"],
            counted(r, window_start, campaign),
        )
        summary["oem_coverage_2sigma"] = {
            "per_derivative": dict(zip(DERIVATIVE_NAMES, map(float, per), strict=True)),
            "overall": overall,
        }
        summary["oem_converged_flights"] = int(np.sum(r["converged"]))
    stages: dict[str, list[float]] = {}
    # timings.jsonl from process 0 (or a single process), timings-p<i>.jsonl from
    # the others; a line cut short by an interruption is skipped
    for log in sorted(out.glob("timings*.jsonl")):
        for line in log.read_text().splitlines():
            try:
                entry = json.loads(line)
                stages.setdefault(entry["stage"], []).append(float(entry["seconds"]))
            except (ValueError, KeyError, TypeError):
                continue
    timing = {
        "total_s": {k: float(np.sum(v)) for k, v in stages.items()},
        "chunk_s": stages,
        "compile_s_estimate": {
            k: float(v[0] - np.median(v[1:]))
            for k, v in stages.items()
            if k != "nn_training" and len(v) > 1
        },
        "s_per_flight_after_compile": {
            k: float(np.median(v[1:]) / campaign.batch)
            for k, v in stages.items()
            if k != "nn_training" and len(v) > 1
        },
        "devices": len(jax.devices()),
        "processes": jax.process_count(),
        "thesis_s_per_100_flights": THESIS_SECONDS,
    }
    (out / "times.json").write_text(json.dumps(timing, indent=2))
    summary["times"] = timing
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary
