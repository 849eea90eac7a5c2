"""A rocket log's descent under parachutes: when each stage opened, where the record
ends, the drag areas and opening times to start from, and what the fit says about them.

The record past apogee holds the barometer alone (the accelerometer and the gyros
read the deployment shocks and the tumbling under the canopy, which the point mass
does not model), and not for `SETTLE` s after each deployment (ejection charges
pressurise the bay, and the canopy's filling and the air it carries along are not
modelled; the time it takes to open is, a parameter). It ends two seconds before the log's landing event, else where the
barometer first reads below `GROUND` m above the pad (a log lying on the ground is
not falling), else at the log's end. Its grid step is `MAX_STEP` (20 Hz, each
channel's samples averaged into it): a descent of minutes at a flight computer's
100 Hz would be tens of thousands of steps.
"""

import numpy as np

from .._errors import LogError
from .._vehicle._atmosphere import G0, R_AIR
from ._data import apogee_time, ascent_record, baro_channel, MAX_STEP


GROUND = 30.0  # m above the pad: below this the record ends
LANDING_MARGIN = 2.0  # s before a landing event
SETTLE = 3.0  # s after a deployment before a stage's fall rate is read
# s: the least opening time an estimated one starts from (one step of the 20 Hz
# grid). The bound at 0 rejects every step that takes it below: from 0 itself,
# where the data would take it below, every step the damping shortens still does,
# and the fit stops where it started, every parameter at its start.
OPEN_FLOOR = 0.05


def deployments(log, rocket) -> tuple[float, ...]:
    """s, log time each parachute stage opened: the drogue at the log's `drogue`
    event, else at apogee ([`apogee_time`][]); the main at the log's `main` event,
    else, where the rocket file gives the main's deployment height, at the first
    barometer sample below it after the drogue."""
    drogue = float(log.events["drogue"].t) if "drogue" in log.events else None
    if drogue is None:
        drogue = apogee_time(log)
    main, why = None, ""
    if "main" in log.events:
        main, why = float(log.events["main"].t), "the log's main event"
    else:
        heights = [h for _, h in rocket.parachutes[1:] if h is not None]
        if heights:
            t, h = baro_channel(log)
            below = np.flatnonzero((t > drogue) & (h < heights[0]))
            if below.size:
                main = float(t[below[0]])
                why = (
                    f"the rocket file's [[parachutes]] entry 2 "
                    f"trigger_altitude_agl_m = {heights[0]:g}"
                )
    if main is None:
        return (drogue,)
    if main < drogue + 2 * SETTLE:
        files = ", ".join(f.name for f in log.files)
        raise LogError(
            f"{files}: the main parachute opens at {main:.2f} s ({why}), "
            f"{main - drogue:.2f} s after the drogue at {drogue:.2f} s: a stage "
            f"needs {2 * SETTLE:g} s of its own fall for its drag area"
        )
    return (drogue, main)


def descent_end(log, drogue: float) -> float:
    """s: where the descent's record ends (see the module docstring)."""
    t, h = baro_channel(log)
    end = float(t[-1])
    if "landing" in log.events:
        end = min(end, float(log.events["landing"].t) - LANDING_MARGIN)
    low = np.flatnonzero((t > drogue) & (h < GROUND))
    if low.size:
        end = min(end, float(t[low[0]]))
    return end


def descent_record(log, rocket, gyro: bool = False):
    """`(record, outputs, deploy)`: the record from just before liftoff to the
    descent's end (see [`ascent_record`][]), the accelerometer and gyros dropped
    from the first deployment on, and the deployment times (s)."""
    deploy = deployments(log, rocket)
    end = descent_end(log, deploy[0])
    if end < deploy[0] + 2 * SETTLE:
        files = ", ".join(f.name for f in log.files)
        raise LogError(
            f"{files}: the log has {max(end - deploy[0], 0.0):.1f} s of descent "
            f"after the drogue at {deploy[0]:.1f} s: too little for its drag area"
        )
    record, outputs = ascent_record(log, until=end, gyro=gyro, step=MAX_STEP)
    inputs = record.inputs.copy()
    inputs[record.t >= deploy[0], 2:] = 0.0
    for when in deploy:
        inputs[(record.t >= when) & (record.t < when + SETTLE), 1] = 0.0
    measured = np.where(inputs[:, 1:] > 0, record.measured, 0.0)
    record = type(record)(record.t, inputs, measured, x0=record.x0, name=record.name)
    return record, outputs, deploy


def fall_rates(t, h, has, deploy) -> list[float]:
    """m/s per stage: the median fall rate of altitudes `h` (m) at times `t` (s)
    where `has`, from `SETTLE` s after the stage opens to the next stage (or the
    end), a line through each second of samples; `nan` for a stage under two
    seconds long."""
    ends = tuple(deploy[1:]) + (float(t[-1]),)
    out = []
    for start, stop in zip(deploy, ends, strict=True):
        edges = np.arange(start + SETTLE, stop - 1.0, 1.0)
        rates = []
        for a in edges:
            m = has & (t >= a) & (t < a + 1.0)
            if m.sum() > 2:
                rates.append(-np.polyfit(t[m], h[m], 1)[0])
        out.append(float(np.median(rates)) if len(rates) >= 2 else np.nan)
    return out


