"""The rocket's descent under parachutes: the fall under a drag area and each
stage's drag area recovered from a log."""

import pathlib
import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diffpegasus.rocket as dr
from diffpegasus import Record
from diffpegasus._estimate._fit import simulate
from diffpegasus._vehicle._rocket._descent import Descent, terminal_velocity
from diffpegasus._vehicle._rocket._model import observe

from .helpers import rocket_parameters


DATA = pathlib.Path(__file__).parent / "data"
# RocketPy's rocket (scripts/make_rocket_fixtures.py --descent): 9.8 kg burned out
FOLDER = DATA / "rocket_descent" / "descent-c-s5-20hz"


def _flight(deploy):
    rocket = dr.read_rocket(FOLDER / "rocket.toml")
    knots = dr.DragKnots((0.1, 0.5, 0.9))
    return rocket, dr.Flight(rocket, knots, 99_500.0, Descent(deploy))


def _start(flight, **over):
    # burned out long before
    return rocket_parameters(
        flight, temperature=287.0, motor_time=-100.0, **{"cds_drogue": 0.25, **over}
    )


def test_falling_point_mass_reaches_its_terminal_velocity():
    """Dropped at rest from 1.5 km under CdS 0.8 m^2 for 60 s: the fall rate is
    `sqrt(2 m g / (rho CdS))` at the height it has reached (m the burned-out
    9.8 kg; rho and g the model's there). The fall is quasi-steady in a density
    that changes with height: the lag behind the local terminal velocity is
    about v^2 / (2 H g) ~ 0.1% (H ~ 9 km the density's scale height), so 0.3%."""
    rocket, flight = _flight((0.0,))
    model = dr.rocket_model(flight, ("altitude",), _start(flight, cds_drogue=0.8), ())
    t = np.arange(0.0, 60.0, 0.02)
    x0 = np.zeros(6)
    x0[2] = 1500.0
    rec = Record(t, np.column_stack([np.zeros_like(t), np.ones_like(t)]), 0 * t, x0)
    x = simulate(model, rec)
    h, vu = x[-1, 2], x[-1, 5]
    rho = float(flight.air(h, _start(flight))[0])
    g = float(flight.gravity(h))
    expected = float(terminal_velocity(rocket.dry_mass, g, rho, 0.8))
    assert 11.0 < expected < 17.0  # the case is a parachute's, not a brick's
    assert -vu == pytest.approx(expected, rel=3e-3)
    assert abs(x[-1, 0]) < 1.0 and abs(x[-1, 1]) < 1.0  # no wind: no drift


def test_the_main_replaces_the_drogue_at_its_deployment():
    """Under the drogue to 10 s, the main after: the fall rate approaches each
    stage's terminal velocity (drogue 0.25 m^2 then main 2.5 m^2: about
    sqrt(10) slower)."""
    rocket, flight = _flight((0.0, 10.0))
    p = _start(flight, cds_drogue=0.25, cds_main=2.5)
    model = dr.rocket_model(flight, ("altitude",), p, ())
    t = np.arange(0.0, 30.0, 0.02)
    x0 = np.zeros(6)
    x0[2] = 2000.0
    rec = Record(t, np.column_stack([np.zeros_like(t), np.ones_like(t)]), 0 * t, x0)
    x = simulate(model, rec)
    for when, cds in ((9.9, 0.25), (29.9, 2.5)):
        k = int(np.argmin(np.abs(t - when)))
        rho = float(flight.air(x[k, 2], p)[0])
        v = float(terminal_velocity(rocket.dry_mass, flight.gravity(x[k, 2]), rho, cds))
        assert -x[k, 5] == pytest.approx(v, rel=5e-3), when


