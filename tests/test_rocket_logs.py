"""Rocket logs as flight computers write them: each reader on a synthetic flight of
closed form (tests/data/rocket_logs, written by make_fixtures.py) and on the six
real flights of the shared data set, whose rocket.toml records what its curator
measured in each log by hand (the independent reference for the events)."""

import importlib.util
import pathlib
import re
import shutil
import tomllib

import numpy as np
import pytest

from diffpegasus._errors import LogError
from diffpegasus._log._rocketlogs import read_rocket_log


HERE = pathlib.Path(__file__).resolve().parent
FIXTURES = HERE / "data" / "rocket_logs"
_spec = importlib.util.spec_from_file_location(
    "make_fixtures", FIXTURES / "make_fixtures.py"
)
truth = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(truth)
G0 = 9.80665


def _rockets() -> pathlib.Path | None:
    """The real flights: ../shared/data/rockets beside the repository (CI), or two
    levels up (a worktree)."""
    root = HERE.parent
    for base in (root.parent, root.parent.parent):
        path = base / "shared" / "data" / "rockets"
        if path.is_dir():
            return path
    return None


ROCKETS = _rockets()
needs_rockets = pytest.mark.skipif(ROCKETS is None, reason="shared rocket data absent")
FLIGHTS = ("prometheus_2022", "hedy", "camoes", "ndrt_2020", "andromeda", "cavour")
CATS = [
    FIXTURES / "cats" / n
    for n in ("imu.csv", "baro.csv", "filteredDataInfo.csv", "gnssInfo.csv")
]
SOURCES = {
    "altos": FIXTURES / "altos.csv",
    "altimeter": FIXTURES / "altimeter.csv",
    "cats": CATS,
}


def _copy(tmp_path, name="altimeter.csv") -> pathlib.Path:
    dst = tmp_path / name
    shutil.copy(FIXTURES / name, dst)
    return dst


def _lines(path) -> list[str]:
    return path.read_text().splitlines()


def _file_time(log, event: str) -> float:
    offset = next(iter(log.time_offsets.values()))
    return log.events[event].t + offset


# --- the synthetic flight, one per format ----------------------------------------


@pytest.mark.parametrize("fmt", sorted(SOURCES))
def test_events_of_the_closed_form_flight(fmt):
    log = read_rocket_log(SOURCES[fmt])
    step = 0.05  # every fixture is written at 20 Hz over the ascent
    # liftoff: the first sample of the boost; the true instant lies one step before
    offset = next(iter(log.time_offsets.values()))
    assert -step <= offset <= step + 0.006  # CATS files are 5 ms apart
    assert _file_time(log, "burnout") == pytest.approx(truth.BURN, abs=step)
    # apogee: the vertex fit sits within a sample of the closed form's; its height
    # within the altitude noise (0.3-0.5 m)
    assert _file_time(log, "apogee") == pytest.approx(truth.T_APOGEE, abs=step)
    assert log.events["apogee"].value == pytest.approx(truth.H_APOGEE, abs=1.0)
    # the main's break (2 Hz in the AltOS descent) and the landing
    descent_step = 0.5 if fmt == "altos" else step
    assert _file_time(log, "main") == pytest.approx(
        truth.T_MAIN, abs=descent_step + step
    )
    assert log.events["main"].value == pytest.approx(truth.H_MAIN, abs=2.0)
    assert _file_time(log, "landing") == pytest.approx(
        truth.T_LANDING, abs=descent_step + step
    )
    assert log.events["liftoff"].t == 0.0


@pytest.mark.parametrize("fmt", sorted(SOURCES))
def test_channels_in_si_on_one_clock(fmt):
    """ft, g, Pa, 1 g removed, the axis along -Y: every conversion lands on the
    closed-form altitude and specific force."""
    log = read_rocket_log(SOURCES[fmt])
    offset = next(iter(log.time_offsets.values()))
    alt = log["altitude"]
    h, _ = truth.flight(alt.t + offset)
    # the fixtures' altitude noise is 0.3-0.5 m; pad re-zeroing moves it by < 0.2 m
    assert np.sqrt(np.mean((alt.values - h) ** 2)) < 0.8
    acc = log["accel_axial"]
    _, sf = truth.flight(acc.t + offset)
    # away from the steps of the closed form (a sample straddles each)
    tf = acc.t + offset
    steady = (
        np.abs(
            tf[:, None] - np.array([0.0, truth.BURN, truth.T_APOGEE, truth.T_DROGUE])
        ).min(1)
        > 0.1
    )
    assert np.median(np.abs(acc.values - sf)[steady]) < 0.4
    assert np.median(acc.values[acc.t < 0]) == pytest.approx(G0, abs=0.3)
    for c in log.channels.values():
        assert np.all(np.diff(c.t) > 0) and np.all(np.isfinite(c.values))


def test_altos_duplicates_and_rate_change_reported():
    log = read_rocket_log(SOURCES["altos"])
    lines = _lines(SOURCES["altos"])
    doubled = sum(a == b for a, b in zip(lines[1:], lines[2:], strict=False))
    assert any(f"dropped {doubled} duplicate rows" in m for m in log.messages)
    assert any("20 Hz from -0.50 s, then 2 Hz from 15.00 s" in m for m in log.messages)
    # the GNSS position held between 1 Hz fixes: one sample per fix
    assert log["gnss_lat"].rate == pytest.approx(1.0, rel=0.05)


def test_cats_axis_and_raw_accelerometer_preferred():
    log = read_rocket_log(CATS)
    assert any("accel_axial is -accel_y" in m for m in log.messages)
    assert not log["accel_axial"].filtered
    assert log["altitude"].filtered  # filteredAltitudeAGL
    # pressure in Pa on the pad of the closed form (sea level)
    assert log.pad["pressure"] == pytest.approx(101325.0, abs=100)


