"""Files that appear complete under their final names or not at all.

Every file the package writes (logs, sidecars, figures, reports, campaign chunks) is
written to a temporary name in the same folder, flushed to disk (`fsync`) and renamed
over the final name: a rename within one file system is atomic, so an interruption
(Ctrl-C, a crash, a full disk, a power cut after the folder's entry is synced) leaves
the old file or the new one, never a truncated one. The temporary file is removed
when the write fails.
"""

import contextlib
import os
import pathlib
import tempfile


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _sync_folder(folder: pathlib.Path) -> None:
    with contextlib.suppress(OSError):  # not every file system syncs folders
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def atomic_write(path, write, *, binary: bool = False) -> pathlib.Path:
    """Call `write(f)` on a temporary file beside `path`, then rename it to `path`.

    The file gets the permissions an ordinary `open` would give it (those of the file
    it replaces, else 0666 less the umask), not `mkstemp`'s private 0600.
    """
    return commit(staged(path, write, binary=binary), path)


def staged(path, write, *, binary: bool = False) -> pathlib.Path:
    """The first half of [`atomic_write`][]: `write(f)` to a synced temporary file
    beside `path`, returned for [`commit`][] (e.g. after writing a file that must
    name this one's hash)."""
    path = pathlib.Path(path)
    try:
        mode = path.stat().st_mode & 0o7777
    except OSError:
        mode = 0o666 & ~_umask()
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, mode)
        with os.fdopen(
            fd, "wb" if binary else "w", newline=None if binary else ""
        ) as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
    except BaseException:
        discard(tmp)
        raise
    return pathlib.Path(tmp)


def commit(tmp, path) -> pathlib.Path:
    """Rename the staged file `tmp` to `path` (atomic) and sync the folder."""
    path = pathlib.Path(path)
    try:
        os.replace(tmp, path)
    except BaseException:
        discard(tmp)
        raise
    _sync_folder(path.parent)
    return path


def discard(tmp) -> None:
    """Remove a staged file that will not be committed."""
    with contextlib.suppress(OSError):
        os.unlink(tmp)


def write_text(path, text: str) -> pathlib.Path:
    """`path.write_text(text)`, atomically."""
    return atomic_write(path, lambda f: f.write(text))


def save_figure(fig, path, **kwargs) -> pathlib.Path:
    """`fig.savefig(path, **kwargs)`, atomically (the format from `path`'s suffix)."""
    path = pathlib.Path(path)
    fmt = kwargs.pop("format", path.suffix.lstrip(".") or "png")
    return atomic_write(
        path, lambda f: fig.savefig(f, format=fmt, **kwargs), binary=True
    )