def test_start_drag_areas_from_a_logs_fall_rates():
    """A rocket file without CdS: each stage's start is the drag area whose
    terminal velocity is the log's fall rate. The model's fall under 0.3 then
    3.0 m^2 (main at 40 s), its heights read as the log: both within 1% (the
    rates' median over the stage is at its median height within the density's
    change over a second's fall)."""
    import dataclasses

    from diffpegasus._rocket._descent import start_drag_areas

    rocket, flight = _flight((0.0, 40.0))
    p = _start(flight, cds_drogue=0.3, cds_main=3.0)
    model = dr.rocket_model(flight, ("altitude",), p, ())
    t = np.arange(0.0, 70.0, 0.05)
    x0 = np.zeros(6)
    x0[2] = 2500.0
    x0[5] = -25.0
    rec = Record(t, np.column_stack([np.zeros_like(t), np.ones_like(t)]), 0 * t, x0)
    h = np.asarray(simulate(model, rec))[:, 2]
    log = Record(t, rec.inputs, h[:, None], x0)
    bare = dataclasses.replace(rocket, parachutes=((None, None), (None, 300.0)))
    start = start_drag_areas(bare, log, (0.0, 40.0), 99_500.0, 287.0)
    assert start["cds_drogue"] == pytest.approx(0.3, rel=0.01)
    assert start["cds_main"] == pytest.approx(3.0, rel=0.01)
    given = start_drag_areas(rocket, log, (0.0, 40.0), 99_500.0, 287.0)
    assert given == {"cds_drogue": 0.25, "cds_main": 2.5}  # the rocket file's


@pytest.mark.validation
def test_a_synthetic_descent_logs_drag_areas_are_recovered():
    """The model's own flight of the RocketPy fixture's rocket (its drag curve,
    catalogue thrust) under a drogue of 0.32 m^2 from 23 s and a main of 1.9 m^2
    full 1.5 s after its event at 45 s, to 60 s, read at 20 Hz with 1 m of noise
    on the barometer and 0.5 m/s^2 on the accelerometer (ascent only), events
    giving both deployments. Fitted with the descent from the rocket file's 0.25
    and 2.5 m^2 and the main's opening as the log reads it: each stage's CdS and
    the main's opening within three of their standard errors of the truth, and
    the drag areas' errors small (the drogue's about 0.1%, the main's about 0.4%;
    measured 0.3198 ± 0.0003, 1.896 ± 0.007 and 1.482 ± 0.013 s)."""
    rocket = dr.read_rocket(FOLDER / "rocket.toml")
    t = np.arange(0.0, 60.0, 0.05)
    truth = {"cds_drogue": 0.32, "cds_main": 1.9, "open_main": 1.5}
    # a log to prepare the flight from: the fixture's own, cut at 60 s
    a = np.loadtxt(FOLDER / "log.csv", delimiter=",", skiprows=1)
    a = a[a[:, 0] < 60.0]
    log = _log(a[:, 0], a[:, 1], a[:, 2], {"drogue": 23.0, "main": 45.0})
    problem = dr.prepare(rocket, log, descent=True)
    start = dict(problem.start, thrust_scale=1.0, motor_time=0.0, **truth)
    flight = problem.flight
    model = dr.rocket_model(flight, problem.outputs, start, ())
    rec = problem.record
    x = simulate(model, rec)
    y = np.asarray(
        jax.vmap(lambda ti, xi: observe(flight, ti, xi, jnp.ones(3), start))(
            rec.t, jnp.asarray(x)
        )
    )
    rng = np.random.default_rng(3)
    keep = (rec.t >= 0.0) & (rec.t < t[-1])
    baro = y[keep, 0] + rng.normal(0.0, 1.0, keep.sum())
    accel = y[keep, 1] + rng.normal(0.0, 0.5, keep.sum())
    log = _log(rec.t[keep], baro, accel, {"drogue": 23.0, "main": 45.0})
    problem = dr.prepare(rocket, log, descent=True)
    assert problem.start["cds_drogue"] == 0.25  # the rocket file's
    fit = dr.fit_rocket(problem, free=(), drag="scale", throw=False, spread=False)
    for name, value in truth.items():
        est, se = fit.estimate(name)
        assert abs(est - value) < 3 * se, (name, est, se)
        assert se < 0.03 * value or name == "open_main", (name, se)


def _log(t, baro, accel, events):
    def channel(v):
        return types.SimpleNamespace(t=t, values=v, filtered=False)

    ev = {"liftoff": types.SimpleNamespace(t=0.0)}
    ev.update({k: types.SimpleNamespace(t=v) for k, v in events.items()})
    return types.SimpleNamespace(
        channels={"altitude": channel(baro), "accel_axial": channel(accel)},
        events=ev,
        pad={},
    )