@pytest.mark.parametrize("rate", [10.0, 100.0, 1000.0])
@pytest.mark.parametrize("noise", [0.1, 3.0])
def test_events_at_other_rates_and_noise(tmp_path, rate, noise):
    """The closed-form flight at 10 Hz to 1 kHz, altitude noise 0.1 or 3 m (and
    accelerometer noise half that in m/s^2): every rule holds, within what the
    sampling and the noise allow."""
    rng = np.random.default_rng(int(rate) + int(10 * noise))
    dt = 1.0 / rate
    t = np.arange(-0.5, 70.0, dt) + dt * rng.uniform()  # no sample on the instant
    h, sf = truth.flight(t)
    h = h + rng.normal(0, noise, t.size)
    sf = sf + rng.normal(0, noise / 2, t.size)
    path = tmp_path / "log.csv"
    np.savetxt(
        path,
        np.column_stack([t, h, sf]),
        delimiter=",",
        fmt="%.6f",
        header="time (s),altitude (m),acceleration (m/s^2)",
        comments="",
    )
    log = read_rocket_log(
        path,
        {
            "time": "time (s)",
            "altitude": {"column": "altitude (m)", "unit": "m"},
            "accel_axial": {"column": "acceleration (m/s^2)", "gravity": "included"},
        },
    )
    assert next(iter(log.time_offsets.values())) == pytest.approx(0.0, abs=dt + 1e-9)
    # the coast reads only -1.4 m/s^2 at burnout: with accelerometer noise as large
    # (1.5 m/s^2) the zero crossing comes up to a few samples late
    assert _file_time(log, "burnout") == pytest.approx(
        truth.BURN, abs=(3 + 2 * noise) * dt + 1e-9
    )
    # the vertex: 2-3 standard errors of a fit of a few (10 Hz) to hundreds of samples
    assert _file_time(log, "apogee") == pytest.approx(
        truth.T_APOGEE, abs=0.05 + 0.1 * noise
    )
    assert log.events["apogee"].value == pytest.approx(truth.H_APOGEE, abs=0.5 + noise)
    assert _file_time(log, "main") == pytest.approx(truth.T_MAIN, abs=0.3 + 0.1 * noise)
    assert _file_time(log, "landing") == pytest.approx(
        truth.T_LANDING, abs=0.3 + 0.2 * noise
    )


# --- what flight computers leave behind -----------------------------------------


def test_dropouts_counted_on_the_logs_own_grid(tmp_path):
    path = _copy(tmp_path)
    lines = _lines(path)
    rng = np.random.default_rng(3)
    drop = set(
        rng.choice(np.arange(100, len(lines) - 100), 300, replace=False).tolist()
    )
    path.write_text("\n".join(x for k, x in enumerate(lines) if k not in drop) + "\n")
    log = read_rocket_log(path)
    assert any("dropouts: 300 samples missing" in m for m in log.messages)
    assert _file_time(log, "apogee") == pytest.approx(truth.T_APOGEE, abs=0.1)


def test_late_start_extrapolated(tmp_path):
    """A log that begins 0.5 s into the boost: liftoff from the altitude arc alone;
    the accelerometer's gravity convention from the end of the climb (drag gone:
    ~0 with gravity included), or from the column map."""
    path = _copy(tmp_path)
    lines = _lines(path)
    path.write_text(
        "\n".join([lines[0], *[x for x in lines[1:] if float(x.split(",")[0]) >= 0.5]])
        + "\n"
    )
    log = read_rocket_log(path)
    assert any(
        "no samples on the pad" in m and "gravity included" in m for m in log.messages
    )
    columns = {
        "time": "t(s)",
        "altitude": {"column": "alt(ft)", "unit": "ft"},
        "accel_axial": {"column": "accel(g)", "unit": "g", "gravity": "included"},
    }
    log = read_rocket_log(path, columns)
    assert any(
        "the log starts 0.5" in m and "liftoff extrapolated" in m for m in log.messages
    )
    # constant acceleration from rest: the extrapolated arc meets the pad at 0
    assert next(iter(log.time_offsets.values())) == pytest.approx(0.0, abs=0.03)
    assert "starts airborne" in log.events["liftoff"].how
    # an accelerometer alone that never saw the pad: no liftoff to put the clock on
    cut = tmp_path / "boost.csv"
    cut.write_text(
        "\n".join(
            [
                "t(s),accel(g)",
                *[
                    ",".join(x.split(",")[::2])
                    for x in lines[1:]
                    if 0.5 <= float(x.split(",")[0]) < 5
                ],
            ]
        )
        + "\n"
    )
    with pytest.raises(LogError, match=r"'accel\(g\)': no liftoff: no altitude"):
        read_rocket_log(cut)


def test_corrupt_trailing_rows_dropped(tmp_path):
    path = _copy(tmp_path)
    lines = _lines(path)
    keep = [x for x in lines if not x[0].isdigit() or float(x.split(",")[0]) < 45.0]
    # Andromeda's end: two rows falling at 430 m/s, then a row cut off mid-write
    last = keep[-1].split(",")
    t_last, h_last = float(last[0]), float(last[1])
    bad = [
        f"{t_last + 0.5:.2f},{h_last - 700:.2f},0.5",
        f"{t_last + 1:.2f},{h_last - 1300:.2f},0.4",
    ]
    path.write_text("\n".join([*keep, *bad, "46.1,12"]) + "\n")
    log = read_rocket_log(path)
    n = len(keep)  # data rows are numbered from 1 after the header
    assert any(f"dropped the last 1 row(s) from row {n + 2}" in m for m in log.messages)
    assert any(f"dropped the last 2 samples from row {n}" in m for m in log.messages)
    assert log["altitude"].t[-1] + next(
        iter(log.time_offsets.values())
    ) == pytest.approx(t_last)


