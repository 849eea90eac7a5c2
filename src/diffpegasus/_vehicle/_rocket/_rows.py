"""Numeric tables as teams write them (thrust curves, drag curves, air-brake
schedules and tables): comma- or space-separated rows, header lines allowed before the
numbers, blank and comment lines (`#`, `;`) skipped, columns beyond those read
ignored."""

import pathlib

import numpy as np

from ..._errors import LogError


def read_rows(
    path, columns: tuple[str, ...], what: str, *, header_first: bool = False
) -> tuple[np.ndarray, np.ndarray, list[str] | None]:
    """Read the first `len(columns)` numbers of each row of `path`.

    **Arguments:**

    - `path`: the file.
    - `columns`: the columns' names with units, for messages (`("time s",
      "thrust N")`).
    - `what`: the table, for messages (`"the thrust curve"`).
    - `header_first`: the first row is a header whatever it holds (a RASP `.eng`
      file's motor line).

    **Returns:** `(values (rows, len(columns)), line (rows,), header)`: the numbers,
    each row's line number in the file (1-based, for messages) and the header row's
    fields (`None` without one). A row that is not `len(columns)` finite numbers
    raises a `LogError` naming the file, the line and what it holds.
    """
    path = pathlib.Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig", errors="replace")
    except OSError as e:
        raise LogError(f"{path}: cannot read {what} ({e.strerror})") from None
    expected = " ".join(columns)
    rows, lines, header = [], [], None
    for i, line in enumerate(text.splitlines(), 1):
        # RASP files end a line's numbers with a `; comment` as they may start one
        s = (line.split(";")[0] if header_first else line).strip()
        if not s or s.startswith(";") or s.startswith("#"):
            continue
        parts = s.replace(",", " ").split()
        if (
            header_first
            and header is None
            and not (len(parts) == 2 and all(_number(v) for v in parts))
        ):
            header = parts  # a header line missing, the first row is data
            continue
        try:
            values = [float(v) for v in parts[: len(columns)]]
        except ValueError:
            if not rows:  # header lines before the numbers
                header = parts if header is None else header
                continue
            raise LogError(f"{path}: row {i}: {s!r} is not '{expected}'") from None
        if len(values) < len(columns) or not all(np.isfinite(values)):
            raise LogError(f"{path}: row {i}: {s!r} is not '{expected}'")
        rows.append(values)
        lines.append(i)
    if not rows:
        raise LogError(f"{path}: no ({', '.join(columns)}) rows in {what}")
    return np.asarray(rows, float), np.asarray(lines), header


def _number(text: str) -> bool:
    try:
        return np.isfinite(float(text))
    except ValueError:
        return False
