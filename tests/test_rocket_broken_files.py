"""The broken files a user hits on the rocket-log reader's layout features (a units
row; semicolons with decimal commas in Windows-1252; clock times), each written from
the simulated flight of tests/rocket_layouts.py and damaged as a logger, a card or a
spreadsheet damages it: either one error line naming the file and the row (and the
column and cell where there is one), or the channels of the undamaged rows against
the simulation within the layout's rounding, with a message where rows were dropped
or the file read otherwise than it says."""

import re

import numpy as np
import pytest

from diffpegasus import LogError, read_rocket_log

from .rocket_damages import edit, no_altitude, READ, REFUSED, U, X
from .rocket_layouts import flight, LAYOUTS


TRUTH = flight()


@pytest.mark.parametrize(
    "layout, damage, pattern", [c[1:] for c in REFUSED], ids=[c[0] for c in REFUSED]
)
def test_a_broken_file_is_one_error_line(tmp_path, layout, damage, pattern):
    files, cmap, _, _ = LAYOUTS[layout](tmp_path, TRUTH)
    damage(files[0], layout)
    with pytest.raises(LogError) as e:
        read_rocket_log(files, column_map=cmap)
    line = str(e.value)
    assert "\n" not in line
    assert line.startswith(f"{files[0]}: "), line
    assert re.search(pattern, line), line


@pytest.mark.parametrize(
    "layout, damage, message, changes",
    [c[1:] for c in READ],
    ids=[c[0] for c in READ],
)
def test_a_damage_that_spares_the_data_reads_them(
    tmp_path, layout, damage, message, changes
):
    files, cmap, tol, t0 = LAYOUTS[layout](tmp_path, TRUTH)
    rows = len(files[0].read_bytes().splitlines()) - (2 if layout != X else 1)
    damage(files[0], layout)
    log = read_rocket_log(files, column_map={**(cmap or {}), **changes} or None)
    said = "\n".join(log.messages)
    if message is not None:
        assert re.search(message, said), said
    # rows are dropped only where the expected message says so; otherwise all read
    assert ("dropped" in said) == ("dropped" in (message or "")), said
    if "dropped" not in said:
        assert len(log["altitude"].t) == rows
    offset = next(iter(log.time_offsets.values())) - t0
    for name, eps in tol.items():
        if name.startswith("_"):
            continue
        c = log[name]
        truth = np.interp(c.t + offset, TRUTH["t"], TRUTH[name])
        values = c.values
        if name == "altitude":
            truth += tol.get("_datum", 0.0)
            values = values + log.pad.get("altitude_offset", 0.0)
        # the layout's rounding (0.1 ft, 0.01 m, 1 mm; 0.01 mbar; 1 mG) and no more
        assert np.max(np.abs(values - truth)) <= eps * (1 + 1e-6) + 1e-9, name


def test_a_column_all_empty_is_not_used_with_a_message(tmp_path):
    files, _, _, _ = LAYOUTS[U](tmp_path, TRUTH)
    edit(no_altitude)(files[0], U)
    log = read_rocket_log(files)
    assert "altitude" not in log.channels and "pressure" in log.channels
    assert any(
        "column 'altitude': no values, channel 'altitude' not used" in m
        for m in log.messages
    )