def test_corrupt_trailing_rows_far_above_apogee_dropped(tmp_path):
    """An altimeter's last two rows written wrong at its drogue event (Juno III's
    RRC3 log: 10.7 km, then -2.5 km, after a 3.2 km apogee): a rocket past apogee
    cannot read far above it, nor fall that fast; both rows go, the flight stays."""
    path = _copy(tmp_path)
    lines = _lines(path)
    keep = [x for x in lines if not x[0].isdigit() or float(x.split(",")[0]) < 45.0]
    last = keep[-1].split(",")
    t_last = float(last[0])
    bad = [
        f"{t_last + 0.05:.2f},{3.4 * truth.H_APOGEE:.2f},0.5",
        f"{t_last + 0.1:.2f},{-0.8 * truth.H_APOGEE:.2f},0.4",
    ]
    path.write_text("\n".join([*keep, *bad]) + "\n")
    log = read_rocket_log(path)
    n = len(keep)  # the first bad row's number: data rows count from 1
    assert any(
        f"dropped the last 2 samples from row {n}" in m and "far above" in m
        for m in log.messages
    )
    assert log["altitude"].values.max() < truth.H_APOGEE + 5
    assert _file_time(log, "apogee") == pytest.approx(truth.T_APOGEE, abs=0.1)


def test_unreadable_row_mid_file_is_one_error_line(tmp_path):
    path = _copy(tmp_path)
    lines = _lines(path)
    lines[400] = lines[400].replace(lines[400].split(",")[1], "12O.5")
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(LogError) as e:
        read_rocket_log(path)
    message = str(e.value)
    assert "\n" not in message
    assert (
        str(path) in message
        and "'alt(ft)'" in message
        and "row 400" in message
        and "'12O.5'" in message
    )


def test_time_running_backwards(tmp_path):
    path = _copy(tmp_path)
    lines = _lines(path)
    lines[300], lines[301] = lines[301], lines[300]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(
        LogError,
        match=r"column 't\(s\)', row 301: time 14.65 s is before the previous row's 14.7 s",
    ):
        read_rocket_log(path)


# --- units: from the map or the header, checked against the flight ---------------


def test_altitude_in_feet_said_to_be_metres(tmp_path):
    path = _copy(tmp_path)
    columns = {"time": "t(s)", "altitude": {"column": "alt(ft)", "unit": "m"}}
    with pytest.raises(LogError, match=r"coast .* looks like ft"):
        read_rocket_log(path, columns)


def test_altitude_unit_inferred_when_nothing_says(tmp_path):
    path = tmp_path / "alt.csv"
    lines = _lines(FIXTURES / "altimeter.csv")
    path.write_text(
        "\n".join(["time,altitude", *[",".join(x.split(",")[:2]) for x in lines[1:]]])
        + "\n"
    )
    log = read_rocket_log(path)
    assert any("no unit given, read as ft" in m for m in log.messages)
    assert log.events["apogee"].value == pytest.approx(truth.H_APOGEE, abs=1.0)


def test_accelerometer_in_g_said_to_be_si(tmp_path):
    path = _copy(tmp_path)
    columns = {
        "time": "t(s)",
        "altitude": {"column": "alt(ft)", "unit": "ft"},
        "accel_axial": {"column": "accel(g)", "unit": "m/s^2", "gravity": "included"},
    }
    with pytest.raises(
        LogError,
        match=r"row \d+: reads 1.0\d* on the pad, 1 g in g, not in m/s\^2: the column looks like g",
    ):
        read_rocket_log(path, columns)


def test_gravity_said_removed_on_an_accelerometer_that_reads_1g(tmp_path):
    path = _copy(tmp_path)
    columns = {
        "time": "t(s)",
        "altitude": {"column": "alt(ft)", "unit": "ft"},
        "accel_axial": {"column": "accel(g)", "unit": "g", "gravity": "removed"},
    }
    with pytest.raises(LogError, match="gravity is included"):
        read_rocket_log(path, columns)


def _si_columns(
    tmp_path, time_scale=1.0, time_name="time", accel_sign=1.0, until=np.inf
):
    """The synthetic altimeter file rewritten as a user's script writes it: no
    units in the header, metres and m/s^2, the time `time_scale` times seconds
    (with a clock's offset where it is not 1), its rows to `until` s."""
    rows = np.loadtxt(FIXTURES / "altimeter.csv", delimiter=",", skiprows=1)
    rows = rows[rows[:, 0] <= until]
    t = rows[:, 0] * time_scale + (0.0 if time_scale == 1.0 else 123456789.0)
    path = tmp_path / "log.csv"
    np.savetxt(
        path,
        np.column_stack([t, rows[:, 1] * 0.3048, accel_sign * rows[:, 2] * G0]),
        delimiter=",",
        fmt=["%.2f" if time_scale == 1.0 else "%d", "%.4f", "%.4f"],
        header=f"{time_name},altitude,acceleration",
        comments="",
    )
    return path


@pytest.mark.parametrize(
    "name, scale", [("micros", 1e6), ("timestamp_us", 1e6), ("time", 1e6)]
)
def test_time_in_microseconds(tmp_path, name, scale):
    """A logger's micros() clock, named so or not at all: before, its unit was
    dropped from the name (only s and ms were kept), the time read as ms (7.4 h of
    it) and the altitude's unit blamed ('climbs 2336344 m in the 20421.3 s coast');
    `micros` was no time column at all."""
    ref = read_rocket_log(_si_columns(tmp_path))
    log = read_rocket_log(_si_columns(tmp_path, scale, name))
    for event in ("liftoff", "burnout", "apogee"):
        # the times are written to the microsecond: the same events to 1e-6 s
        assert log.events[event].t == pytest.approx(ref.events[event].t, abs=2e-6)
    np.testing.assert_allclose(log["altitude"].t, ref["altitude"].t, atol=2e-6)
    said = [m for m in log.messages if "read as us" in m]
    assert len(said) == (name == "time")  # a unit from the name says nothing


