"""Identify a rocket's drag and thrust from its flight log on the one engine.

[`fit_rocket`][] fits `CD(Mach)` knots (power off; power on by the team's ratio), a
thrust scale and the motor's start time, plus any effects asked for, to the ascent
by output error with multiple shooting ([`fit`][]) and continuation from a one-factor
drag fit, then single shooting from there, and reports the trajectory, the
reconstructed apogee and `CD(Mach)` with its band from the coloured-residual standard
errors. [`equation_error_drag`][] turns measured coast acceleration into `CD` points
with the fitted trajectory's air data, as a check beside it.
"""

import dataclasses

import numpy as np

from .._errors import LogError
from .._estimate._fit import Fit, fit, MultipleShooting, simulate
from .._vehicle._rocket import DragKnots, EFFECTS, Flight, Rocket, rocket_model
from .._vehicle._rocket._model import observe as _observe
from ._data import ascent_record, GNSS, pad_pressure


BASE_FREE = ("thrust_scale", "motor_time")
SENSOR_FREE = ("baro_lag", "static_error")
# the wind along the rail's heading, where an accelerometer spans the ascent
WIND_FREE = ("wind_along",)
# with GNSS positions: the wind's two components, a cross wind drifting the
# rocket at first order
GNSS_WIND_FREE = ("wind_east", "wind_north")
# the accelerometer fixes the length scale the barometer reads in, at every height
ACCEL_FREE = ("temperature", "lapse_rate")
# with gyros and the attitude: the weathercocking's stiffness and damping
GYRO_FREE = ("cn_alpha_scale", "pitch_damping_scale")
# the motor's burn time over the catalogue's, where an accelerometer spans the boost:
# the burn's shape is what it reads (a barometer integrates it twice, into drag)
BURN_FREE = ("burn_scale",)
# the CD the air brakes add fully out, where the rocket flew them: held at zero the
# drag knots take it up as a function of Mach, which the brakes' schedule is not
AIRBRAKE_FREE = ("airbrake_cd",)
STANDARD_LAPSE = -6.5  # K/km
# Mach between drag knots: an accelerometer reads drag directly, as finely as a
# team's tables; an altitude alone carries it twice integrated, so half as finely
KNOT_SPACING = {True: 0.1, False: 0.2}


@dataclasses.dataclass(frozen=True)
class RocketFit:
    """One flight's identification.

    **Fields:** `rocket`, `flight` (the model's [`Flight`][]), `fit` (the engine's
    [`Fit`][]), `record`, `outputs`, `t` `(samples,)` s, `states` `(samples, 6)`
    (east, north, up m; velocities m/s), `baro` `(samples,)` m the model's
    barometric altitude, `accel` `(samples,)` m/s^2 its axial specific force, `mach`
    `(samples,)`, `apogee` m (barometric, as the log reports it), `apogee_time` s,
    `tries` (label -> `(det(R) of the try's own fit, det(R) of its parameters
    flown from the pad, converged)`, the fits [`fit_rocket`][] chose from),
    `spread` the sensors' disagreement over the drag knots ([`Spread`][], `None`
    with one sensor), whose between-sensor variance joins `CD`'s band.
    """

    rocket: Rocket
    flight: Flight
    fit: Fit
    record: object
    outputs: tuple
    t: np.ndarray
    states: np.ndarray
    baro: np.ndarray
    accel: np.ndarray
    mach: np.ndarray
    apogee: float
    apogee_time: float
    tries: dict = dataclasses.field(default_factory=dict)
    spread: object = None

    @property
    def knots(self) -> DragKnots:
        return self.flight.knots

    def cd(self, mach, structural: bool = True):
        """`(cd, stderr)` of power-off `CD` at `mach` `(m,)` from the knots and their
        covariance (coloured-residual standard errors, estimate correlations) and,
        with `structural` and two sensors, the between-sensor variance
        (`spread.tau`, the model's structural error the log shows, knot by knot,
        carried fully correlated through the interpolation)."""
        names = self.fit.model.parameters
        idx = [names.index(n) for n in self.knots.names]
        est = self.fit.params[idx] * self.fit.params[names.index("cd_scale")]
        cov = self.knot_covariance()
        w = self.knots.weights(mach)
        var = np.einsum("mk,kl,ml->m", w, cov, w)
        if structural and self.spread is not None:
            var = var + (np.abs(w) @ self.spread.tau) ** 2
        return w @ est, np.sqrt(np.clip(var, 0, None))

    def knot_covariance(self) -> np.ndarray:
        """`(k, k)` covariance of the power-off CD at the knots, `cd_scale` times
        each knot's value: the estimated ones' covariance (coloured-residual) carried
        through that product's Jacobian, so a fit with the knots held and the scale
        estimated (the prediction's) gives the curve's shape times the scale's
        uncertainty, and one with the knots estimated and the scale held at 1 the
        knots' own covariance."""
        names = list(self.fit.model.parameters)
        both = [*self.knots.names, "cd_scale"]
        idx = [names.index(n) for n in both]
        knots = self.fit.params[idx[:-1]]
        scale = self.fit.params[idx[-1]]
        jac = np.column_stack([scale * np.eye(len(knots)), knots])
        free = np.asarray(self.fit.free)[idx]
        cov = self.fit.covariance_of([n for n, f in zip(both, free, strict=True) if f])
        return jac[:, free] @ cov @ jac[:, free].T

    def estimate(self, name) -> tuple[float, float]:
        i = self.fit.model.parameters.index(name)
        return float(self.fit.params[i]), float(self.fit.stderr_corrected[i])

    def rms(self) -> float:
        """m, RMS of the barometric altitude residual over the logged ascent."""
        has = self.record.inputs[:, 1] > 0
        e = self.record.measured[has, 0] - self.fit.outputs[0][has, 0]
        return float(np.sqrt(np.mean(e**2)))


