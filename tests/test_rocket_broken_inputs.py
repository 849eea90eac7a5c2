"""A rocket's own files damaged as people damage them (`experiments/broken_inputs_sweep.py`
found each of these a traceback or silently read): the `rocket.toml` in another
encoding, a table or a file name of the wrong type, a misspelt key, a number as text,
a negative motor mass or hold-down, an elevation in no place on Earth; a thrust curve
with no thrust or a thrust no motor gives. Each is one line naming the file and the
key or the point."""

import pathlib
import shutil

import pytest
from typer.testing import CliRunner

from diffpegasus import LogError, read_rocket_log, rocket as dr
from diffpegasus._cli import app


CLEAN = pathlib.Path(__file__).parent / "data" / "rocket_sim" / "clean"


def _folder(tmp_path):
    folder = tmp_path / "flight"
    shutil.copytree(CLEAN, folder)
    return folder


# (id, text replaced, replacement, pattern of the one line after "rocket.toml: ")
TOML = [
    (
        "rocket not a table",
        "[rocket]\n",
        "rocket = 1\n[rocket_notes]\n",
        r"rocket = 1 is not a table",
    ),
    (
        "thrust_file a number",
        'thrust_file = "motor.csv"',
        "thrust_file = 5",
        r"\[motor\] thrust_file = 5 is not a file name",
    ),
    (
        "drag file a list",
        'power_off_drag_file = "drag.csv"',
        'power_off_drag_file = ["drag.csv"]',
        r"\[aero\] power_off_drag_file = \['drag.csv'\] is not a file name",
    ),
    (
        "misspelt key",
        "dry_mass_kg = 1.6",
        "dry_mass_kg = 1.6\nholddown_time = 1.0",
        r"\[motor\] holddown_time is not a key .* did you mean holddown_time_s\?",
    ),
    (
        "key in other letter case",
        "dry_mass_kg = 1.6",
        "dry_mass_kg = 1.6\nHolddown_time_s = 1.0",
        r"\[motor\] Holddown_time_s is not a key .* did you mean holddown_time_s\?",
    ),
    (
        "misspelt geometry key",
        "nozzle_position_m = 0.0",
        "nozle_position_m = 0.0",
        r"\[geometry\] nozle_position_m is not a key .* did you mean nozzle_position_m\?",
    ),
    (
        "misspelt required key",
        "mass_without_motor_kg = 8.2",
        "mass_without_motr_kg = 8.2",
        r"\[rocket\] mass_without_motr_kg is not a key .* did you mean mass_without_motor_kg\?",
    ),
    (
        "negative motor dry mass",
        "dry_mass_kg = 1.6",
        "dry_mass_kg = -1.6",
        r"\[motor\] dry_mass_kg = -1.6 is negative",
    ),
    (
        "motor dry mass as text",
        "dry_mass_kg = 1.6",
        'dry_mass_kg = "1.6"',
        r"\[motor\] dry_mass_kg = '1.6' is not a number",
    ),
    (
        "elevation as text",
        "elevation_m = 150",
        'elevation_m = "150"',
        r"\[launch\] elevation_m = '150' is not a number",
    ),
    (
        "elevation off the Earth",
        "elevation_m = 150",
        "elevation_m = 1e6",
        r"\[launch\] elevation_m = 1e\+06 is not a pad's elevation",
    ),
    (
        "negative holddown",
        "dry_mass_kg = 1.6",
        "dry_mass_kg = 1.6\nholddown_time_s = -1",
        r"\[motor\] holddown_time_s = -1 is negative",
    ),
    (
        "heading nan",
        "heading_deg = 133",
        "heading_deg = nan",
        r"\[launch\] heading_deg = nan is not a finite number",
    ),
    (
        "temperature as text",
        "surface_temperature_K = 287.177",
        'surface_temperature_K = "287.177"',
        r"\[atmosphere\] surface_temperature_K = '287.177' is text",
    ),
]