def test_bad_parachutes_and_stated_events_refused_in_one_line(tmp_path):
    """A rocket file's parachutes and stated events that cannot be right stop with
    one line naming the file, the entry and key, and the value: a stage that is
    not a table, a number given as text, a deployment height below the pad, an
    opening lag below 0, a stated event outside the log's times (it would move
    every event, or cut the ascent past the descent), and a main opening too soon
    after the drogue for its own drag area (a trigger height above the apogee: at
    once)."""
    import shutil

    import diffpegasus as dp

    good = (FOLDER / "rocket.toml").read_text()

    def case(name, text):
        folder = tmp_path / name
        shutil.copytree(FOLDER, folder)
        (folder / "rocket.toml").write_text(text)
        return folder / "rocket.toml"

    chute = "trigger_altitude_agl_m = 300.0"
    for name, text, words in [
        ("entry", "parachutes = [1, 2]\n" + good.split("[[parachutes]]")[0],
         ("entry 1", "1")),
        ("text", good.replace(chute, 'trigger_altitude_agl_m = "300 m"'),
         ("entry 2", "trigger_altitude_agl_m", "'300 m'")),
        ("below", good.replace(chute, "trigger_altitude_agl_m = -50"),
         ("entry 2", "trigger_altitude_agl_m", "-50")),
        ("lag", good.replace(chute, chute + "\nlag_s = -1"),
         ("entry 2", "lag_s", "-1")),
    ]:  # fmt: skip
        with pytest.raises(dp.LogError) as err:
            dr.read_rocket(case(name, text))
        line = str(err.value)
        assert "\n" not in line and "rocket.toml" in line
        assert all(w in line for w in words), line
    late = case("late", good.replace("apogee_s = 23.064", "apogee_s = 1000.0"))
    with pytest.raises(dp.LogError, match=r"apogee_s = 1000 is outside .*134\.95"):
        dp.read_rocket_log(late)
    high = case("high", good.replace(chute, "trigger_altitude_agl_m = 5000.0"))
    rocket = dr.read_rocket(high)
    log = dp.read_rocket_log(high.parent / "log.csv")
    log.events.pop("main")  # a log that does not say when its main opened
    with pytest.raises(dp.LogError, match=r"log\.csv: the main .* 5000") as err:
        dr.prepare(rocket, log, descent=True)
    assert "\n" not in str(err.value)


def test_the_main_opens_its_opening_time_after_its_event():
    """The main's event at 10 s, its canopy full 2 s later (`open_main`, RocketPy's
    parachute lag): the model's height and fall rate against scipy's vertical fall
    under the drogue's drag area to 12 s and the main's after (the model's air
    density and gravity, tabulated every metre of height, its burned-out mass), at
    every second to 30 s (the fall rate but at 12 s, mid-ramp). The model's 0.2 s
    ramp centred on the opening has the step's area, but the canopy brakes the
    rocket at about 10 g: the two differ by 0.11 m and 3e-3 m/s (measured); 0.15 m
    and 5e-3 m/s. Opened at the event instead, the height is 37 m higher: the lag
    is what the test sees. A fit's step may take
    a drag area through zero: the model uses its magnitude (the fall under -0.25
    and -2.5 m^2 is the fall under 0.25 and 2.5 m^2 to the bit, where a signed one
    pushed the rocket down ever faster, non-finite within 3 s)."""
    from scipy.integrate import solve_ivp

    # the drogue full before the record starts: its own ramp is not tested here
    rocket, flight = _flight((-1.0, 10.0))
    p = _start(flight, cds_drogue=0.25, cds_main=2.5, open_main=2.0)
    t = np.arange(0.0, 30.02, 0.02)
    x0 = np.zeros(6)
    x0[2], x0[5] = 2000.0, -27.0
    rec = Record(t, np.column_stack([np.zeros_like(t), np.ones_like(t)]), 0 * t, x0)

    def fly(**over):
        model = dr.rocket_model(flight, ("altitude",), p | over, ())
        return np.asarray(simulate(model, rec))

    x = fly()
    heights = np.arange(1000.0, 2001.0)
    rho = np.asarray(flight.air(jnp.asarray(heights), p)[0])
    g = np.asarray(flight.gravity(jnp.asarray(heights)))

    def fall(cds):
        def rates(_, y):
            drag = 0.5 * np.interp(y[0], heights, rho) * cds * y[1] ** 2
            return [y[1], -np.interp(y[0], heights, g) + drag / rocket.dry_mass]

        return rates

    tol = dict(rtol=1e-10, atol=1e-8)
    a = solve_ivp(fall(0.25), (0.0, 12.0), [2000.0, -27.0], dense_output=True, **tol)
    b = solve_ivp(fall(2.5), (12.0, 30.0), a.y[:, -1], dense_output=True, **tol)
    every = np.arange(1.0, 31.0)
    ref = np.array([a.sol(s) if s <= 12.0 else b.sol(s) for s in every])
    k = np.searchsorted(t, every - 1e-9)
    off = every != 12.0  # mid-ramp
    assert np.abs(x[k, 2] - ref[:, 0]).max() < 0.15
    assert np.abs(x[k, 5] - ref[:, 1])[off].max() < 5e-3
    early = fly(open_main=0.0)[-1, 2] - x[-1, 2]
    assert early > 30.0
    np.testing.assert_array_equal(fly(cds_drogue=-0.25, cds_main=-2.5), x)