def test_short_log_in_microseconds(tmp_path):
    """A microsecond clock without a unit over a log of 16 s (to 2.5 s past
    apogee): its span, 1.6e7, is a flight's 4.5 h in ms too, but its samples
    would be 50 s apart in ms and are 0.05 s apart in microseconds: read as
    microseconds (it was read as ms and the altitude's unit blamed)."""
    ref = read_rocket_log(_si_columns(tmp_path, until=16.0))
    log = read_rocket_log(_si_columns(tmp_path, 1e6, "time", until=16.0))
    assert log.events["apogee"].t == pytest.approx(ref.events["apogee"].t, abs=2e-6)
    assert any("read as us" in m for m in log.messages)


def test_accelerometer_mounted_tail_first(tmp_path):
    """An accelerometer whose axis points tail-first reads -1 g on the pad: the
    error says which map entry reads it, and with that entry (no unit: the unit
    is inferred, the map's sign kept) it reads as the same file the right way up.
    Before, the inferred unit dropped the map's `scale` and the error stayed."""
    ref = read_rocket_log(_si_columns(tmp_path))["accel_axial"].values
    path = _si_columns(tmp_path, accel_sign=-1.0)
    with pytest.raises(
        LogError, match=r'about -1 g: its axis points tail-first .*"scale": -1'
    ):
        read_rocket_log(path)
    columns = {
        "time": "time",
        "altitude": "altitude",
        "accel_axial": {"column": "acceleration", "scale": -1},
    }
    log = read_rocket_log(path, columns)
    np.testing.assert_allclose(log["accel_axial"].values, ref, rtol=0, atol=1e-12)


def _cats_baro_in(tmp_path, pascals, fmt):
    """The CATS barometer file with its pressure in a unit of `pascals` Pa, written
    with `fmt`."""
    src = (FIXTURES / "cats" / "baro.csv").read_text().splitlines()
    path = tmp_path / "baro.csv"
    rows = [src[0]] + [
        ",".join([*x.split(",")[:3], format(float(x.split(",")[3]) / pascals, fmt)])
        for x in src[1:]
    ]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_pressure_in_hpa(tmp_path):
    path = _cats_baro_in(tmp_path, 100.0, ".2f")
    with pytest.raises(LogError, match=r"pad pressure 1013.* looks like hPa"):
        read_rocket_log(path)
    log = read_rocket_log(
        path, {"time": "ts", "pressure": {"column": "P", "unit": "hPa"}}
    )
    assert log.pad["pressure"] == pytest.approx(101325.0, abs=100)
    assert _file_time(log, "apogee") == pytest.approx(truth.T_APOGEE, abs=0.15)


def test_pressure_in_psi(tmp_path):
    """14.7 psi on the pad: the hint names psi (6894.76 Pa each), and the map's
    "psi" reads the pad as the same file in Pa does."""
    path = _cats_baro_in(tmp_path, 6894.757, ".4f")
    with pytest.raises(LogError, match=r"pad pressure 14\.69.* looks like psi"):
        read_rocket_log(path)
    log = read_rocket_log(
        path, {"time": "ts", "pressure": {"column": "P", "unit": "psi"}}
    )
    # against the same file in Pa (its pad 101326.0): 4 decimals of psi are 0.35 Pa
    # of rounding, measured 0.04 Pa off
    pa = read_rocket_log(FIXTURES / "cats" / "baro.csv").pad["pressure"]
    assert log.pad["pressure"] == pytest.approx(pa, abs=1.0)
    assert _file_time(log, "apogee") == pytest.approx(truth.T_APOGEE, abs=0.15)


def test_column_map_mistakes_name_the_column(tmp_path):
    path = _copy(tmp_path)
    with pytest.raises(
        LogError,
        match=r"no column 'alt\(km\)' for channel 'altitude' \(columns: t\(s\), alt\(ft\), accel\(g\)\)",
    ):
        read_rocket_log(path, {"time": "t(s)", "altitude": "alt(km)"})
    with pytest.raises(LogError, match="column map: give a table of channels"):
        read_rocket_log(path, ["alt(ft)"])
    # a one-file map without "time" takes the header's one time column
    log = read_rocket_log(path, {"altitude": "alt(ft)"})
    assert list(log.channels) == ["altitude"]
    assert log["altitude"].source.endswith("(ft)")  # the unit from the header
    empty = tmp_path / "empty.csv"
    empty.write_text("t(s),alt(ft)\n" + "".join(f"{k / 10},\n" for k in range(50)))
    with pytest.raises(
        LogError, match=r"no channel could be read \(.*'alt\(ft\)': no values"
    ):
        read_rocket_log(empty)
    with pytest.raises(LogError, match="gravity must be"):
        read_rocket_log(
            path,
            {"time": "t(s)", "accel_axial": {"column": "accel(g)", "gravity": "down"}},
        )


# --- the six real flights ------------------------------------------------------


def _facts(flight):
    return tomllib.loads((ROCKETS / flight / "rocket.toml").read_text())