def default_start(rocket: Rocket, knots: DragKnots, temperature: float) -> dict:
    """Start values: the team's power-off curve at the knots (0.5 without one),
    the team's power-on ratio, catalogue thrust, the motor lighting so that it lifts
    off at log time 0, the day's pad temperature, nothing else."""
    start = dict.fromkeys(EFFECTS, 0.0)
    if rocket.team_drag_off is not None:
        m, c = rocket.team_drag_off
        good = m >= 0.05  # some tables fall to 0 at rest
        cd = np.interp(knots.mach, m[good], c[good])
    else:
        cd = np.full(len(knots.mach), 0.5)
    start.update(zip(knots.names, cd, strict=True))
    ratio = 1.0
    if rocket.team_drag_on is not None and rocket.team_drag_off is not None:
        grid = np.linspace(0.2, 0.8, 13)
        on = np.interp(grid, *rocket.team_drag_on)
        off = np.interp(grid, *rocket.team_drag_off)
        ratio = float(np.clip(np.median(on / off), 0.5, 2.0))
    t, f, _ = rocket.motor.tables()
    weight = rocket.loaded_mass * 9.80665 * np.sin(np.radians(rocket.inclination))
    lift = t[np.argmax(f > weight)] if np.any(f > weight) else 0.0
    start.update(
        power_on_ratio=ratio,
        thrust_scale=1.0,
        burn_scale=1.0,
        cd_scale=1.0,
        motor_time=-max(float(lift), rocket.holddown),
        temperature=temperature,
        lapse_rate=STANDARD_LAPSE,
        altitude_bias=0.0,
        accel_bias=0.0,
        accel_scale=1.0,
        cn_alpha_scale=1.0,
        pitch_damping_scale=1.0,
    )
    return start


def top_speed(record, rocket) -> float:
    """m/s, the flight's top speed from the data: the integral of the axial specific
    force less gravity along the rail over the boost where the log has an
    accelerometer, else the largest climb rate of the barometric altitude (straight
    lines over 0.5 s, or over three samples where the log is coarser: at 1 Hz no
    0.5 s holds three) over the sine of the rail's inclination."""
    sin = np.sin(np.radians(rocket.inclination))
    if record.inputs.shape[1] > 2 and record.inputs[:, 2].sum() > 10:
        has = record.inputs[:, 2] > 0
        t, f = record.t[has], record.measured[has, 1]
        a = np.where(t > 0, f - 9.80665 * sin, 0.0)
        v = np.r_[0.0, np.cumsum(0.5 * (a[1:] + a[:-1]) * np.diff(t))]
        return float(np.max(v))
    has = record.inputs[:, 1] > 0
    t, h = record.t[has], record.measured[has, 0]
    best = 0.0
    step = max(1, int(0.1 / record.dt))
    span = max(0.5, 2.0 * float(np.median(np.diff(t)))) if len(t) > 1 else 0.5
    for i in range(0, len(t), step):
        w = (t >= t[i]) & (t <= t[i] + span * (1 + 1e-9))
        if w.sum() >= 3:
            best = max(best, float(np.polyfit(t[w], h[w], 1)[0]))
    return best / sin


def measured_thrust_scale(record, rocket, motor_time: float | None = None) -> float:
    """The thrust scale the accelerometer reads (an equation-error start): the
    impulse `sum m f dt` over the samples with the motor burning (specific force
    above the gravity component along the rail, mass falling with the catalogue
    impulse) over the catalogue impulse at the same samples (the motor lit so that
    it lifts off at 0, or at `motor_time`); 1 without an accelerometer. Drag makes
    it read a few per cent low; the fit takes it from there."""
    if record.inputs.shape[1] < 3 or record.inputs[:, 2].sum() < 10:
        return 1.0
    has = (record.inputs[:, 2] > 0) & (record.t > -0.05)
    t, f = record.t[has], record.measured[has, 1]
    sin = np.sin(np.radians(rocket.inclination))
    burning = f > 9.80665 * sin + 5.0
    if burning.sum() < 5:
        return 1.0
    tc, fc, burned = rocket.motor.tables()
    start = motor_time
    if start is None:
        start = default_start(rocket, DragKnots((0.1,)), 288.15)["motor_time"]
    catalogue, mass = _thrust_and_mass(rocket, (tc, fc, burned), t - start)
    dt = np.gradient(t)
    drag = start_drag(t, f, rocket)
    impulse = float(np.sum(((mass * f + drag) * dt)[burning]))
    total = float(np.sum((catalogue * dt)[burning]))
    return float(np.clip(impulse / max(total, 1e-9), 0.5, 1.5))


def _thrust_and_mass(rocket, tables, tm, stretch=1.0):
    """N and kg at motor times `tm` (s, any shape) of the motor's `tables`
    (`rocket.motor.tables()`) stretched in time by `stretch`: [`motor_at`][]'s
    thrust and the mass with the propellant burned along it, in NumPy for the
    start searches (thousands of evaluations, no tracing)."""
    tc, fc, burned = tables
    tm = tm / stretch
    thrust = np.interp(tm, tc, fc, left=0.0, right=0.0) / stretch
    mass = rocket.loaded_mass - rocket.motor.propellant_mass * np.interp(
        tm, tc, burned, left=0.0, right=1.0
    )
    return thrust, mass


def start_drag(t, f, rocket):
    """N, the drag at the accelerometer's samples `t`, `f` `(samples,)` (s, m/s^2)
    of the speed it integrates to (less gravity along the rail, from log time 0),
    sea-level-ish air and the start drag curve (the team's, else 0.5): a few per
    cent of the thrust, for the equation-error starts."""
    sin = np.sin(np.radians(rocket.inclination))
    speed = np.cumsum(np.where(t > 0, f - 9.80665 * sin, 0.0) * np.gradient(t))
    if rocket.team_drag_off is not None:
        cd = np.interp(speed / 340.0, *rocket.team_drag_off)
    else:
        cd = 0.5
    return 0.5 * 1.1 * speed**2 * rocket.area * cd