def test_descent_fixtures_read_through_their_rocket_toml():
    """The RocketPy descent flights' `rocket.toml` `[log]` tables: the channels
    `read_rocket_log` gives are the CSV's columns as numpy reads them, to the
    bit; the stated events are RocketPy's (the main's trigger, not the canopy's
    opening the data show 2.9 s later on the flight with a 2.5 s lag); the
    parachutes' `lag_s` are read, and the opening times to start from are the
    drogue's `lag_s` and the main's as the log shows it."""
    import diffpegasus as dp
    from diffpegasus._rocket._descent import descent_record, start_openings

    for folder in sorted((DATA / "rocket_descent").iterdir()):
        log = dp.read_rocket_log(folder / "rocket.toml")
        a = np.loadtxt(folder / "log.csv", delimiter=",", skiprows=1)
        for j, name in ((1, "altitude"), (2, "accel_axial")):
            np.testing.assert_array_equal(log.channels[name].t, a[:, 0])
            np.testing.assert_array_equal(log.channels[name].values, a[:, j])
        assert log.events["drogue"].t == pytest.approx(23.07)
        assert log.events["main"].t == pytest.approx(116.85, abs=0.011)
    # the opening times to start from: the drogue's the file's lag_s (0 without),
    # the main's read from the log's drop over the seconds left out: RocketPy's
    # 2.5 s within 0.25 s (measured 2.64), its instant opening within 0.4 s
    # (measured 0.29; the model's braking from the drogue's rate is not in the
    # reading, which takes it for a later opening)
    for name, drogue, main in (
        ("descent-open-c-s9-20hz", 1.0, 2.5),
        ("descent-c-s5-20hz", 0.0, 0.0),
    ):
        toml = DATA / "rocket_descent" / name / "rocket.toml"
        rocket = dr.read_rocket(toml)
        record, _, deploy = descent_record(dp.read_rocket_log(toml), rocket)
        start = start_openings(rocket, record, deploy)
        assert start["open_drogue"] == drogue
        assert abs(start["open_main"] - main) < (0.25 if main else 0.4), start
    assert rocket.parachute_lags == (None, None)  # the clean flight's file: none
    toml = DATA / "rocket_descent/descent-open-c-s9-20hz/rocket.toml"
    assert dr.read_rocket(toml).parachute_lags == (1.0, 2.5)


@pytest.mark.validation
def test_a_rocketpy_parachute_lag_is_recovered():
    """RocketPy's flight under a drogue full 1 s after apogee and a main full 2.5 s
    after its trigger at 300 m (`lag`; scripts/make_rocket_fixtures.py --descent
    descent-open-c-s9-20hz), its rocket file's `[log]` stating RocketPy's events.
    The fit with the descent, the main's opening started at 0 (the drogue's held at
    the file's 1 s): the main's drag area within 0.1 m^2 of 2.5 (measured 2.539 ±
    0.043) and its opening time within 0.25 s of 2.5 (measured 2.64 ± 0.05 from
    the file's 2.5: RocketPy's canopy carries added air, which slows its braking,
    and the model's does not). The instantaneous opening this replaces fitted
    1.41 ± 0.10 m^2."""
    import diffpegasus as dp

    toml = DATA / "rocket_descent" / "descent-open-c-s9-20hz" / "rocket.toml"
    problem = dr.prepare(dr.read_rocket(toml), dp.read_rocket_log(toml), descent=True)
    # the drogue's held at the file's lag, the main's started from the log's drop
    assert problem.start["open_drogue"] == 1.0
    assert abs(problem.start["open_main"] - 2.5) < 0.25, problem.start
    fit = dr.fit_rocket(problem, start={"open_main": 0.0}, throw=False, spread=False)
    assert fit.fit.converged
    cds, _ = fit.estimate("cds_main")
    opening, se = fit.estimate("open_main")
    assert abs(abs(cds) - 2.5) < 0.1, cds
    assert abs(opening - 2.5) < 0.25 and se < 0.1, (opening, se)


