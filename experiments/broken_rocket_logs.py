"""The broken variants a user hits on the rocket-log reader's layout features
(units row, semicolons with decimal commas and Windows-1252, clock times), each
written from the simulated flight of tests/rocket_layouts.py and damaged as
tests/rocket_damages.py damages it (the same rows as the tests), read with
`read_rocket_log`, and the outcome printed as one line: `error` (the LogError's
line), `read` (rows, the largest altitude error against the simulation, the
reader's messages) or `TRACEBACK` (an exception that is not a LogError).

Run: PYTHONPATH=src python experiments/broken_rocket_logs.py
"""

import pathlib
import sys
import tempfile

import numpy as np


sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from tests.rocket_damages import F, MORE, READ, REFUSED  # noqa: E402
from tests.rocket_layouts import flight, LAYOUTS  # noqa: E402

from diffpegasus import LogError, read_rocket_log  # noqa: E402


TRUTH = flight()
# the damages of tests/test_rocket_broken_files.py (refused, then read), then the
# probe's other layouts for them: (id, layout, damage, column map changes)
CASES = (
    [(c[0], c[1], c[2], {}) for c in REFUSED]
    + [(c[0], c[1], c[2], c[4]) for c in READ]
    + list(MORE)
)


def run(label, layout, damage, changes):
    with tempfile.TemporaryDirectory() as tmp:
        files, cmap, _, t0 = LAYOUTS[layout](pathlib.Path(tmp), TRUTH)
        path = files[0]
        damage(path, layout)
        if changes:
            cmap = {**(cmap or {}), **changes}
        try:
            log = read_rocket_log([path], column_map=cmap)
        except LogError as e:
            text = str(e).replace(str(path), path.name)
            return f"error: {text[:230]}"
        except Exception as e:  # noqa: BLE001 (what the probe is for)
            return f"TRACEBACK {type(e).__name__}: {str(e)[:150]}"
        said = " | ".join(m for m in log.messages if "unit" not in m)
        said = said.replace(str(path.parent) + "/", "")[:200]
        if "altitude" not in log.channels:
            return f"read without altitude: {sorted(log.channels)}; {said}"
        c = log["altitude"]
        offset = next(iter(log.time_offsets.values())) - t0
        truth = np.interp(c.t + offset, TRUTH["t"], TRUTH["altitude"])
        datum = 150.0 if layout == F else 0.0
        err = np.max(
            np.abs(c.values + log.pad.get("altitude_offset", 0) - truth - datum)
        )
        return f"read {len(c.t)} rows, altitude off {err:.3g} m; {said}"


if __name__ == "__main__":
    for case in CASES:
        print(f"{case[0]}: {run(*case)}", flush=True)