@pytest.mark.parametrize(
    "old, new, pattern", [c[1:] for c in TOML], ids=[c[0] for c in TOML]
)
def test_a_damaged_rocket_file_is_one_line(tmp_path, old, new, pattern):
    folder = _folder(tmp_path)
    toml = folder / "rocket.toml"
    text = toml.read_text()
    assert old in text
    toml.write_text(text.replace(old, new, 1))
    with pytest.raises(LogError, match=f"^{toml}: {pattern}") as e:
        dr.read_rocket(toml)
    assert "\n" not in str(e.value)


def test_a_misspelt_parachute_key_is_one_line(tmp_path):
    """A stage's drag area misspelt (before, the stage fell without it)."""
    folder = _folder(tmp_path)
    toml = folder / "rocket.toml"
    toml.write_text(
        toml.read_text() + '\n[[parachutes]]\nname = "Drogue"\ncds_m2 = 0.9\n'
    )
    with pytest.raises(
        LogError,
        match=r"\[\[parachutes\]\] entry 1: cds_m2 is not a key .* "
        r"did you mean cd_s_m2\?",
    ):
        dr.read_rocket(toml)


def test_a_note_beside_a_key_stays_a_note(tmp_path):
    """Keys one or two letters from a key read, that differ only in their digits
    (`I33_kgm2` beside `I11_kgm2`), their unit (`elevation_ft`, `dry_mass_g`,
    `surface_temperature_C`) or their datum (`recorded_apogee_asl_m`), and text notes
    where a number is optional (`"not given"`), are read as before."""
    folder = _folder(tmp_path)
    toml = folder / "rocket.toml"
    text = toml.read_text().replace("I11_kgm2 = 4.4", "I11_kgm2 = 4.4\nI33_kgm2 = 0.01")
    text = text.replace("[launch]\n", "[launch]\nelevation_ft = 492\n")
    text = text.replace("dry_mass_kg = 1.6", "dry_mass_kg = 1.6\ndry_mass_g = 1600")
    text = text.replace("[atmosphere]\n", "[atmosphere]\nsurface_temperature_C = 20\n")
    text = text.replace("[results]", "[results]\nrecorded_apogee_asl_m = 3100")
    text = text.replace(
        "[results]", '[results]\npreflight_simulated_apogee_agl_m = "not given"'
    )
    toml.write_text(text)
    rocket = dr.read_rocket(toml)
    assert rocket.preflight_apogee is None and rocket.dry_mass == pytest.approx(9.8)


@pytest.mark.parametrize(
    "points, pattern",
    [
        ("0.0,0\n1.0,0\n2.0,0\n", r"every thrust point is 0 N"),
        (
            "0.0,0\n1.0,1e30\n2.0,0\n",
            r"thrust 1e\+30 N at t = 1 s is more than any motor",
        ),
    ],
    ids=["no thrust", "thrust no motor gives"],
)
def test_a_thrust_curve_without_a_plausible_thrust_is_refused(
    tmp_path, points, pattern
):
    """Before, a curve of zeros divided by its zero impulse (NaN masses) and a
    thrust of 1e30 N flew."""
    path = tmp_path / "motor.csv"
    path.write_text("time,thrust\n" + points)
    with pytest.raises(LogError, match=f"^{path}: {pattern}"):
        dr.read_motor(path, propellant_mass=1.0)


def test_an_eng_header_without_a_mass_asks_for_one(tmp_path):
    """A RASP header whose propellant field is not a number (before: a ValueError)."""
    path = tmp_path / "m.eng"
    path.write_text("L995 seventy-five long\n0.1 100\n1.0 100\n1.1 0\n")
    with pytest.raises(LogError, match="give the propellant mass .*header 'L995"):
        dr.read_motor(path)


def _eng_folder(tmp_path, header=True):
    """The clean flight with its thrust curve written as a RASP file."""
    folder = _folder(tmp_path)
    rows = (folder / "motor.csv").read_text().split()
    head = "; a comment\nJ500 54 400 0 1.9 3.5 Maker\n" if header else "; no header\n"
    (folder / "motor.eng").write_text(
        head + "\n".join(r.replace(",", " ") for r in rows)
    )
    toml = folder / "rocket.toml"
    toml.write_text(toml.read_text().replace('"motor.csv"', '"motor.eng"'))
    return folder, toml


