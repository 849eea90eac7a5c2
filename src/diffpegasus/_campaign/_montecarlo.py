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

import functools
import json
import os
import pathlib
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._estimate._lse import lse_arrays, window_truth, windowed_least_squares
from .._estimate._nn import (
    load_network,
    save_network,
    train_network,
)
from .._estimate._pegasus_oem import oem_setup, windowed_lift_drag
from .._estimate._windows import WindowLayout
from .._simulate._solve import (
    elevator_command,
    flight_to_log,
    PegasusConfig,
    Perturbation,
    simulate,
    simulate_batch,
)
from .._vehicle._parts import Geometry
from ._distributed import _note, _Processes, _warn
from ._settings import (  # noqa: F401 (the campaign's constants, imported from here)
    Campaign,
    ESTIMATOR_SETTINGS,
    LABELS,
    METHODS,
    THESIS_MEANS,
    THESIS_SECONDS,
    THESIS_STD,
)
from ._sharding import map_over_devices, shard_batch
from ._storage import _check_manifest, _chunk_problem, _read_chunk, _save
from ._summary import (  # noqa: F401 (public through diffpegasus.montecarlo)
    counted,
    coverage,
    flight_mse,
    load_results,
    write_reports,
)


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
        coeffs = net.coefficients(c)
        a = layout.split(jnp.stack([c["alpha"], c["de"]], axis=-1))
        theta, stderr, _, _, ok = windowed_least_squares(
            a, layout.split(coeffs), layout.mask(), column_scale=jnp.array([deg, deg])
        )
        values = jnp.swapaxes(theta, 1, 2).reshape(layout.count, 6)
        sd = jnp.swapaxes(stderr, 1, 2).reshape(layout.count, 6)
        return values, sd, ok

    return jax.vmap(one)(channels)


def _oem_chunk(setups, max_iter: int = 30):
    def one(s):
        fit = s.fit(max_iter=max_iter)
        values, sd, ok, flags = windowed_lift_drag(fit, s.alpha, "body")
        return values, sd, ok, flags["converged"][0], flags["iterations"][0]

    return jax.vmap(one)(setups)


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


@functools.cache
def _oem_chunk_at(max_iter: int):
    # one function object per iteration cap: `map_over_devices` keeps one compiled
    # program per function, so a partial made afresh for every chunk compiled the
    # OEM chunk once per chunk and once per resumed run
    return functools.partial(_oem_chunk, max_iter=max_iter)


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
        foreign = problem.startswith(("computed with other", "it carries no"))
        _warn(
            (
                f"campaign chunk {path} does not belong to this campaign"
                if foreign
                else f"damaged campaign chunk {path}"
            )
            + f" ({problem}); computing it again"
        )
        path.unlink()
        return False

    def finish(method, c, t0, values, stderr, valid, **arrays):
        seconds = time.perf_counter() - t0
        record(method, seconds)
        _save(
            chunk_path(method, c),
            campaign,
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
                    geometry=Geometry(s_ref=s_ref, c_ref=c_ref),
                )
                setups.append(setup)
            # stacked on the host: `jnp.stack` compiles a program per leaf shape,
            # and placing a stacked device array across the devices another one
            # to slice it (about 30 small programs per process); numpy does both
            # without compiling
            stacked = jax.tree_util.tree_map(lambda *x: np.stack(x), *setups)
            v, sd, ok, conv, its = jax.block_until_ready(
                map_over_devices(_oem_chunk_at(campaign.max_iter), stacked)
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