@needs_rockets
@pytest.mark.parametrize("flight", FLIGHTS)
def test_real_flight_events_against_the_curators_measurements(flight):
    log = read_rocket_log(ROCKETS / flight / "rocket.toml")
    facts = _facts(flight)
    if "telemetrum" in facts["log"]:  # Prometheus: the first computer's own events
        events = facts["log"]["telemetrum"]["events"]
    else:
        events = facts["log"]["events"]
    apogee_file = _file_time(log, "apogee")
    # the curator's apogee is the highest sample; the top is flat to within the baro
    # noise for 1-2 s (Prometheus: 3889-3895 m from 28.6 to 29.6 s, and its highest
    # sample, 3903.8 m at 29.61 s, belongs to the ejection pulse 29.59-29.61 s)
    assert apogee_file == pytest.approx(events["apogee_s"], abs=1.0)
    recorded = facts["results"].get(
        "log_apogee_agl_m", facts["results"]["recorded_apogee_agl_m"]
    )
    # the vertex against the highest sample: baro noise near apogee is 1-15 m
    assert log.events["apogee"].value == pytest.approx(recorded, rel=0.005)
    if "burnout_s" in events:
        # the curator took the zero of the log's acceleration (1 g removed: thrust
        # = drag + weight), ours the zero of the specific force (thrust = drag),
        # which comes later by the tail-off: up to 0.2 s
        assert _file_time(log, "burnout") - events["burnout_s"] == pytest.approx(
            0.05, abs=0.2
        )
    for c in log.channels.values():
        assert np.all(np.diff(c.t) > 0) and np.all(np.isfinite(c.values))


@needs_rockets
def test_real_flight_artefacts_reported():
    log = read_rocket_log(ROCKETS / "prometheus_2022" / "rocket.toml")
    assert any("dropped 1369 duplicate rows" in m for m in log.messages)
    assert any("dropped 511 duplicate rows" in m for m in log.messages)
    # two flight computers, each on its own clock, aligned at their own liftoffs:
    # their barometers pass 500-3000 m together (the boards differ by a few metres,
    # a few hundredths of a second at 150-300 m/s)
    for level in (500.0, 1000.0, 2000.0, 3000.0):
        crossing = []
        for name in ("altitude", "altitude.telemega"):
            c = log[name]
            up = c.t < 20
            crossing.append(c.t[up][np.argmax(c.values[up] > level)])
        assert crossing[0] == pytest.approx(crossing[1], abs=0.06)
    log = read_rocket_log(ROCKETS / "andromeda" / "rocket.toml")
    assert any("20 Hz from 0.00 s, then 2 Hz from 27.3" in m for m in log.messages)
    assert any(
        re.search(r"dropped the last 2 samples from row 1138", m) for m in log.messages
    )
    assert any("liftoff extrapolated" in m for m in log.messages)
    log = read_rocket_log(ROCKETS / "cavour" / "rocket.toml")
    assert any("250 samples missing" in m and "404 of 654" in m for m in log.messages)
    log = read_rocket_log(ROCKETS / "ndrt_2020" / "rocket.toml")
    # 400 Hz accelerometer in g with gravity beside 20 Hz altitude in ft
    assert log["accel_axial"].rate == pytest.approx(400, rel=0.01)
    assert log["altitude"].rate == pytest.approx(20, rel=0.01)
    pad = log["accel_axial"].values[log["accel_axial"].t < 0]
    assert np.median(pad) == pytest.approx(0.87 * G0, rel=0.06)
    assert log.events["main"].t + log.time_offsets[
        str(ROCKETS / "ndrt_2020" / "logs" / "ndrt_2020_flight_data.csv")
    ] == pytest.approx(65.4, abs=0.5)
    log = read_rocket_log(ROCKETS / "camoes" / "rocket.toml")
    offset = next(iter(log.time_offsets.values()))
    # filtered_acceleration is forced to 0 from 24.38 s on: those samples are dropped
    assert log["accel_axial"].t[-1] + offset == pytest.approx(24.37, abs=0.02)


@needs_rockets
@pytest.mark.parametrize("flight", ["prometheus_2022", "hedy", "ndrt_2020"])
def test_real_flight_layout_from_the_header(flight):
    """Without the shipped map, the headers alone give the same flight."""
    facts = _facts(flight)
    files = [
        ROCKETS / flight / v["file"]
        for v in facts["log"].values()
        if isinstance(v, dict) and "file" in v
    ]
    mapped = read_rocket_log(ROCKETS / flight / "rocket.toml")
    found = read_rocket_log(files)
    assert found.events["apogee"].t == pytest.approx(
        mapped.events["apogee"].t, abs=0.05
    )
    assert found.events["apogee"].value == pytest.approx(
        mapped.events["apogee"].value, abs=0.5
    )
    if flight == "prometheus_2022":
        # the TeleMega's IMU columns are logged but empty
        assert any("accel_x/y/z not used" in m for m in found.messages)
    if flight == "hedy":
        assert any("accel_axial is -accel_y" in m for m in found.messages)


# --- an independent simulator's flights (RocketPy, written by the rocket tests) ----

SIM = HERE / "data" / "rocket_sim"


@pytest.mark.skipif(not SIM.is_dir(), reason="RocketPy flight fixtures absent")
@pytest.mark.parametrize("case", ["clean", "planted"])
def test_rocketpy_flights(case):
    """Logs written by RocketPy (50 Hz from ignition to apogee; no pad samples, no
    unit in the map: the header's suffixes and the end of the climb decide)."""
    folder = SIM / case
    facts = tomllib.loads((folder / "rocket.toml").read_text())
    log = read_rocket_log(folder / "log.csv")
    assert any("gravity included" in m for m in log.messages)
    offset = next(iter(log.time_offsets.values()))
    # RocketPy ignites at 0; the rocket moves once thrust beats weight, a sample or
    # three later at 50 Hz
    assert 0.0 <= offset <= 0.1
    # apogee against the simulator's geometric apogee: the barometer's noise (0.5 or
    # 1 m), lag and static-pressure error (planted) move the vertex by a few metres
    truth_apogee = facts["truth"]["apogee_geometric_agl_m"]
    assert log.events["apogee"].value == pytest.approx(truth_apogee, abs=3.0)
    # burnout inside the motor's tail-off: after thrust falls below half its peak,
    # before it ends
    thrust = np.loadtxt(folder / "motor.csv", delimiter=",")
    half = thrust[np.flatnonzero(thrust[:, 1] >= 0.5 * thrust[:, 1].max())[-1], 0]
    burnout = _file_time(log, "burnout")
    assert half <= burnout <= thrust[-1, 0]