def start_drag_areas(rocket, record, deploy, pad_pressure, temperature) -> dict:
    """m^2 per stage: the rocket file's CdS where it gives one, else the one whose
    terminal velocity is the log's fall rate ([`fall_rates`][]) at the stage's
    median height in the standard atmosphere through the pad's pressure and
    temperature."""
    from .._vehicle._rocket._descent import drag_area_for_rate, STAGE_NAMES
    from .._vehicle._rocket._sensors import layered_air

    t, h = record.t, record.measured[:, 0]
    rates = fall_rates(t, h, record.inputs[:, 1] > 0, deploy)
    ends = tuple(deploy[1:]) + (float(t[-1]),)
    out = {}
    for k, (start, stop) in enumerate(zip(deploy, ends, strict=True)):
        name = STAGE_NAMES[k]
        given = rocket.parachutes[k][0] if k < len(rocket.parachutes) else None
        if given is not None:
            out[name] = float(given)
            continue
        m = (t >= start) & (t <= stop) & (record.inputs[:, 1] > 0)
        height = float(np.median(h[m])) if m.any() else 0.0
        p, temp, _, _ = layered_air(pad_pressure, temperature, -6.5, height)
        rho = float(p / (R_AIR * temp))
        rate = rates[k] if np.isfinite(rates[k]) else (20.0 if k == 0 else 6.0)
        out[name] = float(drag_area_for_rate(rocket.dry_mass, G0, rho, rate))
    return out


def start_openings(rocket, record, deploy) -> dict:
    """s per stage: each canopy's opening time after its event to start from. The
    drogue's is the rocket file's `lag_s` (0 without; held). A later stage's is
    read from the log where it can be: the height lost over the `SETTLE` s left
    out after the event (a line through the barometer's 2.5 s before the event's
    last half second, and one through its 2 s after, each read at its end: an
    ejection charge can disturb the reading around the event), fallen at the
    earlier stage's rate until the canopy opened and at its own after
    ([`fall_rates`][]): `(drop - v_own SETTLE) / (v_before - v_own)`, within 0 to
    `SETTLE` s (a fit started from an opening inside the seconds left out, far
    from the log's, can stop where the drag area takes the drop instead). Else the
    file's `lag_s`, else 0. A later stage's (estimated, [`estimated_openings`][])
    starts at `OPEN_FLOOR` at least: inside the bound at 0, not on it."""
    from .._vehicle._rocket._descent import OPEN_NAMES

    lags = tuple(rocket.parachute_lags) + (None,) * len(deploy)
    out = {
        OPEN_NAMES[k]: 0.0 if lags[k] is None else float(lags[k])
        for k in range(len(deploy))
    }
    t, h = record.t, record.measured[:, 0]
    for k in range(len(deploy)):
        # a held opening past the next event or the log's end (ms for s?) would
        # leave that canopy shut through the fit, silently
        end = deploy[k + 1] if k + 1 < len(deploy) else float(t[-1])
        if lags[k] is not None and deploy[k] + lags[k] >= end:
            raise LogError(
                f"[[parachutes]] {k + 1}: lag_s = {lags[k]:g} s opens the canopy at "
                f"{deploy[k] + lags[k]:.2f} s, after "
                + ("the next parachute's event" if k + 1 < len(deploy) else "the log")
                + f" ({end:.2f} s): a lag in seconds, shorter than that"
            )
    has = record.inputs[:, 1] > 0
    rates = fall_rates(t, h, has, deploy)
    for k in range(1, len(deploy)):
        event, settled = deploy[k], deploy[k] + SETTLE
        before = has & (t >= event - 3.0) & (t < event - 0.5)
        after = has & (t >= settled) & (t < settled + 2.0)
        v0, v1 = rates[k - 1], rates[k]
        if before.sum() < 3 or after.sum() < 3 or not v0 > v1:  # nan too
            continue
        drop = np.polyval(np.polyfit(t[before], h[before], 1), event) - np.polyval(
            np.polyfit(t[after], h[after], 1), settled
        )
        lag = (drop - v1 * SETTLE) / (v0 - v1)
        out[OPEN_NAMES[k]] = float(np.clip(lag, 0.0, SETTLE))
    for k in range(1, len(deploy)):
        out[OPEN_NAMES[k]] = max(out[OPEN_NAMES[k]], OPEN_FLOOR)
    return out


def estimated_openings(descent) -> tuple[str, ...]:
    """The opening times a descent's fit estimates: the main's, whose lag the
    rocket keeps falling at the drogue's rate (a second of it moves every later
    height by the difference of the two fall rates, about 20 m); not the drogue's,
    opening at apogee where the rocket moves at a few m/s (held at its start,
    [`start_openings`][])."""
    return descent.openings[1:]