def measured_burn_scale(
    record, rocket, motor_time: float, search: float = 0.5, step: float = 0.01
) -> float:
    """The burn scale the accelerometer reads (an equation-error start): the
    stretch of the catalogue curve (0.7 to 1.5, by `step`), with a shift within
    `search` s of `motor_time`, whose thrust over the mass (propellant burned along
    the stretched curve) best fits by least squares, with a free scale and offset,
    the measured specific force plus the start drag over the mass
    ([`start_drag`][]), from half a second before the motor's start to a second
    after the longest burn. The shift is searched with it (a filtered channel's
    lag) and dropped. 1 where the accelerometer does not span the boost
    ([`accel_covers_boost`][]). On RocketPy's flights 1.00 (clean, planted, a
    thrust scale of 1.05); on Camoes 1.24, whose specific force burns 4.42 s for
    the file's 3.72. From 1 its fit stopped at 1.04 (det(R) 10560)."""
    if not accel_covers_boost(record, rocket, motor_time):
        return 1.0
    has = record.inputs[:, 2] > 0
    t, f = record.t[has], record.measured[has, 1]
    tc, fc, burned = rocket.motor.tables()
    stretches = np.arange(0.7, 1.5 + step / 2, step)
    w = (t >= motor_time - search - 0.5) & (
        t <= motor_time + search + stretches[-1] * tc[-1] + 1.0
    )
    t, f = t[w], f[w]
    drag = start_drag(t, f, rocket)
    shifts = np.arange(-search, search + step / 2, step)
    best, found = np.inf, 1.0
    for s in stretches:
        tm = t[None, :] - motor_time - shifts[:, None]  # (shifts, samples)
        thrust, mass = _thrust_and_mass(rocket, (tc, fc, burned), tm, s)
        x = thrust / mass
        y = f[None, :] + drag[None, :] / mass
        # least squares y = a x + b on each row, in closed form
        xc = x - x.mean(axis=1, keepdims=True)
        yc = y - y.mean(axis=1, keepdims=True)
        sxx = np.sum(xc**2, axis=1)
        a = np.sum(xc * yc, axis=1) / np.where(sxx > 0, sxx, 1.0)
        sse = np.mean((yc - a[:, None] * xc) ** 2, axis=1)
        if np.min(sse) < best:
            best, found = float(np.min(sse)), float(s)
    return found


def measured_motor_time(
    record, rocket, start: float, search: float = 0.5, *, filtered: bool = False
) -> float:
    """s, the log time of the thrust curve's zero that the accelerometer reads (an
    equation-error start): the shift, within `search` s of `start`, at which the
    catalogue thrust over the mass (propellant burned with the impulse) best fits
    the measured specific force by least squares with a free scale and offset, over
    the samples from the log's start to a second after the shifted burnout. The
    ignition ramp and the burnout tail are a few samples wide, so a start off by
    one ramp (a liftoff time taken from a coarse event, an ignition delay) leaves
    the output-error fit in a local minimum; this search has none to fall in.
    `start` unchanged without an accelerometer over the boost, for a `filtered`
    one (a flight computer's smoothed channel: its timing is the filter's; Camoes's
    reads 0.28 s late), or for a rocket held down after ignition (its specific
    force does not follow the thrust)."""
    if record.inputs.shape[1] < 3 or rocket.holddown > 0 or filtered:
        return start
    has = record.inputs[:, 2] > 0
    t, f = record.t[has], record.measured[has, 1]
    tc, fc, burned = rocket.motor.tables()
    if t.size < 20 or t[0] > start + tc[-1] or t[-1] < start + tc[-1]:
        return start
    step = max(float(np.min(np.diff(t))) / 4, 1e-4)
    best, shift = np.inf, start
    for s in np.arange(start - search, start + search + step / 2, step):
        w = t <= s + tc[-1] + 1.0
        thrust, mass = _thrust_and_mass(rocket, (tc, fc, burned), t[w] - s)
        x = thrust / mass
        a = np.column_stack([x, np.ones_like(x)])
        coef, *_ = np.linalg.lstsq(a, f[w], rcond=None)
        sse = float(np.mean((a @ coef - f[w]) ** 2))
        if sse < best:
            best, shift = sse, float(s)
    return shift


def ascent_end(problem) -> float:
    """s: where the ascent ends in the problem's record: the first parachute's
    deployment with a descent, else the record's end."""
    if problem.flight.descent is not None:
        return float(problem.flight.descent.deploy[0])
    return float(problem.record.t[-1])


def accel_covers_ascent(record, share: float = 0.9, end: float | None = None) -> bool:
    """Whether the accelerometer was read over the ascent (its samples spanning
    `share` of the time from liftoff to `end`, s, by default the record's end). One of two length scales
    must be trusted: the accelerometer's over a whole ascent fixes the day's
    temperature and lapse rate the barometer reads through; an accelerometer that
    stops after the boost is instead calibrated (its scale) against the barometer
    read through the day's atmosphere."""
    if record.inputs.shape[1] < 3:
        return False
    end = record.t[-1] if end is None else end  # s, the ascent's end
    t = record.t[(record.inputs[:, 2] > 0) & (record.t >= 0)]
    return t.size > 1 and (t[-1] - max(t[0], 0.0)) >= share * end


def accel_covers_boost(record, rocket, motor_time: float, after: float = 0.5) -> bool:
    """Whether the accelerometer was read over the whole burn: from the motor's
    start (or the log's liftoff, whichever is later) to `after` s past the
    catalogue's burnout, at least 20 samples between. Then the burn's length is
    estimated (`burn_scale`): the specific force shows where the thrust ends, which
    the barometer, integrating it twice into height, cannot tell from the drag."""
    if record.inputs.shape[1] < 3:
        return False
    t = record.t[record.inputs[:, 2] > 0]
    end = motor_time + rocket.motor.burn_time
    inside = (t >= max(motor_time, 0.0)) & (t <= end)
    return (
        t.size > 0
        and t[0] <= max(motor_time, 0.0) + 0.1
        and t[-1] >= end + after
        and int(inside.sum()) >= 20
    )


