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
never cached either (only XLA's compilation is) -- except through
[`kept_call`][]: the engine's solve of `fit` is kept as its exported (traced)
program (`jax.export`, in `programs/` of the cache folder), so that a later process
skips its tracing as well (on the HFB-320 fit, 2-3 s of a 5 s command), and so is a
diagnosis's score test. Two processes that need one kept program at the same time
(two test workers, two campaign processes) do not both compile it: one traces and
compiles it while the other waits on a lock file beside it, then reads both.
"""

import contextlib
import hashlib
import os
import pathlib
import pickle


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
    global _ACTIVE
    _ACTIVE = folder
    return folder


# ---------------------------------------------------------------------------------
# Traced programs kept across processes (jax.export)

_ACTIVE: pathlib.Path | None = None  # the folder enable_cache switched on
_MEMO: dict = {}  # key -> (jitted call of the deserialized program, output skeleton)
_SOURCE_DIGEST: str | None = None
# Code a kept program may refer to by name: a function or class from elsewhere (a
# user's model file) could change without changing the key, so such calls are
# traced as usual. Ours is covered by the digest of the package's source.
_TRUSTED = (
    "diffpegasus", "jax", "jaxlib", "numpy", "equinox", "jaxtyping", "builtins",
    "typing", "collections", "functools", "operator", "math", "copyreg", "abc",
    "enum", "types", "dataclasses",
)  # fmt: skip


def _source_digest() -> str:
    global _SOURCE_DIGEST
    if _SOURCE_DIGEST is None:
        h = hashlib.sha256()
        root = pathlib.Path(__file__).resolve().parent
        for f in sorted(root.rglob("*.py")):
            h.update(str(f.relative_to(root)).encode())
            h.update(f.read_bytes())
        _SOURCE_DIGEST = h.hexdigest()
    return _SOURCE_DIGEST


class _Leaf(tuple):
    """An array argument's place in a key: shape, dtype, weak type."""


class _KeyPickler(pickle.Pickler):
    """Pickles a call's static part; refuses functions and classes from outside
    the trusted modules (their code is not in the key)."""

    def reducer_override(self, obj):
        if isinstance(obj, type) or callable(obj) and hasattr(obj, "__qualname__"):
            module = getattr(obj, "__module__", None) or ""
            if module.split(".")[0] not in _TRUSTED:
                raise pickle.PicklingError(f"{module}.{obj.__qualname__} not trusted")
        return NotImplemented


def _call_key(fn, static: dict, dynamic: dict) -> str:
    import io

    import equinox
    import jax
    import jaxlib
    import numpy as np

    skeleton = jax.tree.map(
        lambda x: _Leaf(
            (
                np.shape(x),
                str(x.dtype if hasattr(x, "dtype") else np.asarray(x).dtype),
                bool(getattr(x, "weak_type", False)),
            )
        ),
        dynamic,
    )
    buf = io.BytesIO()
    _KeyPickler(buf, protocol=5).dump((static, skeleton))
    h = hashlib.sha256()
    for part in (
        _source_digest(),
        f"{fn.__module__}.{fn.__qualname__}",
        jax.__version__,
        jaxlib.__version__,
        equinox.__version__,
        np.__version__,
        str(jax.config.jax_enable_x64),
        jax.default_backend(),
        str(len(jax.devices())),
        jax.devices()[0].device_kind,
    ):
        h.update(part.encode() + b"\0")
    h.update(buf.getvalue())
    return h.hexdigest()


def kept_call(fn, static: dict, dynamic: dict):
    """`fn(**static, **dynamic)` for a jitted `fn` (keyword arguments: `static` the
    static ones, `dynamic` the array pytrees), through its exported program
    (`jax.export`: traced and lowered) kept in the cache folder: the first process
    traces it and writes it; later ones read it and only compile it, which JAX's
    persistent cache answers. The key is a digest of the package's source, the JAX,
    jaxlib, equinox and numpy versions, the backend and device, the static
    arguments (pickled) and the arguments' shapes and dtypes.

    The call is made directly (no file) when the cache is off ([`enable_cache`][]
    not called, or disabled), inside a transformation (traced arguments), when `fn`
    or the static arguments refer to code outside the package (a model file) or when
    the program cannot be kept (host callbacks: then it is compiled as usual); the
    result is the same. Within a process a program is loaded or compiled once.
    """
    import jax

    def direct():
        return fn(**static, **dynamic)

    if _ACTIVE is None or cache_disabled():
        return direct()
    if not (getattr(fn, "__module__", None) or "").startswith("diffpegasus."):
        return direct()  # the key names `fn`; only the package's code is in it
    leaves, treedef = jax.tree.flatten(dynamic)
    if any(isinstance(x, jax.core.Tracer) for x in leaves):
        return direct()
    # device_put: jnp.asarray compiles a small program per shape
    leaves = [x if isinstance(x, jax.Array) else jax.device_put(x) for x in leaves]
    try:
        key = _call_key(fn, static, dynamic)
    except (pickle.PicklingError, TypeError, AttributeError, ValueError):
        return direct()
    if key not in _MEMO:
        path = _ACTIVE / "programs" / f"{key}.bin"
        with _one_at_a_time(path):
            entry = _load_kept(path) or _compile_and_keep(
                fn, static, treedef, leaves, path
            )
            if entry is not None:
                # compiled (or read from JAX's persistent cache) holding the lock,
                # so that a process waiting for it reads both; run once released
                _MEMO[key] = _compiled(entry, leaves)
        if key not in _MEMO:
            return direct()
    call, skeleton = _MEMO[key]
    return jax.tree.unflatten(jax.tree.structure(skeleton), call(*leaves))


def _compiled(entry, leaves):
    """`entry`, the kept program's jitted call, compiled ahead for the arguments
    `leaves`: its first call runs that executable (JAX's own caches hold it, so
    `jax.clear_caches` still frees it)."""
    try:
        entry[0].lower(*leaves).compile()
    except Exception:  # compiled by its first call instead
        pass
    return entry


@contextlib.contextmanager
def _one_at_a_time(path: pathlib.Path):
    """Held while one process reads or traces, keeps and compiles the program at
    `path`: another process that needs the same program meanwhile (two test
    workers, two campaign processes started together) waits, then reads the kept
    program and the compiled one instead of compiling it too. The lock is the
    operating system's (`flock` on a file beside the program), released when its
    holder ends however it ends; where there is none, no process waits."""
    try:
        import fcntl

        path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        lock = open(path.with_suffix(".lock"), "a")  # noqa: SIM115
    except (ImportError, OSError):
        yield
        return
    with lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX)
        except OSError:
            pass
        yield


