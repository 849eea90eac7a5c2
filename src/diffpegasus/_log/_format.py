"""Flight logs: the one CSV + JSON-sidecar format everything reads and writes.

A log is a CSV file with a header row of channel names and one row per sample (SI
units, angles in radians), plus an optional JSON sidecar with the same stem holding
metadata. Reading validates the file and reports the first problem as one
[`LogError`][] line naming the file, column, row and value. Rows are numbered from 1
for the first data row (the header is line 1 of the file, so row r is line r + 1).
"""

import csv
import dataclasses
import hashlib
import json
import math
import os
import pathlib
import re
import warnings
from typing import Any

import numpy as np

from .._errors import LogError as LogError
from .._files import atomic_write, commit, discard, staged
from .._vehicle._pegasus._aerodynamics import DERIVATIVE_NAMES
from ._checks import check_physics, num, PlausibilityError
from ._sidecar import check_sidecar


REQUIRED_CHANNELS = (
    "t",
    "de",
    "ax",
    "az",
    "q",
    "qdot",
    "alpha",
    "V",
    "theta",
    "h",
    "mach",
    "qbar",
    "thrust",
    "mass",
    "Iyy",
    "Iyy_dot",
    "xcg",
    "xcp",
)
TRUTH_CHANNELS = tuple(f"true_{n}" for n in DERIVATIVE_NAMES)
PEGASUS_METADATA = {"S_ref": 13.5, "c_ref": 2.48, "vehicle": "pegasus"}
# Largest magnitude (rad) each angle channel can plausibly have; beyond it the column
# is almost surely in degrees.
_ANGLE_LIMITS = {
    "alpha": 1.2,
    "beta": 1.0,
    "de": 0.8,
    "da": 0.8,
    "dr": 0.8,
    "theta": math.pi,
    "phi": math.pi,
}
_POSITIVE = ("V", "mass", "Iyy")
# Measured on this machine: 2 million rows of the 18 standard channels (694 MB at 17
# digits) read in about 20 s and 0.8 GB; beyond this size a log is refused up front.
MAX_LOG_BYTES = 4 * 2**30
# The sidecar key holding the SHA-256 of the CSV it was written with.
CSV_HASH_KEY = "csv_sha256"


@dataclasses.dataclass(frozen=True)
class FlightLog:
    """A flight log in memory.

    **Fields:**

    - `channels`: name to 1-D float64 array, all of one length (SI units, radians).
    - `metadata`: the sidecar's content (`S_ref`, `c_ref`, `vehicle`,
      `sample_rate_hz`, and whatever the writer recorded).
    - `path`: where it was read from, if anywhere.
    """

    channels: dict[str, np.ndarray]
    metadata: dict[str, Any] = dataclasses.field(default_factory=dict)
    path: pathlib.Path | None = None

    @property
    def t(self) -> np.ndarray:
        """Sample times, s."""
        return self.channels["t"]

    @property
    def sample_rate(self) -> float:
        """Samples per second, Hz."""
        return float(
            self.metadata.get("sample_rate_hz", 1.0 / np.mean(np.diff(self.t)))
        )

    @property
    def s_ref(self) -> float:
        """Reference area, m^2 (sidecar `S_ref`, default Pegasus)."""
        return float(self.metadata.get("S_ref", PEGASUS_METADATA["S_ref"]))

    @property
    def c_ref(self) -> float:
        """Moment reference length, m (sidecar `c_ref`, default Pegasus)."""
        return float(self.metadata.get("c_ref", PEGASUS_METADATA["c_ref"]))

    @property
    def has_truth(self) -> bool:
        """Whether the simulated true derivatives are present."""
        return all(c in self.channels for c in TRUTH_CHANNELS)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.channels[name]

    def __len__(self) -> int:
        return len(self.t)


def sidecar_path(path: str | os.PathLike) -> pathlib.Path:
    """The JSON sidecar next to a log CSV."""
    return pathlib.Path(path).with_suffix(".json")


