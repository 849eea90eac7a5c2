"""Chunk files of a campaign: written atomically, read back checked, a manifest that
refuses another campaign's folder."""

import json
import os
import pathlib
import zipfile

import numpy as np

from ._settings import (
    Campaign,
)


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