def knots_for(record, rocket, temperature) -> DragKnots:
    """Knots about every `KNOT_SPACING` Mach (finer with an accelerometer) from 0.1
    to the flight's top Mach (its top speed over the pad's speed of sound); beyond
    the last, `CD` is constant."""
    sound = float(np.sqrt(1.4 * 287.05287 * temperature))
    top = max(top_speed(record, rocket) / sound, 0.3)
    spacing = KNOT_SPACING[record.inputs.shape[1] > 2]
    n = max(3, int(np.round((top - 0.1) / spacing)) + 1)
    return DragKnots(tuple(float(m) for m in np.round(np.linspace(0.1, top, n), 3)))


def default_free(problem) -> tuple[str, ...]:
    """The effects [`fit_rocket`][] estimates by default besides the drag and the
    thrust. With an accelerometer: the barometer's lag and static-pressure error
    (the lag is told from the flight only against an accelerometer's independent
    kinematics), the transonic static-pressure jump on a flight whose knots reach
    Mach 1, and, where the accelerometer spans the ascent, the wind along the rail's
    heading: the drag acts on the airspeed, the barometer integrates the ground
    speed, and an accelerometer reading the drag over the whole climb tells them
    apart, if weakly (4.4-4.7 m/s standard error on RocketPy's flights). Held at
    zero, a wind the log cannot rule out goes into `CD` at low Mach, where it is a
    large share of the airspeed (RocketPy's flight with a 6.4 m/s tail wind: `CD`
    56% low at Mach 0.15, 4 bands out); estimated, `CD`'s band carries it. An
    altitude alone: the static-pressure error only, which follows the dynamic
    pressure at once (a dip at burnout, no integration; Andromeda: 53 m RMS
    without, 22 m with). With gyros (the attitude asked for): the scales of the
    normal-force slope and of the pitch damping, which the weathercocking's
    frequency and decay in the body rate carry. Where the record deploys air
    brakes, with or without an accelerometer: the CD they add fully out
    (`airbrake_cd`; held at zero, the knots took them up as a function of Mach,
    which their schedule is not). With GNSS positions (`gnss_e`, `gnss_n`): the
    wind's east and north components instead of the one along the heading, with
    or without an accelerometer (a cross wind drifts the rocket at first order)."""
    from .._vehicle._rocket._sensors import TRANSONIC_WIDTH

    gnss = GNSS_WIND_FREE if "gnss_e" in problem.outputs else ()
    if "accel" not in problem.outputs:
        brakes = AIRBRAKE_FREE if np.any(problem.record.inputs[:, 0] > 0) else ()
        return ("static_error",) + brakes + gnss
    free = SENSOR_FREE
    if problem.flight.knots.mach[-1] > 1.0 - TRANSONIC_WIDTH:
        free += ("transonic_error",)
    if gnss:
        free += gnss
    elif accel_covers_ascent(problem.record, end=ascent_end(problem)):
        free += WIND_FREE
    if "gyro" in problem.outputs:
        free += GYRO_FREE
    if np.any(problem.record.inputs[:, 0] > 0):
        free += AIRBRAKE_FREE
    return free


@dataclasses.dataclass(frozen=True)
class Problem:
    """A flight ready to fit: the rocket, its [`Flight`][] (one per problem, so
    every fit of it shares one compiled program), the ascent record, its outputs and
    the start values."""

    rocket: Rocket
    flight: Flight
    record: object
    outputs: tuple
    start: dict


def held(t, times, values):
    """`values (rows,)` at `t (samples,)` (s), each row held from its time
    `times (rows,)` to the next row's (a command log: a row `(0, 0)` before `(3.8,
    1)` means closed until 3.8 s, not opening over the boost); 0 before the first
    row and after the last, where the schedule ends (Camoes's team: closed after
    its last row, at 0.38 out)."""
    i = np.searchsorted(times, t, side="right") - 1
    out = np.asarray(values)[np.clip(i, 0, len(values) - 1)]
    return np.where((i >= 0) & (t <= times[-1]), out, 0.0)


def airbrake_input(rocket: Rocket, deployment):
    """The air brakes' input `(samples,)`, 0-1: the deployment, shaped by the
    team's table where the file gives one (the CD the brakes add at that
    deployment over the CD they add fully out, averaged over Mach), so that the
    model's `airbrake_cd` times it is the team's increment up to one scale."""
    if rocket.airbrake_table is None:
        return deployment
    levels, inc = rocket.airbrake_table
    return np.interp(deployment, levels, inc) / inc[-1]