@pytest.mark.skipif(not SIM.is_dir(), reason="RocketPy flight fixtures absent")
def test_simulated_flight_read_through_its_rocket_toml(tmp_path):
    """A simulator's export read through its rocket.toml: `[log.column_map]` as a
    table and `[log.stated_events]` (time zero and apogee as the writer knows them)
    give the file's columns unchanged, against numpy's own read of the CSV; the
    events found from the data are reported beside the stated ones. A stated
    event that is not one, or not a number, is one line naming the key."""
    folder = SIM / "clean"
    raw = np.loadtxt(folder / "log.csv", delimiter=",", skiprows=1)
    log = read_rocket_log(folder / "rocket.toml")
    assert list(log.channels) == ["altitude", "accel_axial"]
    for j, name in enumerate(log.channels, start=1):
        np.testing.assert_array_equal(log[name].t, raw[:, 0])
        np.testing.assert_array_equal(log[name].values, raw[:, j])
    assert log.time_offsets == {str(folder / "log.csv"): 0.0}
    assert log.pad == {}  # no samples before the stated liftoff
    assert log.events["liftoff"].t == 0.0
    assert log.events["apogee"].t == raw[-1, 0]
    assert log.events["apogee"].value == raw[-1, 1]
    # found from the data: the vertex 0.016 s before the last row (measured)
    found = [m for m in log.messages if m.startswith("apogee:")]
    assert found == [
        "apogee: 24.000 s after liftoff as the rocket.toml states (found from the "
        "data: 23.984 s)"
    ]
    # the found burnout is kept: inside the motor's tail-off, as on the file alone
    thrust = np.loadtxt(folder / "motor.csv", delimiter=",")
    assert 0.5 * thrust[-1, 0] < log.events["burnout"].t <= thrust[-1, 0]
    text = (folder / "rocket.toml").read_text()
    for line, key in (
        ("apogee_s = 24.000", "burnup_s"),
        ("apogee_s = 24.000", "apogee"),
    ):
        shutil.copytree(folder, tmp_path / key)
        bad = text.replace(line, f"{key} = 24.000")
        (tmp_path / key / "rocket.toml").write_text(bad)
        with pytest.raises(LogError, match=rf"\[log.stated_events\] {key}: not an"):
            read_rocket_log(tmp_path / key / "rocket.toml")
    shutil.copytree(folder, tmp_path / "text")
    (tmp_path / "text" / "rocket.toml").write_text(
        text.replace("apogee_s = 24.000", 'apogee_s = "24"')
    )
    with pytest.raises(LogError, match="apogee_s = '24': not a time in s"):
        read_rocket_log(tmp_path / "text" / "rocket.toml")


def test_rocket_toml_names_its_logs_and_maps(tmp_path):
    """A user's rocket.toml: `[log] file` with a `column_map` inline (in the syntax of
    every column map: `t` for time, or `{"step": s}` for a file without one), or
    `[log] column_map` naming a map file."""
    shutil.copy(FIXTURES / "altimeter.csv", tmp_path / "flight.csv")
    lines = _lines(FIXTURES / "altimeter.csv")
    (tmp_path / "alt.csv").write_text(
        "\n".join(["altitude"] + [x.split(",")[1] for x in lines[1:]]) + "\n"
    )
    (tmp_path / "rocket.toml").write_text(
        'name = "test"\n[log.alt]\nfile = "alt.csv"\n'
        'column_map = { t = { step = 0.05 }, altitude = { column = "altitude", '
        'unit = "ft" } }\n'
    )
    log = read_rocket_log(tmp_path / "rocket.toml")
    # the file's first sample is at -0.3 s; with the step the clock starts at 0
    assert _file_time(log, "apogee") - 0.3 == pytest.approx(truth.T_APOGEE, abs=0.06)
    (tmp_path / "map.json").write_text(
        '{"t": "t(s)", "altitude": {"column": "alt(ft)", "unit": "ft"}}'
    )
    (tmp_path / "rocket.toml").write_text(
        '[log]\nfile = "flight.csv"\ncolumn_map = "map.json"\n'
    )
    log = read_rocket_log(tmp_path / "rocket.toml")
    assert list(log.channels) == ["altitude"]
    assert _file_time(log, "apogee") == pytest.approx(truth.T_APOGEE, abs=0.06)


def test_temperature_unit(tmp_path):
    """A board's temperature with no unit: degC where K would be implausible; a
    unit the map gives that the reading contradicts is refused."""
    lines = _lines(FIXTURES / "altimeter.csv")
    path = tmp_path / "rrc.csv"
    path.write_text(
        "\n".join(
            ["Time (s),Altitude (ft),Temperature"]
            + [
                f"{x.split(',')[0]},{x.split(',')[1]},{20 + k % 3}"
                for k, x in enumerate(lines[1:])
            ]
        )
        + "\n"
    )
    log = read_rocket_log(path)
    assert any("no unit given, read as degC" in m for m in log.messages)
    assert np.median(log["temperature"].values) == pytest.approx(294.15)
    with pytest.raises(
        LogError, match=r"'Temperature', row \d+: temperature 21 K is not 200-350 K"
    ):
        read_rocket_log(
            path,
            {
                "time": "Time (s)",
                "altitude": "Altitude (ft)",
                "temperature": {"column": "Temperature", "unit": "K"},
            },
        )


