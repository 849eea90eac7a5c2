"""Spread a batch over the available devices.

On CPU, JAX sees one device unless told otherwise; to use every core, set
`XLA_FLAGS=--xla_force_host_platform_device_count=N` before JAX is imported (the
benchmark scripts do). On several GPUs the same code shards over them.

Only this process's devices (`jax.local_devices()`) are used: after
`jax.distributed.initialize()` every process works on batches of its own (a
campaign hands each process whole chunks, see `_montecarlo.py`), so a batch never
needs to cross hosts.
"""

import functools

import jax
import numpy as np
from jax.sharding import AxisType, NamedSharding, PartitionSpec


def batch_sharding(batch_size: int) -> NamedSharding | None:
    """A sharding that splits a leading batch axis over this process's devices, or
    `None` when there is one device or the batch does not divide evenly."""
    devices = jax.local_devices()
    n = len(devices)
    if n == 1 or batch_size % n:
        return None
    mesh = jax.sharding.Mesh(
        np.asarray(devices), ("batch",), axis_types=(AxisType.Auto,)
    )
    return NamedSharding(mesh, PartitionSpec("batch"))


def shard_batch(tree):
    """Place every array leaf of `tree` (leading axis = batch) across the devices.

    The jitted, vmapped computation that consumes it is then partitioned by XLA, one
    slice of the batch per device. A no-op on one device.
    """
    leaves = [x for x in jax.tree_util.tree_leaves(tree) if hasattr(x, "shape")]
    if not leaves:
        return tree
    sharding = batch_sharding(leaves[0].shape[0])
    if sharding is None:
        return tree
    return jax.device_put(tree, sharding)


@functools.cache
def _jitted(fn):
    return jax.jit(fn)


@functools.cache
def _per_device(fn, mesh):
    spec = PartitionSpec("batch")
    # check_vma=False: equinox's runtime checks inside diffrax use lax.cond branches
    # whose outputs shard_map's varying-axis typing would reject
    return jax.jit(
        jax.shard_map(fn, mesh=mesh, in_specs=spec, out_specs=spec, check_vma=False)
    )


def map_over_devices(fn, tree):
    """Run `fn` (a batched function: leading axis in, leading axis out) on each
    device's slice of the batch with `jax.shard_map`, or jitted on one device when
    there is one device or the batch does not divide evenly.

    For programs with long while loops (the OEM fits) this compiles the per-device
    program once, where letting XLA partition the whole batched program (as
    [`shard_batch`][] does) took several times longer to compile.
    """
    leaves = [x for x in jax.tree_util.tree_leaves(tree) if hasattr(x, "shape")]
    sharding = batch_sharding(leaves[0].shape[0]) if leaves else None
    if sharding is None:
        return _jitted(fn)(tree)
    return _per_device(fn, sharding.mesh)(jax.device_put(tree, sharding))
