"""Where the validation data of `shared/data/` lives.

The repository is checked out beside a `shared/` folder; `DIFFPEGASUS_SHARED` (the
path of that folder) overrides the search.
"""

import os
import pathlib


def shared_data(relative: str) -> pathlib.Path:
    """Path of `shared/data/<relative>`; the first candidate that exists, else the
    conventional location (so the error message names it)."""
    here = pathlib.Path(__file__).resolve()
    candidates = []
    if os.environ.get("DIFFPEGASUS_SHARED"):
        candidates.append(
            pathlib.Path(os.environ["DIFFPEGASUS_SHARED"]) / "data" / relative
        )
    candidates += [p / "shared" / "data" / relative for p in here.parents]
    for c in candidates:
        if c.exists():
            return c
    return here.parents[2] / "shared" / "data" / relative