def test_propellant_mass_from_the_eng_header_where_not_given(tmp_path):
    """A RASP file's header carries the propellant mass: the key may be left out
    (the header's 1.9 kg); given, the key wins; a CSV curve without it asks."""
    folder, toml = _eng_folder(tmp_path)
    given = dr.read_rocket(toml)
    toml.write_text(toml.read_text().replace("propellant_initial_mass_kg = 1.9\n", ""))
    assert dr.read_rocket(toml).motor.propellant_mass == 1.9
    assert given.motor.propellant_mass == 1.9
    toml.write_text(toml.read_text().replace('"motor.eng"', '"motor.csv"'))
    with pytest.raises(LogError, match=r"\[motor\] needs propellant_initial_mass_kg"):
        dr.read_rocket(toml)


def test_an_eng_file_without_its_header_line_keeps_its_first_point(tmp_path):
    """A thrust curve saved as .eng without RASP's motor line: its first point was
    taken for the header and dropped; now it is a point, and the propellant mass,
    which no header gives, is asked for in the rocket file."""
    folder, toml = _eng_folder(tmp_path, header=False)
    motor = dr.read_motor(folder / "motor.eng", propellant_mass=1.9)
    csv = dr.read_motor(folder / "motor.csv", propellant_mass=1.9)
    assert motor.time[0] == csv.time[0] == 0.0
    assert motor.total_impulse == csv.total_impulse
    toml.write_text(toml.read_text().replace("propellant_initial_mass_kg = 1.9\n", ""))
    with pytest.raises(
        LogError, match=r"propellant_initial_mass_kg: .*the file has none"
    ):
        dr.read_rocket(toml)


def test_an_eng_file_with_a_mark_and_comments_after_its_points(tmp_path):
    """A RASP file saved with a byte-order mark and without its motor line, and one
    whose points carry `; comments` (both among RocketPy's motor files): read as
    the plain file is."""
    plain = tmp_path / "plain.eng"
    plain.write_text("M1 75 600 0 2.0 4.0 X\n0.1 2000\n2.0 2000\n2.1 0\n")
    marked = tmp_path / "marked.eng"
    marked.write_bytes(b"\xef\xbb\xbf0 0\n0.1 2000\n2.0 2000\n2.1 0\n")
    noted = tmp_path / "noted.eng"
    noted.write_text("M1 75 600 0 2.0 4.0 X\n0.1 2000 ; lit\n2.0 2000\n2.1 0; out\n")
    want = dr.read_motor(plain).total_impulse
    assert dr.read_motor(noted).total_impulse == want
    assert dr.read_motor(marked, propellant_mass=2.0).total_impulse == want


@pytest.mark.parametrize("mark", [True, False])
def test_a_rocket_file_read_alike_for_the_rocket_and_its_log(tmp_path, mark):
    """The rocket and its logs read one rocket.toml alike: with a byte-order mark
    both read it; with a Latin-1 byte both refuse it in one line (before, the log's
    reader refused the mark and raised a UnicodeDecodeError on Latin-1)."""
    folder = _folder(tmp_path)
    toml = folder / "rocket.toml"
    text = toml.read_bytes()
    if mark:
        toml.write_bytes(b"\xef\xbb\xbf" + text)
        assert dr.read_rocket(toml).name == "sim-clean"
        assert "altitude" in read_rocket_log(toml).channels
    else:
        toml.write_bytes(text.replace(b"sim-clean", b"sim-cl\xe9an"))
        for read in (dr.read_rocket, read_rocket_log):
            with pytest.raises(LogError, match=r"not UTF-8 text \(byte \d+ is 0xe9"):
                read(toml)


@pytest.mark.parametrize("damage", ["latin-1", "binary"])
def test_cli_rocket_file_not_utf8_is_one_line(tmp_path, damage):
    """`rocket fit` on a rocket.toml saved as Latin-1 or not text at all: before, a
    UnicodeDecodeError traceback."""
    folder = _folder(tmp_path)
    toml = folder / "rocket.toml"
    text = toml.read_text().replace("sim-clean", "sim-cl\u00e9an")
    toml.write_bytes(
        text.encode("latin-1") if damage == "latin-1" else b"\x89\xff" * 99
    )
    res = CliRunner().invoke(
        app, ["rocket", "fit", str(toml), "--out", str(tmp_path / "out")]
    )
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {toml}: not UTF-8 text")
    assert not (tmp_path / "out").exists()


