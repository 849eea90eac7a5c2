"""Flight computers' export layouts the shipped flights do not use, each written
from one simulated flight (RocketPy's, tests/rocket_layouts.py) and read with the
column map a user would write, or none: channels in SI against the simulation
within the layout's own rounding, liftoff and apogee against the simulator's; and
a map that disagrees with its file stops the read with one line naming the file,
the column, the row and the value."""

import json

import numpy as np
import pytest

from diffpegasus import LogError, read_rocket_log

from .rocket_layouts import (
    APOGEE_T,
    excel_semicolon,
    flight,
    LAYOUTS,
    openlog_arduino,
    stratologger_pf2,
)


TRUTH = flight()
APOGEE_M = float(TRUTH["altitude"][-1])  # RocketPy's last row: its apogee


def _read(tmp_path, name, **changes):
    files, cmap, tol, t0 = LAYOUTS[name](tmp_path, TRUTH)
    if changes:
        cmap = {**(cmap or {}), **changes}
    return read_rocket_log(files, column_map=cmap), tol, t0


@pytest.mark.parametrize("name", sorted(LAYOUTS))
def test_layout_read_against_the_simulation(tmp_path, name):
    log, tol, t0 = _read(tmp_path, name)
    datum = tol.pop("_datum", 0.0)  # an altitude above sea level: the pad's
    # the flight's time of liftoff: RocketPy ignites at 0 and the rocket moves when
    # thrust beats weight, a few samples later (0.04-0.08 s measured)
    offset = next(iter(log.time_offsets.values())) - t0
    assert 0.0 <= offset <= 0.1
    assert set(tol) <= set(log.channels)
    for name_, eps in tol.items():
        c = log[name_]
        values = c.values + (
            log.pad.get("altitude_offset", 0.0) * (name_ == "altitude")
        )
        truth = np.interp(c.t + offset, TRUTH["t"], TRUTH[name_])
        truth += datum * (name_ == "altitude")
        # the layout's rounding (integer ft: 0.15 m; 0.01 mbar: 0.5 Pa), and no more
        assert np.max(np.abs(values - truth)) <= eps * (1 + 1e-6) + 1e-9, name_
    apogee = log.events["apogee"]
    # the vertex fit near the top: within 0.02 s of the last row on the 50 Hz
    # layouts, 0.15 s on the 20 Hz integer-ft StratoLogger file (measured)
    assert apogee.t + offset == pytest.approx(APOGEE_T, abs=0.2)
    if "altitude" in log.channels:
        assert apogee.value == pytest.approx(APOGEE_M, abs=1.5)
    else:
        # from pressure alone: the standard atmosphere from the pad's pressure puts
        # 15 degC at the pad, 1 K warmer than at 150 m: 0.36 % high (measured)
        assert apogee.value == pytest.approx(APOGEE_M, rel=0.005)


def test_units_the_header_leaves_out_are_inferred_with_a_message(tmp_path):
    """A StratoLogger file says no unit: the coast says ft, the speed integrated
    over the climb says ft/s, the header's '(F)' says degF."""
    log, _, _ = _read(tmp_path, "stratologger_pf2")
    said = "\n".join(log.messages)
    assert "column 'Altitude'" in said and "no unit given, read as ft" in said
    assert "column 'Velocity'" in said and "3.28 times" in said
    assert "read as ft/s" in said
    assert log["temperature"].source.endswith("(degf)")


def test_a_write_cut_short_is_dropped(tmp_path):
    log, _, _ = _read(tmp_path, "openlog_arduino")
    assert any("dropped the last 1 row(s)" in m for m in log.messages)


