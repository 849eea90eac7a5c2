"""JAX's persistent compilation cache in a user cache folder, so a program is
compiled once per machine rather than once per command.

The command line switches it on before anything is compiled ([`enable_cache`][]):
`$JAX_COMPILATION_CACHE_DIR` if set, else `$XDG_CACHE_HOME/diffpegasus/jax`, else
`~/.cache/diffpegasus/jax`. `DIFFPEGASUS_NO_CACHE=1` (or `diffpegasus --no-cache`)
turns it off. The cache key holds the program, the JAX/XLA versions, the XLA flags
and the devices, so a stale entry is never used: a changed program is compiled again.
The folder grows by a few MB per distinct program and may be deleted at any time.

What the cache cannot hold: executables with host callbacks. Equinox's runtime checks
(`eqx.error_if`, used inside `diffrax.diffeqsolve` on traced times and by lineax and
optimistix when `throw=True`) are host callbacks under the default
`EQX_ON_ERROR=raise`, so a jitted program that calls `diffeqsolve` with traced
`t0`/`t1`/`SaveAt(ts=...)` is compiled again every run. Tracing and lowering are
never cached either (only XLA's compilation is).
"""

import os
import pathlib


# Programs that compile faster than this are not written (JAX's default is 1 s, which
# leaves out the mid-sized programs a command compiles by the dozen); the tiny
# element-wise ones compile in milliseconds, as fast as a cache read.
MIN_COMPILE_SECONDS = 0.1


def cache_disabled() -> bool:
    """Whether `DIFFPEGASUS_NO_CACHE` asks for no persistent cache (any value but
    empty, `0`, `false`, `no`)."""
    value = os.environ.get("DIFFPEGASUS_NO_CACHE", "").strip().lower()
    return value not in ("", "0", "false", "no")


def default_cache_dir() -> pathlib.Path:
    """`$JAX_COMPILATION_CACHE_DIR`, else `$XDG_CACHE_HOME/diffpegasus/jax`, else
    `~/.cache/diffpegasus/jax`."""
    explicit = os.environ.get("JAX_COMPILATION_CACHE_DIR")
    if explicit:
        return pathlib.Path(explicit)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(
        os.path.expanduser("~"), ".cache"
    )
    return pathlib.Path(base) / "diffpegasus" / "jax"


def enable_cache(path: str | os.PathLike | None = None) -> pathlib.Path | None:
    """Switch JAX's persistent compilation cache on (call before the first
    compilation; later calls keep the folder already in use).

    **Arguments:** `path`, the cache folder (default [`default_cache_dir`][]).

    **Returns:** the folder, or `None` when `DIFFPEGASUS_NO_CACHE` is set or the
    folder cannot be created (then every program is compiled as before; the cache
    is a speed-up, never a requirement).
    """
    import jax

    if cache_disabled():
        return None
    folder = pathlib.Path(path) if path is not None else default_cache_dir()
    try:
        # private: whoever can write the cache can run code in our processes
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError:
        return None
    if not os.access(folder, os.W_OK | os.X_OK):
        return None
    current = jax.config.jax_compilation_cache_dir
    if current and path is None:
        folder = pathlib.Path(current)  # set by the user or an earlier call: keep it
    else:
        jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_SECONDS)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return folder