def prepare(
    rocket: Rocket,
    log,
    *,
    knots: DragKnots | None = None,
    descent: bool = False,
    gnss: bool = False,
) -> Problem:
    """The [`Problem`][] of `rocket` flying `log`'s ascent: the record (see
    [`ascent_record`][]), the pad's pressure and temperature, the drag knots (by
    default over the flight's Mach range) and the start values. `descent`: the
    record goes on through the descent under parachutes (the barometer alone; see
    `_rocket/_descent.py`), each stage's drag area a parameter estimated with the
    drag, and the main's opening time after its event (the drogue's held at the
    rocket file's `lag_s`; see [`start_openings`][], [`estimated_openings`][])
    (the knots, motor time and thrust read from the ascent as without). `gnss`:
    the ascent's GNSS position east and north of the pad joins the outputs
    (`gnss_e`, `gnss_n`; see [`ascent_record`][]) where the log has it (not with
    `descent`); the knots and starts are read from the other channels as
    without."""
    from .._vehicle._atmosphere import isa
    from .._vehicle._rocket import pressure_altitude

    full, outputs = ascent_record(
        log, gyro=rocket.airframe is not None, gnss=gnss and not descent
    )
    # the knots and the starts read the barometer and the accelerometer
    record = without_gnss(full, outputs)
    pressure = pad_pressure(log, rocket.elevation)
    temperature = rocket.surface_temperature
    if temperature is None:
        temperature = float(isa(pressure_altitude(pressure)).temperature)
    if rocket.airbrakes is not None:
        tb, db = rocket.airbrakes
        inputs = record.inputs.copy()
        inputs[:, 0] = airbrake_input(rocket, held(record.t, tb, db))
        record = type(record)(
            record.t, inputs, record.measured, x0=record.x0, name=record.name
        )
    if knots is None:
        knots = knots_for(record, rocket, temperature)
    flight = Flight(rocket, knots, pressure)
    record = type(record)(
        record.t,
        record.inputs,
        record.measured,
        x0=flight.initial_state(),
        name=record.name,
    )
    start = default_start(rocket, knots, temperature)
    if rocket.airbrake_table is not None:
        start["airbrake_cd"] = float(rocket.airbrake_table[1][-1])
    accel = log.channels.get("accel_axial")
    start["motor_time"] = measured_motor_time(
        record,
        rocket,
        start["motor_time"],
        filtered=bool(getattr(accel, "filtered", 0)),
    )
    start["thrust_scale"] = measured_thrust_scale(record, rocket, start["motor_time"])
    start["burn_scale"] = measured_burn_scale(record, rocket, start["motor_time"])
    if len(full.inputs[0]) > len(record.inputs[0]):
        k = record.inputs.shape[1]
        record = type(record)(
            record.t,
            np.column_stack([record.inputs, full.inputs[:, k:]]),
            np.column_stack([record.measured, full.measured[:, k - 1 :]]),
            x0=record.x0,
            name=record.name,
        )
    if descent:
        from .._vehicle._rocket._descent import Descent
        from ._descent import descent_record, start_drag_areas, start_openings

        long, outputs, deploy = descent_record(
            log, rocket, gyro=rocket.airframe is not None
        )
        inputs = long.inputs.copy()
        if rocket.airbrakes is not None:
            inputs[:, 0] = airbrake_input(rocket, held(long.t, tb, db))
        record = type(long)(long.t, inputs, long.measured, x0=record.x0, name=long.name)
        flight = Flight(rocket, knots, pressure, Descent(deploy))
        start.update(start_drag_areas(rocket, record, deploy, pressure, temperature))
        start.update(start_openings(rocket, record, deploy))
    return Problem(rocket, flight, record, outputs, start)


def without_gnss(record, outputs):
    """`record` (with its `outputs`) without the GNSS columns."""
    keep = [j for j, o in enumerate(outputs) if o not in GNSS]
    if len(keep) == len(outputs):
        return record
    return type(record)(
        record.t,
        record.inputs[:, [0] + [1 + j for j in keep]],
        record.measured[:, keep],
        x0=record.x0,
        name=record.name,
    )


def altitude_only(problem: Problem) -> Problem:
    """The same flight with the barometric altitude alone (the accelerometer's
    channel dropped, and the burn scale it read: held, without it, at the
    catalogue's 1)."""
    rec = problem.record
    record = type(rec)(
        rec.t, rec.inputs[:, :2], rec.measured[:, :1], x0=rec.x0, name=rec.name
    )
    return dataclasses.replace(
        problem,
        record=record,
        outputs=problem.outputs[:1],
        start=dict(problem.start, burn_scale=1.0),
    )


def record_until(record, until: float):
    """`record` with its samples after `until` (s) missing, as a channel's gaps are:
    no flag and no reading. The length is kept (the fit shares the compiled
    program). A reading left past the cut would be a residual no parameter moves:
    it swamped R, and the fit of NDRT's first 5 s stopped where it started (its
    predicted apogee 11% low)."""
    inputs = record.inputs.copy()
    inputs[record.t > until, 1:] = 0.0
    measured = np.where(inputs[:, 1:] > 0, record.measured, 0.0)
    return type(record)(record.t, inputs, measured, x0=record.x0, name=record.name)