def test_a_held_opening_past_the_next_event_is_refused_in_one_line():
    """A drogue's `lag_s` of 1000 (milliseconds written as seconds) would keep it
    shut past the main's event, through the whole descent, silently: refused in one
    line naming the entry, the lag and the event it passes."""
    import dataclasses

    import diffpegasus as dp
    from diffpegasus._rocket._descent import descent_record, start_openings

    toml = DATA / "rocket_descent/descent-open-c-s9-20hz/rocket.toml"
    rocket = dr.read_rocket(toml)
    record, _, deploy = descent_record(dp.read_rocket_log(toml), rocket)
    late = dataclasses.replace(rocket, parachute_lags=(1000.0, 2.5))
    with pytest.raises(dp.LogError, match=r"\[\[parachutes\]\] 1: lag_s = 1000 s") as e:
        start_openings(late, record, deploy)
    assert "next parachute's event" in str(e.value) and "\n" not in str(e.value)
    assert start_openings(rocket, record, deploy)["open_drogue"] == 1.0


def test_an_opening_time_below_0_is_refused_and_never_stepped_to():
    """A canopy full before its event fired is no parachute's (at an opening below
    -0.1 s, half the ramp, the model's canopy is full at its event whatever the
    opening: the cost is flat in it). Through the public API an opening time below
    0 (and NaN), the drogue's or the main's, is refused in one line naming it, by
    the simulation and the fit alike, before anything is compiled; 0, a canopy
    full at once, is allowed. A fit's step below 0 finds the model's outputs NaN,
    which the engine rejects; at 0 and just above, finite."""
    import diffpegasus as dp

    toml = FOLDER / "rocket.toml"
    problem = dr.prepare(dr.read_rocket(toml), dp.read_rocket_log(toml), descent=True)
    for name, value in (("open_main", -0.5), ("open_main", float("nan"))) + (
        ("open_drogue", -1e-3),
    ):
        for run in (dr.simulate_flight, dr.fit_rocket):
            with pytest.raises(dp.LogError) as err:
                run(problem, start={name: value})
            line = str(err.value)
            assert "\n" not in line and f"{name} = {value:g}:" in line
            assert "opening time after its event (s) must be 0 or above" in line
    model = dr.rocket_model(
        problem.flight, problem.outputs, dict(problem.start, open_main=0.0), ()
    )
    x, u = jnp.asarray(problem.flight.initial_state()), jnp.ones(3)
    outputs = jax.jit(model.g)
    for opening, finite in ((-1e-3, False), (-2.0, False), (0.0, True), (1e-3, True)):
        theta = np.asarray(model.start)
        theta[model.parameters.index("open_main")] = opening
        y = np.asarray(outputs(0.5, x, u, jnp.asarray(theta)))
        assert np.all(np.isfinite(y)) if finite else np.all(np.isnan(y))


def test_an_estimated_opening_starts_inside_its_bound():
    """RocketPy's main full 2.5 s after its trigger, its event stated 3.5 s after
    the trigger: the log reads the canopy full before the event (the reading below
    0). The main's opening starts at 0.05 s, inside the bound, not on it: from 0,
    where the data would take it below, every step of the fit was rejected and it
    stopped with every parameter at its start (single shooting: det(R) 5.5e4,
    `python experiments/rocket_open_bound.py --single` before the floor). The
    drogue's, held, stays at the file's 1 s."""
    import dataclasses

    import diffpegasus as dp
    from diffpegasus._rocket._descent import descent_record, start_openings

    toml = DATA / "rocket_descent/descent-open-c-s9-20hz/rocket.toml"
    rocket, log = dr.read_rocket(toml), dp.read_rocket_log(toml)
    event = log.events["main"]
    log.events["main"] = dataclasses.replace(event, t=event.t + 3.5)
    record, _, deploy = descent_record(log, rocket)
    assert start_openings(rocket, record, deploy) == {
        "open_drogue": 1.0,
        "open_main": 0.05,
    }