def test_a_drag_curve_in_percent_is_refused(tmp_path):
    """A team's CD written in percent (57 for 0.57): before, re-simulated as such."""
    path = tmp_path / "drag.csv"
    path.write_text("mach,cd\n0.1,57.1\n0.5,52.0\n0.9,63.8\n")
    with pytest.raises(LogError, match=f"^{path}: row 2: Mach 0.1, CD 57.1 is beyond"):
        dr.read_drag_curve(path)


def test_a_mass_the_motor_cannot_lift_is_refused(tmp_path):
    """The rocket's mass in grams (8200 kg on a 1.9 kg motor): before, the fit ran,
    its figures failed on NaN axes (a traceback) and left half the --out folder."""
    folder = _folder(tmp_path)
    toml = folder / "rocket.toml"
    toml.write_text(
        toml.read_text().replace(
            "mass_without_motor_kg = 8.2", "mass_without_motor_kg = 8200"
        )
    )
    with pytest.raises(
        LogError,
        match=f"^{toml}: the motor's peak thrust .* does not lift the 8203.5 kg rocket",
    ):
        dr.read_rocket(toml)


def test_a_hold_down_past_the_burn_is_refused(tmp_path):
    """On a hold-down the rocket is released with what thrust is left: released
    after the burn it never lifts (before, the check looked at the curve's peak at
    ignition, and the fit flew a rocket that stayed on the rail); released early it
    does, lighter by the propellant burned."""
    folder = _folder(tmp_path)
    toml = folder / "rocket.toml"
    burn = dr.read_motor(folder / "motor.csv", propellant_mass=1.9).burn_time
    text = toml.read_text()
    toml.write_text(
        text.replace("dry_mass_kg = 1.6", "dry_mass_kg = 1.6\nholddown_time_s = 0.5")
    )
    assert dr.read_rocket(toml).holddown == 0.5
    late = f"dry_mass_kg = 1.6\nholddown_time_s = {burn + 1:g}"
    toml.write_text(text.replace("dry_mass_kg = 1.6", late))
    with pytest.raises(
        LogError, match=rf"peak thrust 0 N after its {burn + 1:g} s hold-down"
    ):
        dr.read_rocket(toml)


def test_rocket_outputs_are_complete_or_absent(tmp_path, monkeypatch):
    """A figure that fails after others were drawn leaves no --out folder and no
    staging folder beside it; a second run leaves none of the first's figures it
    did not draw; a folder that cannot be made is one error line."""
    from diffpegasus._rocket import _pipeline, _report

    def half(problem, result, prediction, team, ee, out):
        (out / "altitude.png").write_bytes(b"png")
        raise ValueError("Axis limits cannot be NaN or Inf")

    monkeypatch.setattr(_report, "figures", half)
    monkeypatch.setattr(_pipeline, "equation_error_drag", lambda result: None)
    out = tmp_path / "out"
    with pytest.raises(ValueError):
        _pipeline._write_outputs(None, None, None, None, {}, False, out)
    assert sorted(tmp_path.iterdir()) == []
    # a fit that did not converge (a radius given as the diameter: NaN bands, and
    # before, a traceback from the figures) gets its summary.json alone
    _pipeline._write_outputs(None, None, None, None, {"converged": False}, False, out)
    assert [p.name for p in tmp_path.iterdir()] == ["out"]
    assert [p.name for p in out.iterdir()] == ["summary.json"]
    # an earlier run's figures do not stay beside it (a file of the user's does)
    for name in ("drag.png", "descent.png", "notes.txt"):
        (out / name).write_bytes(b"earlier")
    _pipeline._write_outputs(None, None, None, None, {"converged": False}, False, out)
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "summary.json"]
    # a folder that cannot be made is one line
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(LogError, match=r"cannot write the results there"):
        _pipeline._write_outputs(
            None, None, None, None, {"converged": False}, False, blocker / "out"
        )