def fit_rocket(
    problem: Problem,
    *,
    free=None,
    until=None,
    drag: str = "knots",
    start: dict | None = None,
    shooting_interval: float = 2.0,
    hold_temperature: bool = False,
    hold: tuple[str, ...] = (),
    single: bool = True,
    throw: bool = True,
    spread: bool = True,
) -> RocketFit:
    """Fit the rocket's model to the ascent, by continuation: the start curve's
    shape scaled by one factor first (with the thrust scale, motor time and the
    accelerometer's offset and scale or the day's atmosphere), then everything asked
    for from there; the direct fit from the start too when that one fails or ends
    above the first stage's det(R); all by multiple shooting, then single shooting
    from the best of them (the penalty lets the node states absorb misfit, and a
    multiple-shooting fit can stop far above its noise). The fit of lowest det(R)
    is returned, with its result code (one still falling when its budget ran out
    says so).

    **Arguments:**

    - `problem`: from [`prepare`][].
    - `free`: effects estimated besides the drag, the thrust scale, the motor's
      start time and, with an accelerometer, its offset, the burn's length where
      it spans the boost (see [`accel_covers_boost`][]) and either the day's
      temperature and lapse rate or its scale (see [`accel_covers_ascent`][]) (names
      in the model's parameter list); by default [`default_free`][]'s.
    - `until`: s, use the log only up to this time (the model still runs to apogee;
      the record keeps its length, so the fit shares the compiled program).
    - `drag`: `"knots"` (the knots estimated) or `"scale"` (the start curve held,
      one scale factor estimated: what a short log supports).
    - `start`: start values by name, over the problem's. A value no rocket has (a
      positive effect at 0 or below, an airframe at 0 kg or less, a parachute's
      opening time below 0; see `unphysical`) raises a `LogError` naming it.
    - `shooting_interval`: s between multiple-shooting nodes (one as long as the
      record: single shooting alone).
    - `hold_temperature`: hold the pad temperature and lapse rate even with an
      accelerometer over the whole ascent (see [`accel_covers_ascent`][]).
    - `hold`: parameters otherwise estimated (the thrust scale, the motor time and
      burn scale, the
      accelerometer's offset, the day's atmosphere) held at their start values: what
      a diagnosis tests as absent.
    - `single`: follow the multiple-shooting tries by single shooting from the
      best of them (the lower det(R) kept).
    - `throw`: raise on a failed fit (else the fit carries its result code).
    - `spread`: with two sensors, measure their disagreement over the drag knots
      ([`structural_spread`][]: each sensor's own converged fit from the joint
      one; not at a joint fit that did not converge) and carry it in `CD`'s band;
      `False`: the noise's band alone, without the sensors' own fits.

    **Returns:** a [`RocketFit`][].
    """
    values = dict(problem.start)
    values.update(start or {})
    free = default_free(problem) if free is None else tuple(free)
    unknown = [f for f in free if f not in values]
    if unknown:
        raise LogError(f"unknown effect(s) {unknown}; effects are {', '.join(EFFECTS)}")
    knots = problem.flight.knots
    if drag not in ("knots", "scale"):
        raise ValueError(f"drag must be 'knots' or 'scale', got {drag!r}")
    record = problem.record
    if until is not None:
        record = record_until(record, until)
    extras = ()
    if "accel" in problem.outputs:
        extras += ("accel_bias",)
        if accel_covers_boost(record, problem.rocket, values["motor_time"]):
            extras += BURN_FREE
        if not accel_covers_ascent(problem.record, end=ascent_end(problem)):
            extras += ("accel_scale",) if "accel_scale" not in free else ()
        elif not hold_temperature:
            extras += tuple(a for a in ACCEL_FREE if a not in free)
    if problem.flight.descent is not None:
        from ._descent import estimated_openings

        descent = problem.flight.descent
        extras += descent.names + estimated_openings(descent)
    base = tuple(n for n in BASE_FREE + extras if n not in hold)
    scaled = ("cd_scale",) + base
    estimated = knots.names + base if drag == "knots" else scaled
    estimated += tuple(f for f in free if f not in base)

    if problem.rocket.airframe is None:
        tried, flown = _tries(
            problem, record, values, scaled, estimated, free, shooting_interval, single
        )
    else:
        tried, flown = _attitude_tries(
            problem, record, values, scaled, estimated, free, shooting_interval, single
        )
    # the lowest det(R) flown from the pad, converged or not: a fit still creeping
    # down a valley when its budget ran out lies below one that converged in
    # another basin (a simulated clean flight: 0.029 unconverged against 1.11
    # converged), and its result code says it did not converge. At a tie the
    # converged one: single shooting from a multiple-shooting fit stopped against a
    # bound moves nothing (every step crosses it), and the multiple-shooting fit
    # before it, the same parameters, ends singular where its nodes take up what the
    # bounded parameter moves (a main's opening within the seconds left out after
    # its event), so that the stop against the bound went unreported
    label = min(tried, key=lambda k: (flown[k], not tried[k].converged))
    result = against_bound(problem.flight, tried[label])
    if throw and not result.converged:
        raise RuntimeError(result.reason)
    from ._spread import structural_spread

    fitted = dataclasses.replace(
        trajectory(problem.rocket, problem.flight, result, record, problem.outputs),
        tries={
            k: (float(f.cost), float(flown[k]), bool(f.converged))
            for k, f in tried.items()
        },
    )
    if not spread or drag != "knots" or not np.isfinite(result.cost):
        return fitted
    return dataclasses.replace(fitted, spread=structural_spread(fitted))


def against_bound(flight: Flight, result: Fit) -> Fit:
    """`result`, or, where it converged against a bound (its Gauss-Newton step from
    the point it stopped at leaves the rocket's physical region: every step past
    the bound was rejected, see `_vehicle/_rocket/_model.py`), the same fit marked
    `nonfinite` with one line naming the effect, where it stopped and where the
    data would take it, where it stopped within its standard error of the bound.
    A fit at an interior optimum has a step of nearly zero, and one further from
    the bound than its standard error is returned unchanged."""
    import equinox as eqx
    import jax.numpy as jnp

    from .._estimate._engine import lm_step, RESULTS
    from .._vehicle._rocket._model import unphysical

    lin = getattr(result, "linearisation", None)  # None: a fit by another solver
    if lin is None or not result.converged:
        return result
    model = result.model
    nx, p = len(model.states), len(model.parameters)
    free = result.layout.free_columns(jnp.asarray(model.free), nx, p)
    step = np.asarray(lm_step(lin.normal, lin.gradient, free, 0.0))
    ns = result.nodes.size
    here = dict(zip(model.parameters, result.params, strict=True))
    there = dict(zip(model.parameters, result.params + step[ns : ns + p], strict=True))
    why = unphysical(flight, there)
    if not why or unphysical(flight, here):
        return result
    name = why.split(" ", 1)[0]
    # an ill-conditioned direction can carry the step of a fit well inside the
    # region across the bound: it is a stop against the bound only where the
    # parameter is within its standard error of it (the data cannot tell them)
    i = model.parameters.index(name)
    inside, outside = 0.0, 1.0
    for _ in range(50):
        mid = 0.5 * (inside + outside)
        trial = dict(here, **{name: here[name] + mid * (there[name] - here[name])})
        inside, outside = (inside, mid) if unphysical(flight, trial) else (mid, outside)
    distance = abs(inside * (there[name] - here[name]))
    if not distance < float(result.stderr_corrected[i]):
        return result
    reason = (
        f"{name} stopped against its bound at {here[name]:.3g}: the data would "
        f"take it to {there[name]:.3g} ({why}); check the log's channels (a sign, "
        "a unit) or hold it"
    )
    return eqx.tree_at(
        lambda f: (f.result, f.reason), result, (RESULTS.nonfinite, reason)
    )


