"""Chunk files of a campaign: written atomically, read back checked, a manifest that
refuses another campaign's folder."""

import hashlib
import json
import pathlib
import zipfile

import numpy as np

from .._files import atomic_write, write_text
from ._settings import Campaign


def fingerprint(identity: dict) -> str:
    """A short hash of a campaign's identity (its settings, estimator settings and
    version): what a chunk file and `campaign.json` carry to prove they belong."""
    text = json.dumps(identity, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _save(path: pathlib.Path, campaign: Campaign | None = None, **arrays) -> None:
    """Write atomically: a chunk file either exists complete or not at all. With
    `campaign`, the chunk carries its settings, seed and their fingerprint."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if campaign is not None:
        ident = campaign.identity()
        arrays["identity"] = np.asarray(fingerprint(ident))
        arrays["settings"] = np.asarray(json.dumps(ident, sort_keys=True))
        arrays["seed"] = np.asarray(campaign.seed)
    atomic_write(
        path,
        lambda f: np.savez(f, **{k: np.asarray(v) for k, v in arrays.items()}),
        binary=True,
    )


_CHECKSUM = "checksum"
# What a chunk carries besides its results: whose campaign it is.
_IDENTITY_KEYS = ("identity", "settings", "seed")


def _check_manifest(out: pathlib.Path, campaign: Campaign, create: bool = True) -> None:
    path = out / "campaign.json"
    ident = campaign.identity()
    if path.exists():
        try:
            old = json.loads(path.read_text(encoding="utf-8"))
            if not isinstance(old, dict):
                raise ValueError("not a JSON object")
        except (OSError, UnicodeDecodeError, ValueError) as e:
            raise ValueError(
                f"{path} is damaged ({e}), so the results beside it cannot be checked "
                "against the settings; use another --out, or delete the folder to "
                "start the campaign again"
            ) from None
        checksum = old.pop(_CHECKSUM, None)
        if checksum is not None and checksum != fingerprint(old):
            raise ValueError(
                f"{path} was edited after the campaign wrote it (its settings no "
                "longer match its checksum), so the chunks beside it cannot be trusted "
                "to belong to them; restore it, use another --out, or delete the "
                "folder to start again"
            )
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
        write_text(path, json.dumps({**ident, _CHECKSUM: fingerprint(ident)}, indent=2))


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
    if "identity" not in arrays:
        return "it carries no campaign settings (an older or foreign file)"
    if str(arrays["identity"]) != fingerprint(campaign.identity()):
        try:
            theirs = json.loads(str(arrays["settings"]))
        except (KeyError, ValueError):
            theirs = {}
        ours = campaign.identity()
        diff = {k: (theirs.get(k), v) for k, v in ours.items() if theirs.get(k) != v}
        return "computed with other campaign settings " + (
            ", ".join(f"{k} {a!r}, not {b!r}" for k, (a, b) in diff.items())
            if diff and theirs
            else "(its fingerprint differs)"
        )
    shape = (campaign.batch, windows, 6)
    if arrays["values"].shape != shape or arrays["stderr"].shape != shape:
        return f"values of shape {arrays['values'].shape}, expected {shape}"
    if not np.array_equal(arrays["flight"], campaign.flight_indices(c)):
        return f"flights {arrays['flight'].tolist()} are not those of chunk {c}"
    return None
