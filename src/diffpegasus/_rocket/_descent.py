"""A rocket log's descent under parachutes: when each stage opened, where the record
ends, the drag areas to start from, and what the fit says about them.

The record past apogee holds the barometer alone (the accelerometer and the gyros
read the deployment shocks and the tumbling under the canopy, which the point mass
does not model), and not for `SETTLE` s after each deployment (ejection charges
pressurise the bay, and the canopy's inflation and the air it carries along are
not modelled). It ends two seconds before the log's landing event, else where the
barometer first reads below `GROUND` m above the pad (a log lying on the ground is
not falling), else at the log's end. Its grid step is `MAX_STEP` (20 Hz, each
channel's samples averaged into it): a descent of minutes at a flight computer's
100 Hz would be tens of thousands of steps.
"""

import pathlib

import numpy as np

from .._errors import LogError
from .._vehicle._atmosphere import G0, R_AIR
from ._data import apogee_time, ascent_record, baro_channel, MAX_STEP


GROUND = 30.0  # m above the pad: below this the record ends
LANDING_MARGIN = 2.0  # s before a landing event
SETTLE = 3.0  # s after a deployment before a stage's fall rate is read


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


def descent_table(problem, result) -> list[dict]:
    """One row per stage: `stage`, `deploy_s`, `cds_m2` and its standard error
    (the fit's), `cds_rocket_file_m2` (or `None`), `fall_rate_log_m_s` (the
    barometer's, [`fall_rates`][]) and `fall_rate_model_m_s` (the fitted model's
    over the same seconds)."""
    descent = problem.flight.descent
    t, baro = descent_trajectory(problem, result)
    rec = problem.record
    has = rec.inputs[:, 1] > 0
    log_rates = fall_rates(rec.t, rec.measured[:, 0], has, descent.deploy)
    model_rates = fall_rates(t, baro, has, descent.deploy)
    rows = []
    for k, name in enumerate(descent.names):
        value, stderr = result.estimate(name)
        given = (
            problem.rocket.parachutes[k][0]
            if k < len(problem.rocket.parachutes)
            else None
        )
        rows.append(
            {
                "stage": name.removeprefix("cds_"),
                "deploy_s": float(descent.deploy[k]),
                "cds_m2": float(value),
                "cds_stderr_m2": float(stderr),
                "cds_rocket_file_m2": given,
                "fall_rate_log_m_s": log_rates[k],
                "fall_rate_model_m_s": model_rates[k],
            }
        )
    return rows


def descent_trajectory(problem, result):
    """`(t (samples,) s, barometric altitude (samples,) m)`: the fitted model
    flown from the pad over the whole record (through the descent)."""
    from ._identify import _flown, _observed

    model, params = result.fit.model, result.fit.params
    t, x, inputs = _flown(model, params, problem.record, extra=0.0)
    ys = np.asarray(_observed(problem.flight, t, x, inputs, params, model.parameters))
    n = len(problem.record.t)
    return t[:n], ys[:n, 0]


def descent_figure(problem, result, path) -> pathlib.Path:
    """A PNG at `path`: the barometric altitude logged and fitted through the
    descent (m above the pad against s), each deployment marked, and the residual
    below."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, model = descent_trajectory(problem, result)
    rec = problem.record
    has = rec.inputs[:, 1] > 0
    fig, (ax, res) = plt.subplots(
        2, 1, figsize=(8, 6), sharex=True, gridspec_kw={"height_ratios": [3, 1]}
    )
    ax.plot(rec.t[has], rec.measured[has, 0], ".", ms=2, label="log (barometer)")
    ax.plot(t, model, "-", lw=1.2, label="model")
    for k, (name, when) in enumerate(
        zip(problem.flight.descent.names, problem.flight.descent.deploy, strict=True)
    ):
        value, stderr = result.estimate(name)
        label = (
            f"{name.removeprefix('cds_')} at {when:.1f} s: "
            f"CdS {value:.4g} +/- {stderr:.2g} m$^2$"
        )
        for a in (ax, res):
            a.axvline(when, color=f"C{k + 2}", ls="--", lw=0.8)
        ax.plot([], [], color=f"C{k + 2}", ls="--", lw=0.8, label=label)
    ax.set_ylabel("altitude above the pad (m)")
    ax.legend(loc="upper right", fontsize=8)
    res.plot(rec.t[has], rec.measured[has, 0] - model[has], ".", ms=2)
    res.set_ylabel("log - model (m)")
    res.set_xlabel("time since liftoff (s)")
    fig.tight_layout()
    path = pathlib.Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