def write_log(path: str | os.PathLike, log: FlightLog) -> pathlib.Path:
    """Write `log` as CSV plus JSON sidecar; returns the CSV path.

    Required channels come first in the standard order, then the rest sorted. Values
    are written with 17 significant digits, so a read returns the same float64 values.
    """
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    names = [c for c in REQUIRED_CHANNELS if c in log.channels]
    names += sorted(c for c in log.channels if c not in names)
    data = np.column_stack([np.asarray(log.channels[c], float) for c in names])

    bad = ~np.isfinite(data)
    if bad.any():
        row, col = (int(i) for i in np.argwhere(bad)[0])
        raise LogError(
            f"{path}: channel {names[col]!r}, row {row + 1}: value {data[row, col]} "
            "is not finite; a log with NaN or infinity is never written (a simulation "
            "that diverged, or an effect value of nan)"
        )

    def write_csv(f):
        f.write(",".join(names) + "\n")
        np.savetxt(f, data, delimiter=",", fmt="%.17g")

    metadata = {**PEGASUS_METADATA, **log.metadata}
    metadata.pop(CSV_HASH_KEY, None)
    metadata.setdefault("sample_rate_hz", float(1.0 / np.mean(np.diff(log.t))))
    try:
        side_text = json.dumps(_jsonable(metadata), indent=2, allow_nan=False)
    except ValueError:
        raise LogError(
            f"{sidecar_path(path)}: the metadata hold NaN or infinity, which JSON "
            "cannot; nothing was written"
        ) from None
    # The sidecar names the hash of the CSV it belongs to and is renamed in first:
    # an interruption between the two renames leaves the old CSV beside a sidecar
    # whose hash it does not match, which read_log refuses.
    tmp = staged(path, write_csv)
    try:
        with open(tmp, "rb") as f:
            digest = hashlib.file_digest(f, "sha256").hexdigest()
        side_text = side_text[:-1].rstrip() + f',\n  "{CSV_HASH_KEY}": "{digest}"\n}}'
        atomic_write(sidecar_path(path), lambda f: f.write(side_text))
        commit(tmp, path)
    except BaseException:
        discard(tmp)
        raise
    return path


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.generic | np.ndarray):
        return x.tolist()
    return x


def _known(required: tuple[str, ...]) -> frozenset[str]:
    return (
        frozenset(required) | frozenset(REQUIRED_CHANNELS) | frozenset(TRUTH_CHANNELS)
    )


def _check_size(path: pathlib.Path) -> None:
    size = path.stat().st_size
    if size > MAX_LOG_BYTES:
        raise LogError(
            f"{path}: the file is {size / 2**30:.1f} GiB; logs above "
            f"{MAX_LOG_BYTES / 2**30:g} GiB (about {MAX_LOG_BYTES // 350:,} rows of the "
            "standard channels at 17 digits) are refused to keep memory bounded; "
            "split or decimate it"
        )


def _read_rows(
    path: pathlib.Path, known: frozenset[str]
) -> tuple[list[str], np.ndarray]:
    """Header and data of a CSV; columns that are not known channels and hold text
    are dropped. NumPy's strict C parser first, a careful reader that names the bad
    cell only when it fails."""
    try:
        with open(path, encoding="utf-8-sig", newline="") as f:
            header = [h.strip() for h in next(csv.reader([f.readline()]), [])]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                data = np.loadtxt(f, delimiter=",", ndmin=2, comments=None)
        if (
            any(header)
            and data.shape[1] == len(header)
            and len(set(header)) == len(header)
            and data.shape[0] > 0
        ):
            return header, data
    except (ValueError, OSError, UnicodeDecodeError, csv.Error):
        pass  # the careful reader below finds and names the problem
    return _read_rows_carefully(path, known)


# What a number in a log may look like: ASCII decimal, optional exponent, nan, inf.
# Python's float() also takes "1_000" and non-ASCII digits, which are not data.
_NUMBER = re.compile(
    r"\s*[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf|infinity)\s*",
    re.IGNORECASE | re.ASCII,
)
_BLOCK = 65_536


def _read_rows_carefully(
    path: pathlib.Path, known: frozenset[str]
) -> tuple[list[str], np.ndarray]:
    try:
        with open(path, encoding="utf-8-sig", newline="") as f:
            return _parse(path, csv.reader(f), known)
    except OSError as e:
        raise LogError(f"{path}: cannot read the file ({e.strerror})") from None
    except UnicodeDecodeError as e:
        raise LogError(
            f"{path}: not a UTF-8 text CSV file (byte {e.start} of a block cannot be "
            "decoded)"
        ) from None
    except csv.Error as e:
        raise LogError(f"{path}: not a readable CSV file ({e})") from None