def flown_cost(problem: Problem, record, result) -> float:
    """det(R) of `result`'s parameters flown from the pad (one segment over
    `record`, RK4 at its step): the measure the fits [`fit_rocket`][] tries are
    compared on. A multiple-shooting fit's own det(R) is that of segments restarted
    at estimated node states, which take up misfit that its parameters, flown from
    the pad, leave; compared on their own det(R), multiple shooting looks better
    than it flies. `inf` for a try that failed (not finite)."""
    if not np.isfinite(result.cost):
        return np.inf
    t, x, inputs = _flown(result.model, result.params, record)
    ys = np.asarray(
        _observed(problem.flight, t, x, inputs, result.params, result.model.parameters)
    )[:, observed_columns(problem.outputs)]
    n = len(record.t)
    has = record.inputs[:, 1:] > 0
    e = np.where(has, record.measured - ys[:n], 0.0)
    # as the engine's R: mean square over the record's samples, per channel
    cost = float(np.prod(np.sum(e**2, axis=0) / n))
    return cost if np.isfinite(cost) else np.inf


def _tries(
    problem, record, values, scaled, estimated, free, interval, single_try=True
) -> dict:
    """The fits [`fit_rocket`][] chooses from, by label, and each one's det(R)
    flown from the pad ([`flown_cost`][]), by label: the continuation by multiple
    shooting (nodes every `interval` s), then single shooting (one segment from the
    pad) from the best of those flown, to the constrained optimum in the basin
    multiple shooting found (none when one segment already spans the record)."""
    knots = problem.flight.knots
    single = float(record.t[-1] - record.t[0]) + 1.0

    def run(start_values, names, every):
        model = rocket_model(problem.flight, problem.outputs, start_values, names)
        return fit(
            model,
            record,
            # the penalty's optimum: the single-shooting try is the constrained one
            shooting=MultipleShooting(interval=every, settle=None),
            initial_state="fixed",
            throw=False,
        )

    # continuation: the start curve's shape scaled by one factor first (few
    # parameters, a basin as wide as the start is poor), then everything asked for
    # from there; the direct fit from the start too when that one fails or ends
    # above the first stage's cost (its parameters are a subset, so it cannot be
    # the better optimum)
    label = "multiple" if interval < single else "single"
    first = run(values, scaled, interval)
    if estimated == scaled:
        tried = {label: first}
    else:
        tried = {}
        if first.converged:
            named = dict(zip(first.model.parameters, first.params, strict=True))
            for k in knots.names:
                named[k] = named[k] * named["cd_scale"]
            named["cd_scale"] = 1.0
            # sensors and effects that the first stage held start where asked
            named.update({k: values[k] for k in free})
            tried[f"{label} continued"] = run(named, estimated, interval)
        last = tried.get(f"{label} continued")
        if last is None or not last.converged or last.cost > first.cost:
            tried[f"{label} direct"] = run(values, estimated, interval)
    # the penalty lets the node states absorb misfit, so a multiple-shooting fit
    # can stop far above its noise (a simulated flight with 5% more thrust: det(R)
    # 28.5); single shooting from there reaches the constrained optimum (0.021),
    # the one single shooting from the start reaches too, in a fraction of its time
    flown = {k: flown_cost(problem, record, f) for k, f in tried.items()}
    best = min(tried, key=lambda k: flown[k])
    if single_try and interval < single and np.isfinite(flown[best]):
        fitted = tried[best]
        named = dict(zip(fitted.model.parameters, fitted.params, strict=True))
        tried["single from multiple"] = run(named, estimated, single)
        flown["single from multiple"] = flown_cost(
            problem, record, tried["single from multiple"]
        )
    return tried, flown


# one point-mass Flight per attitude Flight: every fit of one flight shares the
# point mass's compiled program as it shares the attitude's
_POINT_MASS: dict = {}


def point_mass(problem: Problem, record=None) -> tuple[Problem, object]:
    """`problem` (and `record`, by default its own) without the attitude: the rocket
    pointing along its air-relative velocity, the gyro channel dropped."""
    record = problem.record if record is None else record
    keep = [o for o in problem.outputs if o != "gyro"]
    cols = [0] + [1 + problem.outputs.index(o) for o in keep]

    def strip(rec):
        return type(rec)(
            rec.t,
            rec.inputs[:, cols],
            rec.measured[:, [problem.outputs.index(o) for o in keep]],
            x0=rec.x0[:6],
            name=rec.name,
        )

    key = id(problem.flight)
    if key not in _POINT_MASS or _POINT_MASS[key][0] is not problem.flight:
        rocket = dataclasses.replace(problem.rocket, airframe=None)
        _POINT_MASS[key] = (
            problem.flight,
            Flight(
                rocket,
                problem.flight.knots,
                problem.flight.pad_pressure,
                problem.flight.descent,
            ),
        )
    flight = _POINT_MASS[key][1]
    simple = dataclasses.replace(
        problem,
        rocket=flight.rocket,
        flight=flight,
        record=strip(problem.record),
        outputs=tuple(keep),
    )
    return simple, strip(record)


