"""A rocket log's ascent as a [`Record`][] on one uniform grid.

Channels keep their own rates in the log; the record's grid is the fastest of them
(between 20 and 100 Hz), each channel's samples are averaged into the grid step they
fall in, and an input `has_<channel>` is 1 at the steps that hold a sample and 0
elsewhere, so the model's output there is 0 like the record's (no residual). Slow,
sparse or interrupted channels (a 2 Hz tail, telemetry dropouts, an accelerometer
that stops after the boost, a GNSS receiver's 1-10 Hz fixes) so enter the fit only
where they were measured.
"""

import numpy as np

from .._errors import LogError
from .._model import Record


MIN_STEP, MAX_STEP = 0.01, 0.05  # s: 100 Hz, 20 Hz
GNSS = ("gnss_e", "gnss_n")  # the GNSS outputs, m east and north of the pad
WGS84_A, WGS84_F = 6_378_137.0, 1 / 298.257223563  # m, flattening


def local_tangent(lat, lon, lat0: float, lon0: float):
    """`(east, north)` m of the points `lat`, `lon` (deg, arrays, on the WGS84
    ellipsoid) in the plane tangent to it at `lat0`, `lon0` (deg): the model's
    east-north-up frame, fixed at the pad. Earth-centred coordinates, their
    difference turned into the pad's east and north; the fix's height is not
    used (a point 3 km east on the pad's parallel lies 0.6 m north in this
    plane: the meridians converge)."""
    e2 = WGS84_F * (2 - WGS84_F)

    def centred(la, lo):
        la, lo = np.radians(la), np.radians(lo)
        n = WGS84_A / np.sqrt(1 - e2 * np.sin(la) ** 2)
        c = np.cos(la)
        return n * c * np.cos(lo), n * c * np.sin(lo), n * (1 - e2) * np.sin(la)

    x, y, z = centred(np.asarray(lat, float), np.asarray(lon, float))
    x0, y0, z0 = centred(float(lat0), float(lon0))
    dx, dy, dz = x - x0, y - y0, z - z0
    phi, lam = np.radians(lat0), np.radians(lon0)
    east = -np.sin(lam) * dx + np.cos(lam) * dy
    north = (
        -np.sin(phi) * np.cos(lam) * dx
        - np.sin(phi) * np.sin(lam) * dy
        + np.cos(phi) * dz
    )
    return east, north


def gnss_position(log):
    """`(t, east m, north m)`: the log's GNSS fixes (`gnss_lat`, `gnss_lon`) east
    and north of the pad, or `None` where it has none or no pad position. The pad
    is the fixes' median before liftoff (the reader's `pad` value), else the last
    fix within 10 s before liftoff, else the first fix if it is within 0.5 s after
    it (the rocket still on the rail, a metre from the pad across it). A fix
    repeated unchanged after liftoff is the receiver holding its last one (the
    rocket moves metres between fixes): dropped, so that each fix keeps its
    time."""
    ch = log.channels
    if "gnss_lat" not in ch or "gnss_lon" not in ch:
        return None
    lat, lon = ch["gnss_lat"], ch["gnss_lon"]
    if len(lat.t) != len(lon.t) or not np.array_equal(lat.t, lon.t):
        return None
    t, la, lo = lat.t, lat.values, lon.values
    pad = getattr(log, "pad", {})
    if "gnss_lat" in pad and "gnss_lon" in pad:
        lat0, lon0 = pad["gnss_lat"], pad["gnss_lon"]
    elif np.any((t <= 0) & (t > -10)):
        i = np.flatnonzero((t <= 0) & (t > -10))[-1]
        lat0, lon0 = la[i], lo[i]
    elif t.size and 0 < t[0] <= 0.5:
        lat0, lon0 = la[0], lo[0]
    else:
        return None
    same = np.r_[False, (la[1:] == la[:-1]) & (lo[1:] == lo[:-1])]
    keep = ~(same & (t > 0)) & np.isfinite(la) & np.isfinite(lo)
    east, north = local_tangent(la[keep], lo[keep], float(lat0), float(lon0))
    return t[keep], east, north


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
    log,
    until=None,
    name="flight",
    gyro: bool = False,
    step: float = MIN_STEP,
    gnss: bool = False,
) -> tuple[Record, tuple[str, ...]]:
    """The record of the ascent from just before liftoff to `until` (default the
    apogee), and its output names (`gyro`: the lateral body rate where the log has
    it, for the attitude; `gnss`: the GNSS position east and north of the pad,
    `gnss_e` and `gnss_n`, where the log has at least three fixes after liftoff
    (see [`gnss_position`][]), last; `step`: s, the shortest grid step allowed;
    the grid is the other channels', each fix in the step it falls in).

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
    fixes = gnss_position(log) if gnss else None
    if fixes is not None and np.sum((fixes[0] > 0) & (fixes[0] <= end)) >= 3:
        outputs += GNSS
        series["gnss_e"] = fixes[0], fixes[1]
        series["gnss_n"] = fixes[0], fixes[2]
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