def _parse(path, reader, known) -> tuple[list[str], np.ndarray]:
    header = None
    for row in reader:
        if any(cell.strip() for cell in row):
            header = [h.strip() for h in row]
            break
    if header is None:
        raise LogError(f"{path}: the file is empty (expected a header row of channels)")
    if len(header) == 1:
        for sep, name in ((";", "';'"), ("\t", "tabs"), (" ", "spaces")):
            if sep in header[0].strip():
                raise LogError(
                    f"{path}: the columns are separated by {name}; a flight log is "
                    "comma-separated (header t,de,ax,az,...)"
                )
    if all(_NUMBER.fullmatch(h) for h in header):
        raise LogError(
            f"{path}: the file has no header row (its first row is numbers; expected "
            "channel names such as t,de,ax,az,...)"
        )
    for dup in sorted({h for h in header if header.count(h) > 1 and h in known}):
        raise LogError(f"{path}: column {dup!r} appears more than once in the header")
    columns = [j for j, h in enumerate(header) if h in known or header.count(h) == 1]
    text: set[int] = set()  # unknown columns with a cell that is not a number
    blocks, block = [], []
    width = len(header)
    row_number = 0
    for row in reader:
        if not any(cell.strip() for cell in row):
            continue
        row_number += 1
        if len(row) != width:
            raise LogError(
                f"{path}: row {row_number} has {len(row)} values, the header has "
                f"{width}"
            )
        values = []
        for j in columns:
            cell = row[j]
            if j in text:
                values.append(math.nan)
            elif _NUMBER.fullmatch(cell):
                values.append(float(cell))
            elif header[j] in known:
                shown = cell.strip()
                raise LogError(
                    f"{path}: column {header[j]!r}, row {row_number}: "
                    + (
                        "the cell is empty"
                        if not shown
                        else f"{shown!r} is not a number"
                        + (
                            " (write plain digits, no '_' or ',' separators)"
                            if any(ch in shown for ch in "_")
                            else ""
                        )
                    )
                )
            else:
                text.add(j)
                values.append(math.nan)
        block.append(values)
        if len(block) == _BLOCK:
            blocks.append(np.array(block, dtype=float).reshape(-1, len(columns)))
            block = []
    blocks.append(np.array(block, dtype=float).reshape(-1, len(columns)))
    data = np.concatenate(blocks)
    keep = [k for k, j in enumerate(columns) if j not in text]
    return [header[columns[k]] for k in keep], data[:, keep]


def _read_sidecar(path: pathlib.Path) -> dict[str, Any]:
    side = sidecar_path(path)
    if not side.exists():
        return dict(PEGASUS_METADATA)
    try:
        meta = json.loads(side.read_text(encoding="utf-8-sig"))
    except json.JSONDecodeError as e:
        raise LogError(f"{side}: not valid JSON (line {e.lineno}: {e.msg})") from None
    except UnicodeDecodeError:
        raise LogError(f"{side}: not a UTF-8 text file") from None
    except OSError as e:
        raise LogError(f"{side}: cannot read the sidecar ({e.strerror})") from None
    if not isinstance(meta, dict):
        raise LogError(f"{side}: expected a JSON object of metadata")
    expected = meta.pop(CSV_HASH_KEY, None)
    if expected is not None:
        with open(path, "rb") as f:
            digest = hashlib.file_digest(f, "sha256").hexdigest()
        if digest != expected:
            raise LogError(
                f"{side}: the sidecar belongs to another version of {path.name} (its "
                f"{CSV_HASH_KEY} {str(expected)[:12]}... is not the CSV's "
                f"{digest[:12]}...: an interrupted write, or an edited CSV); write the "
                f"pair again, or if you edited the CSV on purpose delete "
                f'"{CSV_HASH_KEY}" from the sidecar'
            )
    try:
        check_sidecar(meta, str(side))
    except ValueError as e:
        raise LogError(str(e)) from None
    return {**PEGASUS_METADATA, **meta}


def validate_channels(
    channels: dict[str, np.ndarray],
    name: str = "log",
    *,
    required: tuple[str, ...] = REQUIRED_CHANNELS,
    min_samples: int = 2,
    resample: bool = False,
) -> dict[str, np.ndarray]:
    """Check a log's channels; returns them (resampled if asked and needed).

    Raises [`LogError`][] for a missing channel, a NaN or infinite value, time not
    strictly increasing, non-uniform sampling (unless `resample`, which interpolates
    onto a uniform grid with a warning), an angle column that looks like degrees, a
    non-positive airspeed, mass or inertia, or fewer than `min_samples` samples.
    """
    missing = [c for c in required if c not in channels]
    if missing:
        lower = {c.lower(): c for c in channels}
        near = [f"{lower[m.lower()]!r}" for m in missing if m.lower() in lower]
        raise LogError(
            f"{name}: missing channel(s) {', '.join(map(repr, missing))}; a flight log "
            f"needs {', '.join(required)}"
            + (
                f" (found {', '.join(near)}: channel names are case-sensitive)"
                if near
                else ""
            )
        )
    n = len(channels["t"])
    known = _known(required)
    for col, values in channels.items():
        if col not in known:
            continue  # extra columns are carried along, never used
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise LogError(
                f"{name}: column {col!r}, row {bad[0] + 1}: value {num(values[bad[0]])} "
                "(NaN and infinity are not allowed)"
            )
    if n < max(min_samples, 2):
        raise LogError(
            f"{name}: only {n} samples; at least {max(min_samples, 2)} are needed"
        )
    t = channels["t"]
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        r = bad[0] + 2
        raise LogError(
            f"{name}: column 't', row {r}: time {num(t[r - 1])} is not after "
            f"{num(t[r - 2])} at row {r - 1} (time must increase strictly)"
        )
    typical = float(np.median(dt))
    off = np.flatnonzero(np.abs(dt - typical) > 1e-6 * typical + 1e-9)
    if off.size:
        r = off[0] + 2
        if not resample:
            raise LogError(
                f"{name}: column 't', row {r}: step {dt[off[0]]:.6g} s differs from "
                f"the typical step {typical:.6g} s (non-uniform sampling; resample the "
                "log or read it with resample=True / --resample)"
            )
        step = (t[-1] - t[0]) / (n - 1)
        warnings.warn(
            f"{name}: non-uniform sampling (first at row {r}); resampled onto a "
            f"uniform {step:.6g} s grid by linear interpolation",
            stacklevel=2,
        )
        grid = t[0] + step * np.arange(n)
        channels = {c: np.interp(grid, t, v) for c, v in channels.items()}
    check_ranges(channels, name)
    return channels