def _attitude_tries(
    problem, record, values, scaled, estimated, free, interval, single_try=True
):
    """[`_tries`][] for a rocket with the attitude: the point mass's continuation
    and single shooting first (its program, a fraction of the attitude's cost per
    iteration), then the attitude by single shooting from its optimum (the
    attitude's own states start from the pad, so no node holds them). With nodes,
    the attitude's fit crept: on a simulated flight det(R) fell by 6e-5 of itself
    per full Gauss-Newton step for over 100 steps. Where that single-shooting fit
    fails, the attitude's own continuation by multiple shooting as before."""
    simple, simple_record = point_mass(problem, record)
    attitude_only = set(GYRO_FREE)
    tried_pm, flown_pm = _tries(
        simple,
        simple_record,
        values,
        tuple(n for n in scaled if n not in attitude_only),
        tuple(n for n in estimated if n not in attitude_only),
        tuple(n for n in free if n not in attitude_only),
        interval,
        single_try,
    )
    best = min(tried_pm, key=lambda k: flown_pm[k])
    tried, flown = {}, {}
    if np.isfinite(flown_pm[best]):
        pm = tried_pm[best]
        named = dict(zip(pm.model.parameters, pm.params, strict=True))
        named.update({k: values[k] for k in GYRO_FREE})
        model = rocket_model(problem.flight, problem.outputs, named, estimated)
        label = f"attitude from point mass {best}"
        length = float(record.t[-1] - record.t[0]) + 1.0
        tried[label] = fit(
            model,
            record,
            shooting=MultipleShooting(interval=length, settle=None),
            initial_state="fixed",
            throw=False,
            # the valley from the point mass's optimum bends: the wind with the
            # drag and the day's atmosphere; the straight step's cost rose 200-fold
            # and the damping cut it to 1% of the way (166 steps on `clean`, 40
            # with the acceleration)
            acceleration=True,
        )
        flown[label] = flown_cost(problem, record, tried[label])
        if tried[label].converged and np.isfinite(flown[label]):
            return tried, flown
    more, more_flown = _tries(
        problem, record, values, scaled, estimated, free, interval, single_try
    )
    return {**tried, **more}, {**flown, **more_flown}


def simulate_flight(problem: Problem, start: dict | None = None) -> RocketFit:
    """The flight simulated (not fitted) from the pad with the problem's start values
    (the team's drag curve, catalogue thrust) or `start` over them; `fit` is `None`."""
    values = dict(problem.start)
    values.update(start or {})
    model = rocket_model(problem.flight, problem.outputs, values, ())
    return trajectory(
        problem.rocket,
        problem.flight,
        None,
        problem.record,
        problem.outputs,
        model=model,
        params=np.asarray(model.start),
    )


def trajectory(
    rocket, flight, result, record, outputs, extra=30.0, *, model=None, params=None
) -> RocketFit:
    """The fitted flight integrated from the pad past the apogee (`extra` s beyond
    the record, stopped at the top), with its barometric altitude, axial specific
    force and Mach number."""
    model = result.model if model is None else model
    params = result.params if params is None else params
    t, x, inputs = _flown(model, params, record, extra)
    dt = record.dt
    ys = np.asarray(_observed(flight, t, x, inputs, params, model.parameters))
    baro, accel, mach = ys[:, 0], ys[:, 1], ys[:, 2]
    cut = int(apogee_cut(t, x[:, 5], dt))
    peak = int(np.argmax(baro[:cut]))
    return RocketFit(
        rocket=rocket,
        flight=flight,
        fit=result,
        record=record,
        outputs=outputs,
        t=t[:cut],
        states=x[:cut],
        baro=baro[:cut],
        accel=accel[:cut],
        mach=mach[:cut],
        apogee=float(baro[peak]),
        apogee_time=float(t[peak]),
    )


def apogee_cut(t, climb, dt: float):
    """How many samples the flown apogee is sought in: up to a second (rounded to
    samples of `dt` s) after the climb rate `climb` (m/s, `(samples,)` at the times
    `t`) first falls to zero or below past t = 1 s; all of them where it never
    does. NumPy or JAX arrays; a JAX integer (traceable, so the apogee's gradient
    shares it)."""
    import jax.numpy as jnp

    n = climb.shape[0]
    falling = (climb <= 0) & (t > 1.0)
    top = jnp.where(jnp.any(falling), jnp.argmax(falling), n - 1)
    return jnp.minimum(n, top + int(round(1.0 / dt)))


def _flown(model, params, record, extra=30.0):
    """`(t, states, inputs)` of `model` flown with `params` from the record's start
    over the record and `extra` s beyond it (every channel flagged), RK4 at the
    record's step."""
    t, inputs, long = _long_record(record, extra)
    return t, simulate(model, long, params), inputs


def _long_record(record, extra):
    """`(t, inputs, record)`: `record` over its span and `extra` s beyond it at its
    step, every channel flagged, no readings (what the flight is flown over)."""
    from .._model import Record

    dt = record.dt
    n = len(record.t) + int(extra / dt)
    t = record.t[0] + dt * np.arange(n)
    inputs = np.zeros((n, record.inputs.shape[1]))
    inputs[:, 0] = np.interp(t, record.t, record.inputs[:, 0], right=0.0)
    inputs[:, 1:] = 1.0
    long = Record(t, inputs, np.zeros((n, inputs.shape[1] - 1)), x0=record.x0)
    return t, inputs, long


_OBSERVED: dict = {}
# each output's column in what `_observed` returns
_COLUMNS = {"altitude": 0, "accel": 1, "gyro": 3, "gnss_e": 4, "gnss_n": 5}


def observed_columns(outputs) -> list[int]:
    """The columns of `_observed`'s return that hold `outputs` (names), in order."""
    return [_COLUMNS[o] for o in outputs]


def _observed(flight, t, x, u, params, names):
    """`(samples, 6)`: barometric altitude, axial specific force, Mach, the
    lateral body rate (0 without the attitude) and the position east and north of
    the pad (one compiled program per flight)."""
    import jax
    import jax.numpy as jnp

    key = (id(flight), names)
    if key not in _OBSERVED or _OBSERVED[key][0] is not flight:

        def one(t, x, u, params):
            p = dict(zip(names, params, strict=True))
            _, _, air = flight.forces(t, x, u, p)
            y = _observe(flight, t, x, jnp.stack([u[0], 1.0, 1.0, 1.0]), p)
            return jnp.stack([y[0], y[1], air[3], y[2], x[0], x[1]])

        _OBSERVED[key] = (flight, jax.jit(jax.vmap(one, (0, 0, 0, None))))
    fn = _OBSERVED[key][1]
    return fn(jnp.asarray(t), jnp.asarray(x), jnp.asarray(u), jnp.asarray(params))