def _altitude_log(tmp_path, t, h):
    """An altimeter's `time (s),altitude (m)` file of `t`, `h` to the millimetre,
    read."""
    path = tmp_path / "log.csv"
    np.savetxt(
        path,
        np.column_stack([t, h]),
        delimiter=",",
        fmt="%.3f",
        header="time (s),altitude (m)",
        comments="",
    )
    return read_rocket_log(path)


@pytest.mark.parametrize("glitch", [False, True])
def test_apogee_not_taken_from_an_ejection_pulse_that_reads_higher(tmp_path, glitch):
    """An ejection charge 0.6 s after apogee: the barometer reads 300 m low for a
    second, then recovers through readings 40 m above the top (a CATS-like flight
    computer's filtered altitude at 20 Hz did this on two flights, 120 and 745 m
    low, 3 and 81 m above the top). A rocket that
    has begun to fall cannot climb back: the apogee is the top before the pulse.
    With `glitch`, a 120 m drop for 0.3 s while the rocket climbs at 250 m/s (a
    transonic pressure jump) changes nothing."""
    rng = np.random.default_rng(3)
    t = np.arange(-0.5, 60.0, 0.05)
    h, _ = truth.flight(t)
    h = h + rng.normal(0, 0.5, t.size)
    s = t - (truth.T_APOGEE + 0.6)
    h = h - 300 * np.exp(-(((s - 0.4) / 0.25) ** 2)) * (s > 0)
    h = h + 70 * np.exp(-(((s - 1.2) / 0.2) ** 2))
    if glitch:
        h = h - 120 * ((t > 2.0) & (t < 2.3))
    log = _altitude_log(tmp_path, t, h)
    assert h.max() > truth.H_APOGEE + 30  # the pulse's recovery reads higher
    # the vertex of the top before the pulse: as without it (0.05 + 0.1 * noise s
    # and 0.5 + noise m in test_events_at_other_rates_and_noise)
    assert _file_time(log, "apogee") == pytest.approx(truth.T_APOGEE, abs=0.1)
    assert log.events["apogee"].value == pytest.approx(truth.H_APOGEE, abs=1.0)
    # the apogee the fit's errors are taken against: the highest sample before the
    # pulse (the noise is 0.5 m: a few sigma above the truth)
    from diffpegasus._rocket._data import logged_apogee

    assert logged_apogee(log) == pytest.approx(truth.H_APOGEE + 0.75, abs=1.0)


def test_time_column_after_its_channels(tmp_path):
    """A logger that writes `alt,t` (the time last): the columns before the first
    time column are its stream's, read as with the time first."""
    rows = [x.split(",") for x in _lines(FIXTURES / "altimeter.csv")]
    first, last = tmp_path / "first.csv", tmp_path / "last.csv"
    first.write_text("\n".join(f"{r[0]},{r[1]}" for r in rows) + "\n")
    last.write_text("\n".join(f"{r[1]},{r[0]}" for r in rows) + "\n")
    a, b = read_rocket_log(first), read_rocket_log(last)
    np.testing.assert_array_equal(a["altitude"].values, b["altitude"].values)
    assert b.events["apogee"].t == a.events["apogee"].t


def test_one_hertz_log_liftoff_after_its_pad_sample(tmp_path):
    """An altimeter writing once a second, its first row on the pad: liftoff lies
    between that row and the next (before, the arc's least 8 samples spanned the
    boost and the coast and put liftoff seconds before the pad row)."""
    rows = [x.split(",") for x in _lines(FIXTURES / "altimeter.csv")[1:]]
    every = [r for r in rows if round((float(r[0]) + 0.3) * 20) % 20 == 0]
    path = tmp_path / "coarse.csv"
    path.write_text("t(s),alt(ft)\n" + "\n".join(f"{r[0]},{r[1]}" for r in every))
    log = read_rocket_log(path)
    liftoff = next(iter(log.time_offsets.values()))  # file time at liftoff; truth 0
    assert float(every[0][0]) <= liftoff <= float(every[1][0])


def test_log_cut_and_rezeroed_in_flight_is_said(tmp_path):
    """A record that starts 1.5 s into the boost with its altitude re-zeroed there
    (0 m at 88 m/s): no boost reaches that from the pad in the time the arc allows,
    and the message says the zero is not the pad; a record cut at the same time
    but not re-zeroed (its first height the pad's 66 m) gives no such message."""
    rows = [x.split(",") for x in _lines(FIXTURES / "altimeter.csv")[1:]]
    late = [r for r in rows if float(r[0]) >= 1.5]
    zero = float(late[0][1])
    cut, rezeroed = tmp_path / "cut.csv", tmp_path / "rezeroed.csv"
    cut.write_text("t(s),alt(ft)\n" + "\n".join(f"{r[0]},{r[1]}" for r in late))
    rezeroed.write_text(
        "t(s),alt(ft)\n" + "\n".join(f"{r[0]},{float(r[1]) - zero:.2f}" for r in late)
    )
    assert not any("not the pad" in m for m in read_rocket_log(cut).messages)
    said = [m for m in read_rocket_log(rezeroed).messages if "not the pad" in m]
    assert len(said) == 1 and "already climbing at" in said[0]


def test_gnss_without_a_fix_dropped(tmp_path):
    """A receiver without a fix writing (-0.0001, -0.0001) among the flight's
    positions near 39.39 N, 8.29 W: those rows leave the GNSS channels, with a
    message naming the first; the altitude keeps every row."""
    rows = [x.split(",") for x in _lines(FIXTURES / "altimeter.csv")[1:]]
    lines = []
    for k, r in enumerate(rows):
        fix = (-0.0001, -0.0001) if k in (40, 41, 300) else (39.39, -8.29 + 1e-5 * k)
        lines.append(f"{r[0]},{r[1]},{fix[0]},{fix[1]}")
    path = tmp_path / "gnss.csv"
    path.write_text("t(s),alt(ft),lat,lon\n" + "\n".join(lines) + "\n")
    log = read_rocket_log(path)
    assert len(log["gnss_lat"].t) == len(rows) - 3
    assert np.all(log["gnss_lat"].values > 39) and np.all(log["gnss_lon"].values < -8)
    assert len(log["altitude"].t) == len(rows)
    assert any(
        "3 rows with the GNSS position" in m and "row 41" in m for m in log.messages
    )