def _load_kept(path: pathlib.Path):
    import jax

    try:
        data = path.read_bytes()
    except OSError:
        return None
    try:
        # the folder is private to the user (see enable_cache), as the compiled
        # programs of JAX's cache beside it are
        entry = pickle.loads(data)
        exported = entry["exported"]
        if not isinstance(exported, jax.export.Exported):
            return None
        return jax.jit(exported.call), entry["skeleton"]
    except Exception:  # a damaged or foreign entry: trace again
        return None


def _compile_and_keep(fn, static, treedef, leaves, path: pathlib.Path):
    import dataclasses

    import jax

    holder = {}

    def flat(*xs):
        out = fn(**static, **jax.tree.unflatten(treedef, list(xs)))
        holder["skeleton"] = jax.tree.map(lambda _: 0, out)
        return jax.tree.leaves(out)

    try:
        exported = jax.export.export(jax.jit(flat))(*leaves)
    except Exception:  # not exportable (host callbacks): traced as usual
        return None
    try:
        # pickled whole rather than by Exported.serialize, which needs the
        # flatbuffers package (not a dependency); its vjp rule is not kept.
        # (Not the compiled executable: jax.experimental.serialize_executable's
        # CPU executables crashed on loading here.)
        data = pickle.dumps(
            {
                "exported": dataclasses.replace(exported, _get_vjp=None),
                "skeleton": holder["skeleton"],
            }
        )
        path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except Exception:  # no room, read-only: this process still uses it
        pass
    return jax.jit(exported.call), holder["skeleton"]