def test_utf8_with_bom_reads_as_windows_1252(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a, cmap, _, _ = excel_semicolon(tmp_path / "a", TRUTH)
    b, _, _, _ = excel_semicolon(tmp_path / "b", TRUTH, encoding="utf-8-sig")
    la, lb = read_rocket_log(a, cmap), read_rocket_log(b, cmap)
    for name in la.channels:
        np.testing.assert_array_equal(la[name].values, lb[name].values)


def test_map_and_file_disagree_in_one_line(tmp_path):
    def one_line(match, name, **changes):
        folder = tmp_path / f"case{len(list(tmp_path.iterdir()))}"
        folder.mkdir()
        with pytest.raises(LogError, match=match) as e:
            _read(folder, name, **changes)
        assert "\n" not in str(e.value)
        return str(e.value)

    # a speed in ft/s said to be m/s: the climb it integrates to is 3.28 times
    one_line(
        r"column 'Velocity': integrated .* 3\.28 times .*looks like ft/s",
        "stratologger_pf2",
        time="Time",
        altitude={"column": "Altitude", "unit": "ft"},
        velocity={"column": "Velocity", "unit": "m/s"},
    )
    # mG said to be g: a boost of hundreds of g
    one_line(
        r"column 'accel_z_mg', row \d+: the boost peaks at .*looks like m/s\^2",
        "openlog_arduino",
        accel_axial={"column": "accel_z_mg", "unit": "g", "gravity": "included"},
    )
    # decimal commas said to be points: the first cell named, the mark hinted
    one_line(
        r"flug\.csv: column 'Zeit \[s\]', row 1: '0,00' has a decimal comma; "
        r'give .*"decimal": ","',
        "excel_semicolon",
        decimal=".",
    )
    one_line(r"header_row 14: that line is blank", "stratologger_pf2", header_row=14)
    one_line(r"delimiter must be .* got '\|'", "stratologger_pf2", delimiter="|")
    # a map's column the file lacks, in a file with a preamble: the names listed
    msg = one_line(
        r"no column 'Alt' for channel 'altitude' \(columns: Time, Altitude,",
        "stratologger_pf2",
        time="Time",
        altitude="Alt",
    )
    assert "Voltage" in msg


def test_map_says_where_the_header_is(tmp_path):
    """`header_row` and `delimiter` in the map: the same numbers as found alone."""
    files, _, _, _ = stratologger_pf2(tmp_path, TRUTH)
    found = read_rocket_log(files)
    cmap = {
        "header_row": 15,
        "delimiter": ",",
        "time": "Time",
        "altitude": {"column": "Altitude", "unit": "ft"},
        "velocity": {"column": "Velocity", "unit": "ft/s"},
    }
    told = read_rocket_log(files, json.loads(json.dumps(cmap)))
    for name in ("altitude", "velocity"):
        np.testing.assert_array_equal(found[name].values, told[name].values)
    files, cmap, _, _ = openlog_arduino(tmp_path, TRUTH)
    log = read_rocket_log(files, {**cmap, "header_row": 2, "delimiter": "tab"})
    assert "pressure" in log.channels


def test_a_summary_block_before_the_header(tmp_path):
    """A flight summary of label and value pairs side by side (14 rows as wide as
    the data, numbers among them), a blank row, then the header and the data: the
    structure Altimeter Cloud's Nano altimeter documents for its CSV (the column
    names here are ours). The header is the row of names right above the data."""
    f = TRUTH
    lines = ["Flight,12,Apogee (m),2961,Max accel (g),9.1"] * 7
    lines += ["Date,2025-06-11,Time,12:07,Pad (m),150"] * 7 + [""]
    lines += ["Time (ms),Altitude (m),Pressure (Pa),Temperature (C),Ax (g),Ay (g)"]
    lines += [
        f"{t * 1000:.0f},{h:.2f},{p:.1f},{k - 273.15:.2f},{a / 9.80665:.4f},0.01"
        for t, h, p, k, a in zip(
            f["t"],
            f["altitude"],
            f["pressure"],
            f["temperature"],
            f["accel_axial"],
            strict=True,
        )
    ]
    path = tmp_path / "nano.csv"
    path.write_text("\n".join(lines) + "\n")
    log = read_rocket_log(
        path,
        {
            "time": {"column": "Time (ms)", "unit": "ms"},
            "altitude": "Altitude (m)",
            "accel_axial": {"column": "Ax (g)", "gravity": "included"},
        },
    )
    assert log["altitude"].source == "nano.csv: column 'Altitude (m)' (m)"
    assert log["accel_axial"].source == "nano.csv: column 'Ax (g)' (g)"
    assert log.events["apogee"].value == pytest.approx(APOGEE_M, abs=1.5)


def test_blue_raven_without_a_map(tmp_path):
    """The wall-clock `Time` before `Flight_Time_(s)` is passed over, a
    `Baro_Altitude_*` column is an altitude and `Baro_Press_*` a pressure: the
    numbers the map gives, the altitude above sea level re-zeroed on the pad."""
    files, cmap, _, _ = LAYOUTS["blue_raven_lr"](tmp_path, TRUTH)
    mapped, found = read_rocket_log(files, cmap), read_rocket_log(files)
    assert found["altitude"].source.endswith("'Baro_Altitude_ASL_(feet)' (ft)")
    for name in ("pressure", "temperature", "velocity"):
        np.testing.assert_allclose(found[name].values, mapped[name].values, rtol=1e-12)
    # ASL and AGL columns differ by the pad's height, each rounded to 0.1 ft
    np.testing.assert_allclose(
        found["altitude"].values, mapped["altitude"].values, atol=0.1 * 0.3048
    )


def test_a_speed_no_unit_explains_is_dropped_not_fatal(tmp_path):
    """A flight computer's speed that climbs ten times what the altitude climbs
    (neither m/s nor ft/s): the fit does not use it, so the log is still read,
    without it, and the message says why."""
    f = TRUTH
    rows = ["t,alt_m,vel"] + [
        f"{t:.3f},{h:.3f},{10 * v:.3f}"
        for t, h, v in zip(f["t"], f["altitude"], f["velocity"], strict=True)
    ]
    path = tmp_path / "flight.csv"
    path.write_text("\n".join(rows) + "\n")
    cmap = {
        "t": "t",
        "altitude": {"column": "alt_m", "unit": "m"},
        "velocity": {"column": "vel", "unit": "m/s"},
    }
    log = read_rocket_log(path, cmap)
    assert "velocity" not in log.channels
    assert "altitude" in log.channels
    assert any(
        "no unit explains it, the channel is not used" in m for m in log.messages
    )


def test_decimal_commas_in_a_comma_file_are_refused_not_truncated(tmp_path):
    """Unquoted decimal commas in a comma-separated file split every number in
    two: the rows are wider than the header, and reading the header's columns
    would take the altitude's integer part (0.95 m off at most, silently). One
    line says why instead."""
    rows = ["Time (ms),Altitude (m),Temperature (C)"] + [
        f"{round(t * 1000)},{h:.1f},15".replace(".", ",")
        for t, h in zip(TRUTH["t"], TRUTH["altitude"], strict=True)
    ]
    path = tmp_path / "flight.csv"
    path.write_text("\n".join(rows) + "\n")
    cmap = {"time": {"column": "Time (ms)", "unit": "ms"}, "altitude": "Altitude (m)"}
    with pytest.raises(LogError, match=r"header \(line 1\) has 3 names, the data") as e:
        read_rocket_log(path, cmap)
    assert "\n" not in str(e.value)


def test_decimal_commas_after_rows_of_whole_numbers(tmp_path):
    """A ';' file whose first rows are whole numbers (a zeroed pad; a spreadsheet
    writes 0 for 0,00): the decimal comma of the later rows decides, and every row
    is read (it used to read the two rows and drop the rest as a cut-short write)."""
    rows = ["Zeit [s];Hoehe [m]", "0;0", "0;0"] + [
        f"{t:.2f};{h:.2f}".replace(".", ",")
        for t, h in zip(TRUTH["t"][1:], TRUTH["altitude"][1:], strict=True)
    ]
    path = tmp_path / "flug.csv"
    path.write_text("\n".join(rows) + "\n")
    cmap = {"time": {"column": "Zeit [s]", "unit": "s"}, "altitude": "Hoehe [m]"}
    log = read_rocket_log(path, cmap)
    told = read_rocket_log(path, {**cmap, "decimal": ","})
    np.testing.assert_array_equal(log["altitude"].values, told["altitude"].values)
    # every row but the duplicate time 0 kept
    assert log["altitude"].values.size >= len(rows) - 3


def test_header_row_past_the_sniffed_lines_and_a_clock_past_midnight(tmp_path):
    """A preamble of 450 lines read with `header_row` (the sniffing reads 400),
    and a time-of-day column whose flight passes midnight: one day added after
    it, with a message, the times as from the clock that does not wrap."""
    start = 23 * 3600 + 59 * 60 + 50.0  # 10 s before midnight
    clock = [
        f"{int(s // 3600) % 24:02d}:{int(s % 3600) // 60:02d}:{s % 60:06.3f}"
        for s in start + TRUTH["t"]
    ]
    rows = [f"note {i}: something" for i in range(450)] + ["Time,Alt (m)"]
    rows += [f"{c},{h:.3f}" for c, h in zip(clock, TRUTH["altitude"], strict=True)]
    path = tmp_path / "flight.csv"
    path.write_text("\n".join(rows) + "\n")
    log = read_rocket_log(
        path, {"header_row": 451, "time": "Time", "altitude": "Alt (m)"}
    )
    assert any("passes midnight" in m for m in log.messages)
    t = log["altitude"].t
    assert np.all(np.diff(t) > 0)
    # the span of the flight kept (the clock's 1 ms rounding)
    assert abs((t[-1] - t[0]) - (TRUTH["t"][-1] - TRUTH["t"][0])) < 2e-3


def test_a_spreadsheets_padded_preamble_is_skipped(tmp_path):
    """A spreadsheet pads every row to the data's width: a title `Flight log,,`,
    a blank row `,,` above the header. Neither is taken for the header."""
    rows = ["Flight log,,", "Date,2024-04-20,", ",,", "Time (s),Alt (m),Accel (m/s2)"]
    rows += [
        f"{t:.3f},{h:.3f},{a:.3f}"
        for t, h, a in zip(
            TRUTH["t"], TRUTH["altitude"], TRUTH["accel_axial"], strict=True
        )
    ]
    path = tmp_path / "flight.csv"
    path.write_text("\n".join(rows) + "\n")
    log = read_rocket_log(path)
    assert {"altitude", "accel_axial"} <= set(log.channels)
    assert log["altitude"].values.size >= len(TRUTH["t"]) - 3