def test_landing_in_the_logs_last_seconds_under_a_slowing_canopy(tmp_path):
    """A main whose descent slows from 12.5 to 10.5 m/s as the air thickens, the
    log ending 1.9 s after touchdown: the landing is found (before, the check of the
    drop between its neighbours took the canopy's slow bend for the best break,
    and the landing was called a wiggle: 'still descending')."""
    rng = np.random.default_rng(5)
    t = np.arange(-1.0, 400.0, 0.01)
    a, burn = 60.0, 3.0
    v0 = a * burn
    t_apo = burn + v0 / G0
    h_apo = 0.5 * a * burn**2 + v0**2 / (2 * G0)
    t_main = t_apo + (h_apo - 800.0) / 25.0
    # main: rate 12.5 - k s, from 800 m to the ground
    k = 2.0 / 70.0
    fall = 800.0 / (12.5 - 0.5 * k * 70.0)
    t_land = t_main + fall
    s = t - t_main
    h = np.select(
        [t < 0, t < burn, t < t_apo, t < t_main, t < t_land],
        [
            0.0 * t,
            0.5 * a * t**2,
            h_apo - 0.5 * G0 * (t - t_apo) ** 2,
            h_apo - 25.0 * (t - t_apo),
            800.0 - (12.5 * s - 0.5 * k * s**2),
        ],
        0.0 * t,
    )
    keep = t < t_land + 1.9
    h = h[keep] + rng.normal(0.0, 0.3, keep.sum())
    path = tmp_path / "canopy.csv"
    path.write_text(
        "t(s),alt(m)\n"
        + "\n".join(f"{x:.2f},{y:.2f}" for x, y in zip(t[keep], h, strict=True))
    )
    log = read_rocket_log(path)
    # measured 0.28 s early: the continuous two lines' break through the binned,
    # noisy descent
    assert log.events["landing"].t == pytest.approx(t_land, abs=0.4)
    assert "the descent stops" in log.events["landing"].how


@pytest.mark.parametrize("dip", [False, True])
def test_apogee_not_taken_from_a_pulse_after_the_climb_stopped(tmp_path, dip):
    """A pressure pulse 1.4 s after apogee reads 50 m above the top within 0.3 s
    and decays over a second (an RRC3 altimeter at 20 Hz did this, 62 m above a
    flat top): the rocket had stopped climbing, and no rocket climbs at 200 m/s
    after it did; the apogee is the top before the pulse. With `dip`, the
    barometer also reads 90 m low for 0.2 s 0.6 s before the top (an ejection
    charge there): those samples are off the arc and do not bend it."""
    rng = np.random.default_rng(5)
    t = np.arange(-0.5, 60.0, 0.05)
    h, _ = truth.flight(t)
    h = h + rng.normal(0, 0.5, t.size)
    s = t - (truth.T_APOGEE + 1.4)
    h = h + 60 * np.clip(s / 0.3, 0, 1) * np.exp(-np.maximum(s - 0.3, 0) / 0.3)
    if dip:
        d = t - (truth.T_APOGEE - 0.6)
        h = h - 90 * ((d > 0) & (d < 0.2))
    log = _altitude_log(tmp_path, t, h)
    assert h.max() > truth.H_APOGEE + 40  # the pulse reads higher
    # as without the pulse (0.05 + 0.1 * noise s and 0.5 + noise m in
    # test_events_at_other_rates_and_noise; the dip leaves ten fewer samples)
    assert _file_time(log, "apogee") == pytest.approx(truth.T_APOGEE, abs=0.1)
    assert log.events["apogee"].value == pytest.approx(truth.H_APOGEE, abs=1.0)
    from diffpegasus._rocket._data import logged_apogee

    assert logged_apogee(log) == pytest.approx(truth.H_APOGEE + 0.75, abs=1.0)


def test_words_in_cells_read_as_empty(tmp_path):
    """An altimeter export (`time, altitude, temperature, events, voltages`) whose
    last rows move the event words into the temperature column and leave the last
    two empty (an RRC3 did this for its last 21 rows): the rows are whole, only the
    temperature is missing; a word in the altitude column mid-file is one empty
    cell. Each is said in a message; no row is dropped."""
    t = np.arange(-0.5, 30.0, 0.05)
    h, _ = truth.flight(t)
    rows = [
        f"{a:.2f},{b:.3f},{31.9 - 0.0065 * b:.1f}, -,3.81"
        for a, b in zip(t, h, strict=True)
    ]
    tail = len(rows) - 21
    for i in range(tail, len(rows)):
        rows[i] = f"{t[i]:.2f},{h[i]:.3f}, -,,"
    rows[300] = f"{t[300]:.2f}, -,31.9, -,3.81"
    path = tmp_path / "log.csv"
    path.write_text("time,altitude,temperature,events,voltages\n" + "\n".join(rows))
    log = read_rocket_log(path)
    alt, temp = log["altitude"], log["temperature"]
    offset = next(iter(log.time_offsets.values()))
    assert alt.t[-1] + offset == pytest.approx(t[-1])  # the last row read
    assert len(alt.t) == len(t) - 1  # only the word's cell left out
    assert temp.t[-1] + offset == pytest.approx(t[tail - 1])
    said = " ".join(log.messages)
    assert "column 'temperature': 21 cell(s) hold a word" in said
    assert "column 'altitude': 1 cell(s) hold a word" in said
    assert "row 301" in said and "dropped the last" not in said