def check_ranges(
    channels: dict[str, np.ndarray],
    name: str,
    columns: dict[str, str] | None = None,
    hint: str = "flight logs store angles in radians",
) -> None:
    """Refuse an angle channel beyond what any flight reaches in radians (almost
    surely degrees) and a speed, mass or inertia that is not positive. `columns`
    names each channel's column in the file, for the message."""
    columns = columns or {}

    def where(col):
        source = columns.get(col, col)
        return f"column {source!r}" + (f" (channel {col!r})" if source != col else "")

    for col, limit in _ANGLE_LIMITS.items():
        if col in channels:
            v = channels[col]
            i = int(np.argmax(np.abs(v)))
            if abs(v[i]) > limit:
                raise LogError(
                    f"{name}: {where(col)}, row {i + 1}: value {v[i]:.6g} is larger "
                    f"than {limit:g} rad; the column looks like degrees ({hint})"
                )
    for col in _POSITIVE:
        if col in channels:
            bad = np.flatnonzero(channels[col] <= 0)
            if bad.size:
                raise LogError(
                    f"{name}: {where(col)}, row {bad[0] + 1}: value "
                    f"{num(channels[col][bad[0]])} must be positive"
                )


def read_log(
    path: str | os.PathLike,
    *,
    required: tuple[str, ...] = REQUIRED_CHANNELS,
    min_samples: int = 2,
    resample: bool = False,
    plausibility: bool = True,
) -> FlightLog:
    """Read and validate a flight log (CSV plus optional JSON sidecar).

    **Arguments:**

    - `path`: the CSV file.
    - `required`: channels that must be present (default: every channel of the
      flight-log format except the `true_*` truth columns).
    - `min_samples`: fewest samples accepted (e.g. one estimation window).
    - `resample`: interpolate a non-uniformly sampled log onto a uniform grid (with a
      warning) instead of rejecting it.
    - `plausibility`: refuse a log whose channels disagree physically (a unit or
      scale mistake; see `diffpegasus._log._checks`). The sidecar's `skip_checks` turns
      single checks off.

    **Returns:** a [`FlightLog`][]. Without a sidecar the Pegasus defaults apply.
    Columns that are not channels of the format are kept when numeric and
    dropped when they hold text.

    **Raises:** [`LogError`][] with one line naming the file, column, row and value.
    """
    path = pathlib.Path(path)
    if not path.exists():
        raise LogError(f"{path}: no such file")
    if path.is_dir():
        raise LogError(f"{path}: is a folder, not a log file")
    _check_size(path)
    header, data = _read_rows(path, _known(required))
    channels = dict(zip(header, np.ascontiguousarray(data.T), strict=True))
    del data
    channels = validate_channels(
        channels,
        str(path),
        required=required,
        min_samples=min_samples,
        resample=resample,
    )
    metadata = _read_sidecar(path)
    rate = 1.0 / np.mean(np.diff(channels["t"]))
    declared = metadata.get("sample_rate_hz")
    if declared is not None and abs(declared - rate) > 1e-3 * rate:
        raise LogError(
            f"{sidecar_path(path)}: sample_rate_hz {num(declared)} disagrees with the "
            f"time column of {path} ({rate:.6g} Hz)"
        )
    metadata["sample_rate_hz"] = float(rate)
    if plausibility:
        try:
            check_physics(channels, metadata, str(path), str(sidecar_path(path)))
        except PlausibilityError as e:
            raise LogError(str(e)) from None
    return FlightLog(channels=channels, metadata=metadata, path=path)
