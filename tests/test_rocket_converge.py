"""A rocket that flew air brakes: the brakes' schedule read as the command log it
is, shaped by the team's drag table, and their drag estimated by default, on the
committed RocketPy flight given a brake schedule (no fit: the record and the
fit's default set, which decide what the fit can reach)."""

import pathlib

import numpy as np
import pytest

import diffpegasus as dp
from diffpegasus import read_rocket_log, rocket as dr


SIM = pathlib.Path(__file__).parent / "data" / "rocket_sim"


def _braked_flight(tmp_path, table=True):
    """The clean RocketPy flight's folder with an air-brake schedule written as
    Camoes's is (a row `(0, 0)`, then fully out from 5 s, half out from 10 s, in
    at 14 s) and, with `table`, a team's `(deployment, Mach, CD)` table whose
    increment over the closed brakes is `0.2 d^2` at every Mach."""
    folder = tmp_path / "braked"
    folder.mkdir(parents=True)
    for f in (SIM / "clean").iterdir():
        (folder / f.name).write_bytes(f.read_bytes())
    (folder / "brakes.csv").write_text("0,0\n5,1\n7.5,1\n10,0.5\n12,0.5\n14,0\n")
    aero = '[aero]\nair_brakes_actuation_file = "brakes.csv"\n'
    if table:
        rows = ["deployment_level, mach, cd"]
        for m in (0.1, 0.5, 0.9):
            for d in (0.0, 0.25, 0.5, 0.75, 1.0):
                rows.append(f"{d}, {m}, {0.5 + 0.1 * m + 0.2 * d**2}")
        (folder / "brakes_table.csv").write_text("\n".join(rows) + "\n")
        aero += 'air_brakes_table = "brakes_table.csv"\n'
    text = (SIM / "clean" / "rocket.toml").read_text()
    (folder / "rocket.toml").write_text(text.replace("[aero]\n", aero, 1))
    return folder


def test_air_brakes_held_between_rows_shaped_by_the_table_and_estimated(tmp_path):
    """Camoes's schedule starts with a row `(0, 0)` and the next at 3.8 s: read by
    straight lines between rows, the brakes opened over the whole boost (0.53 out
    at 2 s) where the law says closed. A command log holds each row's value until
    the next: closed until 5 s here. The team's table makes the drag the brakes
    add at half deployment a quarter of that fully out (`0.2 d^2`), so the input
    is `d^2`, the brakes' CD starts at the table's 0.2, and it is estimated (held
    at zero, the drag knots took the brakes up as a function of Mach, which the
    schedule is not, and the fit of Camoes did not converge)."""
    folder = _braked_flight(tmp_path)
    rocket = dr.read_rocket(folder / "rocket.toml")
    problem = dr.prepare(rocket, read_rocket_log(SIM / "clean" / "rocket.toml"))
    t, brake = problem.record.t, problem.record.inputs[:, 0]
    # the schedule held from each row to the next, squared by the table
    expected = np.select([t < 5, t < 10, t < 14], [0.0, 1.0, 0.25], 0.0)
    np.testing.assert_allclose(brake, expected, atol=1e-12)
    assert abs(problem.start["airbrake_cd"] - 0.2) < 1e-12
    assert dr.default_free(problem)[-1] == "airbrake_cd"

    # without a table the deployment itself, the brakes' CD starting from zero
    folder2 = _braked_flight(tmp_path / "plain", table=False)
    plain = dr.prepare(
        dr.read_rocket(folder2 / "rocket.toml"),
        read_rocket_log(SIM / "clean" / "rocket.toml"),
    )
    expected = np.select([t < 5, t < 10, t < 14], [0.0, 1.0, 0.5], 0.0)
    np.testing.assert_allclose(plain.record.inputs[:, 0], expected, atol=1e-12)
    assert plain.start["airbrake_cd"] == 0.0
    assert "airbrake_cd" in dr.default_free(plain)


@pytest.mark.parametrize(
    ("schedule", "table", "message"),
    [
        ("0,0\n3,8,1\n", None, "brakes.csv: row 2: deployment 8 is not within 0-1"),
        ("0,0\n5,100\n", None, "brakes.csv: row 2: deployment 100 is not within 0-1"),
        ("0,0\n5,1\n4,0\n", None, "brakes.csv: row 3: time 4 s is before"),
        ("5,1\n", None, "brakes.csv: one row"),
        ("t,d\n0,0\n5,x\n", None, "brakes.csv: row 3: '5,x' is not 'time s deploy"),
        ("0,0\n5,1\n", "0,0.5,0.6\n0.5,0.5,0.7\n", "no rows at deployment 1"),
        ("0,0\n5,1\n", "0,0.5,0.6\n1,0.5,0.5\n", "add CD -0.1 over the closed"),
    ],
)
def test_air_brake_files_refused_in_one_line(tmp_path, schedule, table, message):
    """A schedule or table a user could write wrongly (a decimal comma, a
    deployment in percent, time going back, one row, a stray word, no fully
    deployed rows, brakes that lower the drag): one line naming the file, the row
    and the value, before any fit."""
    folder = _braked_flight(tmp_path, table=table is not None)
    (folder / "brakes.csv").write_text(schedule)
    if table is not None:
        (folder / "brakes_table.csv").write_text(table)
    with pytest.raises(dp.LogError) as e:
        dr.read_rocket(folder / "rocket.toml")
    assert message in str(e.value) and "\n" not in str(e.value)


CAMOES = pathlib.Path("/work/shared/data/rockets/camoes/rocket.toml")


@pytest.mark.skipif(not CAMOES.exists(), reason="needs the shared rocket flights")
def test_camoes_burn_scale_starts_at_the_burn_its_accelerometer_reads():
    """Camoes's specific force is above gravity's share along the rail by 5 m/s^2
    for 4.42 s where its motor file burns 3.72 s (a ratio of 1.19, counted here in
    numpy from the log); the equation-error start reads the whole curve's stretch,
    1.24 (its fit: 1.252 +/- 0.001), where 1 had left the fit at 1.04."""
    rocket = dr.read_rocket(CAMOES)
    problem = dr.prepare(rocket, read_rocket_log(CAMOES))
    rec = problem.record
    has = (rec.inputs[:, 2] > 0) & (rec.t > -0.5) & (rec.t < 8.0)
    t, f = rec.t[has], rec.measured[has, 1]
    above = t[f > 9.80665 * np.sin(np.radians(rocket.inclination)) + 5.0]
    ratio = (above[-1] - above[0]) / rocket.motor.burn_time
    assert abs(ratio - 1.19) < 0.01
    assert ratio < problem.start["burn_scale"] < ratio + 0.07