def test_cli_out_naming_a_file_is_refused_before_the_fit(tmp_path):
    """`rocket fit --out FILE`: one line before minutes of fitting (before, a
    FileExistsError traceback after them)."""
    folder = _folder(tmp_path)
    taken = tmp_path / "results"
    taken.write_text("mine")
    res = CliRunner().invoke(
        app, ["rocket", "fit", str(folder / "rocket.toml"), "--out", str(taken)]
    )
    assert res.exit_code == 2
    assert "--out names a file" in res.output and "Traceback" not in res.output
    assert taken.read_text() == "mine"


@pytest.mark.parametrize(
    "value, why",
    [("1e300", "is too large for a measurement"), ("1e12", "times the column's 90th")],
    ids=["overflows", "a corrupt cell"],
)
def test_a_corrupt_cell_in_a_rocket_log_is_refused(tmp_path, value, why):
    """A cell no altimeter writes, as the aircraft readers refuse it: before, read
    (an apogee of 1e300 m went to the fit)."""
    from diffpegasus import read_rocket_log

    folder = _folder(tmp_path)
    log = folder / "log.csv"
    lines = log.read_text().splitlines()
    cells = lines[100].split(",")
    cells[1] = value
    lines[100] = ",".join(cells)
    log.write_text("\n".join(lines) + "\n")
    with pytest.raises(
        LogError,
        match=f"^{log}: column 'altitude_m', row 100: value {value[:2]}.* {why}",
    ):
        read_rocket_log(folder / "rocket.toml")


def test_a_folder_under_a_shipped_flights_name_reads_its_own_log(tmp_path):
    """A flight in a folder named as a shipped one (`cavour`) whose rocket.toml names
    another log: before, the shipped flight's map was applied and read the shipped
    file name beside it (here a stale copy), not the log the rocket.toml names."""
    import numpy as np

    from diffpegasus import read_rocket_log

    folder = tmp_path / "cavour"
    shutil.copytree(CLEAN, folder)
    toml = folder / "rocket.toml"
    text = toml.read_text()
    start = text.index("[log.column_map]")
    toml.write_text(text[:start] + text[text.index("[log.stated_events]") :])
    (folder / "logs").mkdir()
    stale = "ts,altitude[m],velocity[m/s],latitude,longitude\n"
    stale += "".join(f"{0.1 * k:.1f},{k},{10},39.39,-8.29\n" for k in range(300))
    (folder / "logs" / "altimeter_cavour.csv").write_text(stale)
    log = read_rocket_log(toml)
    a = np.loadtxt(folder / "log.csv", delimiter=",", skiprows=1)
    assert float(np.max(log["altitude"].values)) == pytest.approx(np.max(a[:, 1]))


@pytest.mark.parametrize(
    "column, factor, isp",
    [(1, 0.224809, "45.51"), (0, 1000.0, "2.024e\\+05")],
    ids=["thrust in lbf", "times in ms"],
)
def test_a_thrust_curve_in_other_units_is_refused(tmp_path, column, factor, isp):
    """The curve's impulse over the propellant's weight is no motor's specific
    impulse (the clean flight's 202 s): before, a thrust in lbf or times in ms flew,
    and the fit's NaN figures ended in a traceback."""
    import numpy as np

    a = np.loadtxt(CLEAN / "motor.csv", delimiter=",", skiprows=1)
    a[:, column] *= factor
    path = tmp_path / "motor.csv"
    np.savetxt(path, a, delimiter=",", header="time,thrust", comments="")
    with pytest.raises(LogError, match=f"^{path}: .* specific impulse of {isp} s"):
        dr.read_motor(path, propellant_mass=1.9)
    # through the rocket file, the line names the key that holds the mass too
    folder = _folder(tmp_path / "flight")
    (folder / "motor.csv").write_text(path.read_text())
    toml = folder / "rocket.toml"
    with pytest.raises(
        LogError, match=rf"^{toml}: \[motor\] propellant_initial_mass_kg = 1.9 with "
    ):
        dr.read_rocket(toml)
