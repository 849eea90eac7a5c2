"""A rocket log's ascent as a [`Record`][] on one uniform grid.

Channels keep their own rates in the log; the record's grid is the fastest of them
(between 20 and 100 Hz), each channel's samples are averaged into the grid step they
fall in, and an input `has_<channel>` is 1 at the steps that hold a sample and 0
elsewhere, so the model's output there is 0 like the record's (no residual). Slow,
sparse or interrupted channels (a 2 Hz tail, telemetry dropouts, an accelerometer
that stops after the boost) so enter the fit only where they were measured.
"""

import numpy as np

from .._errors import LogError
from .._model import Record


MIN_STEP, MAX_STEP = 0.01, 0.05  # s: 100 Hz, 20 Hz


def channels_of(log, gyro: bool = False) -> tuple[str, ...]:
    """The model outputs the log can feed: `altitude` (barometric, or from pressure)
    and `accel` (axial specific force), in the model's order; with `gyro` (the
    attitude asked for) and an accelerometer, `gyro` too where the log has the
    lateral body rate (see [`lateral_rate`][])."""
    if "altitude" not in log.channels and "pressure" not in log.channels:
        raise LogError(
            "the log has no barometric altitude or pressure: a rocket fit needs one"
        )
    out = ("altitude",)
    if "accel_axial" in log.channels:
        out += ("accel",)
        if gyro and lateral_rate(log) is not None:
            out += ("gyro",)
    return out


def lateral_rate(log):
    """`(t, rad/s)`: the body rate across the rocket's axis, `sqrt(w1^2 + w2^2)` of
    the two gyros across it (whatever the roll), or `None`. From a `gyro_lateral`
    channel, else from `gyro_x/y/z` with the axial one the axis whose accelerometer
    the log's `accel_axial` is (the one reading most along the boost)."""
    ch = log.channels
    if "gyro_lateral" in ch:
        return ch["gyro_lateral"].t, ch["gyro_lateral"].values
    names = ("x", "y", "z")
    if not all(f"gyro_{a}" in ch for a in names) or "accel_axial" not in ch:
        return None
    axial = ch["accel_axial"]
    along = None
    for a in names:
        c = ch.get(f"accel_{a}")
        if c is not None and len(c.t) == len(axial.t):
            if np.allclose(np.abs(c.values), np.abs(axial.values), equal_nan=True):
                along = a
    if along is None:
        return None
    across = [ch[f"gyro_{a}"] for a in names if a != along]
    if len(across[0].t) != len(across[1].t):
        return None
    return across[0].t, np.hypot(across[0].values, across[1].values)


def baro_channel(log):
    """`(t, altitude m AGL)`: the log's raw pressure as standard-atmosphere altitude
    above the pad where it has pressure (unfiltered), else its altitude channel."""
    from .._vehicle._rocket import pressure_altitude

    if "pressure" in log.channels:
        c = log.channels["pressure"]
        pad = pad_pressure(log)
        return c.t, pressure_altitude(c.values) - pressure_altitude(pad)
    c = log.channels["altitude"]
    return c.t, c.values


def logged_apogee(log) -> float:
    """m AGL: the highest barometric altitude after liftoff, before the record's
    first fall faster than free fall or pulse (an ejection charge's pressure pulse,
    which may read above the top: see the apogee event)."""
    from .._log._rocket_events import top_end

    t, h = baro_channel(log)
    up = t > 0
    end = top_end(t, h, 0.0)
    if end is not None and np.any(up[:end]):
        up = up & (np.arange(len(t)) < end)
    return float(np.max(h[up]))


def pad_pressure(log, elevation=0.0) -> float:
    """Pa at the pad: the log's pre-liftoff pressure, else the standard
    atmosphere's at the pad elevation."""
    from .._vehicle._atmosphere import isa

    if "pressure" in getattr(log, "pad", {}):
        return float(log.pad["pressure"])
    if "pressure" in log.channels:
        c = log.channels["pressure"]
        before = c.values[c.t <= 0]
        return float(np.median(before if before.size else c.values[:5]))
    return float(isa(elevation).pressure)


def apogee_time(log) -> float:
    """s: the log's apogee event, else the time of the highest altitude."""
    if "apogee" in log.events:
        return float(log.events["apogee"].t)
    t, h = baro_channel(log)
    return float(t[np.argmax(h)])


def ascent_record(
    log, until=None, name="flight", gyro: bool = False, step: float = MIN_STEP
) -> tuple[Record, tuple[str, ...]]:
    """The record of the ascent from just before liftoff to `until` (default the
    apogee), and its output names (`gyro`: the lateral body rate where the log has
    it, for the attitude; `step`: s, the shortest grid step allowed).

    **Returns:** `(record, outputs)`; the record's inputs are `airbrake` (0 here,
    filled by the caller where the rocket has air brakes) and `has_<output>`.
    """
    outputs = channels_of(log, gyro)
    end = apogee_time(log) if until is None else float(until)
    series = {"altitude": baro_channel(log)}
    if "accel" in outputs:
        c = log.channels["accel_axial"]
        series["accel"] = (c.t, c.values)
    if "gyro" in outputs:
        series["gyro"] = lateral_rate(log)
    steps = []
    for t, _ in series.values():
        inside = t[(t > -1.0) & (t <= end)]
        if inside.size > 2:
            steps.append(float(np.median(np.diff(inside))))
    if not steps:
        raise LogError("the log has no samples between liftoff and apogee")
    dt = float(np.clip(min(steps), max(MIN_STEP, step), MAX_STEP))
    first = min(-0.3, min(float(t[t > -1.0][0]) for t, _ in series.values()))
    n = int(np.floor((end - first) / dt)) + 1
    grid = first + dt * np.arange(n)
    measured = np.zeros((n, len(outputs)))
    has = np.zeros((n, len(outputs)))
    for j, name_ in enumerate(outputs):
        t, v = series[name_]
        keep = (t >= grid[0] - dt / 2) & (t < grid[-1] + dt / 2) & np.isfinite(v)
        k = np.rint((t[keep] - grid[0]) / dt).astype(int)
        count = np.bincount(k, minlength=n)[:n]
        total = np.bincount(k, weights=v[keep], minlength=n)[:n]
        on = count > 0
        measured[on, j] = total[on] / count[on]
        has[on, j] = 1.0
    if has[:, 0].sum() < 10:
        raise LogError(
            f"fewer than 10 altitude samples in the ascent ({int(has[:, 0].sum())})"
        )
    inputs = np.column_stack([np.zeros(n), has])
    rec = Record(grid, inputs, measured, x0=np.zeros(6), name=name)
    return rec, outputs
