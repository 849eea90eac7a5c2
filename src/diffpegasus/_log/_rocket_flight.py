"""One flight computer's clock: liftoff found, units checked against the flight,
the altitude put on the pad, a corrupt end dropped, the events found.

[`read_rocket_log`][] gathers the channels of each clock (one flight computer's
files) and hands them here in the files' own seconds.
"""

import dataclasses
import re

import numpy as np

from .._errors import LogError
from ._rocket_clean import impossible_tail, Series
from ._rocket_events import (
    accel_pad,
    apogee,
    burnout_from_accel,
    burnout_from_altitude,
    descent_changes,
    Event,
    G0,
    isa_height,
    liftoff_from_accel,
    liftoff_from_altitude,
    quantum,
    robust_sigma,
    shocks,
)
from ._rocket_units import (
    check_accel_axial,
    check_altitude_unit,
    check_imu,
    check_pressure,
    check_temperature,
    check_velocity_unit,
)


def _pad_of(t_lift: float):
    def pad(s: Series) -> np.ndarray:
        idx = np.flatnonzero(s.t < t_lift)
        return idx[: int(0.9 * len(idx))]

    return pad


def one_clock(
    flat: dict[str, Series],
    auto: bool,
    messages: list[str],
    stated: dict[str, float] | None = None,
):
    """Liftoff, units and events of the channels on one clock (file time): returns
    `(liftoff time in the file, events, pad)`, or `None` for a clock with nothing
    to find liftoff in (GNSS alone). The series are converted in place. `stated`:
    name -> file time of events the log's writer states, taken instead of those
    found (liftoff is then not searched for)."""
    stated = stated or {}
    alt = flat.get("altitude")
    press = flat.get("pressure")
    if alt is None and press is None:
        if "accel_axial" not in flat:
            return None
    # a height to find liftoff and apogee with: the altitude, else ISA from pressure
    if press is not None:
        check_pressure(press, np.arange(min(5, len(press.t))), messages)
    if alt is not None:
        th, hh = alt.t, alt.v
    elif press is not None:
        th, hh = press.t, isa_height(press.v, float(np.median(press.v[:5])))
    else:
        th = hh = None
    t_lift, late, how = None, False, ""
    if "liftoff" in stated:
        t_lift, how = (
            stated["liftoff"],
            "stated in the rocket.toml's [log.stated_events]",
        )
    elif th is not None:
        top = (
            float(np.max(np.convolve(hh, np.ones(3) / 3, "same")[1:-1]))
            if len(hh) > 3
            else float(hh.max())
        )
        t_lift, late, how = liftoff_from_altitude(th, hh, top)
    if auto and "accel_axial" not in flat and t_lift is not None:
        _auto_axis(flat, t_lift, messages)
    acc = flat.get("accel_axial")
    if acc is not None and "liftoff" not in stated:
        guess = t_lift if t_lift is not None else float(acc.t[np.argmax(acc.v)])
        refined = liftoff_from_accel(acc.t, acc.v, guess)
        if refined is not None and (t_lift is None or abs(refined - t_lift) < 1.0):
            if t_lift is not None and late:
                late = False
            t_lift = refined
            how = (
                "the axial accelerometer leaves its pad reading by more than five "
                "times its pad noise, on the rise to the boost"
            )
    if t_lift is None:
        raise LogError(
            f"{acc.where if acc is not None else 'the log'}: no liftoff: no altitude "
            "or pressure to see the climb, and the accelerometer has no samples on "
            "the pad before its boost"
        )
    pad_of = _pad_of(t_lift)
    if press is not None:
        check_pressure(press, pad_of(press), messages)
    check_imu(flat, pad_of, messages)
    if "temperature" in flat:
        check_temperature(flat["temperature"], messages)
    acc = flat.get("accel_axial")
    if acc is not None:
        near_top = np.array([], int)
        if th is not None:
            # the last tenth of the climb, where drag has all but vanished
            t_top, _ = apogee(th, hh, t_lift)
            near_top = np.flatnonzero(
                (acc.t >= t_top - 0.1 * (t_top - t_lift)) & (acc.t <= t_top)
            )
        check_accel_axial(acc, accel_pad(acc.t, acc.v, t_lift), near_top, messages)
        if acc.spec.filtered:
            zero = np.flatnonzero(acc.v != acc.v[-1])
            if (
                acc.v[-1] == (G0 if acc.spec.gravity == "removed" else 0.0)
                and zero.size
                and zero[-1] < len(acc.v) - 10
            ):
                cut = int(zero[-1]) + 1
                messages.append(
                    f"{acc.where}: held at exactly {acc.v[-1] - G0 * (acc.spec.gravity == 'removed'):g} "
                    f"from {acc.t[cut] - t_lift:.2f} s on (the flight computer stops "
                    "filtering it); those samples dropped"
                )
                acc.keep(np.arange(len(acc.t)) < cut)
    pad = {}
    if alt is not None:
        p = pad_of(alt)
        if p.size >= 3:
            offset = float(np.median(alt.v[p]))
            alt.v = alt.v - offset
            pad["altitude_offset"] = offset
            if abs(offset) > 5 * robust_sigma(alt.v) + quantum(alt.v):
                messages.append(
                    f"{alt.where}: reads {offset:.3g} m on the pad; altitude is "
                    "taken from the pad's own reading"
                )
        th, hh = alt.t, alt.v
    if late:
        first = th[0] if th is not None else t_lift
        messages.append(
            f"the log starts {first - t_lift:.2f} s after liftoff"
            + (f" at {hh[0]:.3g} m" if hh is not None else "")
            + "; liftoff extrapolated"
        )
        if hh is not None:
            src = alt if alt is not None else flat.get("pressure")
            where = src.where if src is not None else "the log"
            messages.extend(_zero_not_the_pad(th, hh, first - t_lift, where))
    for name in ("pressure", "gnss_lat", "gnss_lon", "gnss_alt"):
        if name in flat:
            p = pad_of(flat[name])
            if p.size:
                pad[name] = float(np.median(flat[name].v[p]))
    events = {"liftoff": Event(0.0, how)}
    if th is None:
        return t_lift, events, pad
    t_apo, h_apo = apogee(th, hh, t_lift)
    if alt is not None:
        bad_from, pulses = impossible_tail(alt, t_apo, h_apo, t_lift)
        if bad_from is not None:
            n = len(alt.t) - bad_from
            messages.append(
                f"{alt.where}: dropped the last {n} samples from row "
                f"{alt.rows[bad_from]} ({alt.v[bad_from]:.4g} m at "
                f"{alt.t[bad_from] - t_lift:.2f} s): a fall faster than free fall "
                "from apogee or a reading far above it, a corrupt end of the file"
            )
            bad_rows = set(alt.rows[bad_from:].tolist())
            for s in flat.values():
                if s.file == alt.file:
                    s.keep(~np.isin(s.rows, list(bad_rows)))
            th, hh = alt.t, alt.v
    else:
        pulses = []
    events["apogee"] = Event(
        t_apo - t_lift,
        "vertex of a parabola of curvature -g/2 through the "
        f"{'altitude' if alt is not None else 'pressure (standard-atmosphere height)'}"
        f" near its highest sample ({float(np.max(hh)):.5g} m)",
        h_apo,
    )
    t_bo = None
    if acc is not None:
        t_bo = burnout_from_accel(acc.t, acc.v, t_lift)
        if t_bo is not None:
            events["burnout"] = Event(
                t_bo - t_lift,
                "the axial specific force (running median of three samples) turns "
                "negative after the boost: thrust below drag",
            )
    if t_bo is None:
        t_bo, v_bo = burnout_from_altitude(th, hh, t_lift, t_apo)
        if np.isfinite(t_bo):
            events["burnout"] = Event(
                t_bo - t_lift,
                "greatest climb rate of a smoothing spline through the ascent "
                "altitude (no accelerometer over the boost)",
                v_bo,
            )
    if alt is not None and t_bo is not None and np.isfinite(t_bo):
        h_bo = float(np.interp(t_bo, th, hh))
        factor = check_altitude_unit(alt, t_bo, h_bo, t_apo, h_apo, messages)
        if factor != 1.0:
            hh = alt.v
            top = f"({float(np.max(hh)):.5g} m)"
            how = re.sub(r"\([^()]* m\)$", top, events["apogee"].how)
            events["apogee"] = dataclasses.replace(
                events["apogee"], value=h_apo * factor, how=how
            )
            h_apo *= factor
    if "velocity" in flat and th is not None:
        h_lift = float(np.interp(t_lift, th, hh))
        if not check_velocity_unit(
            flat["velocity"], t_lift, t_apo, h_apo - h_lift, messages
        ):
            del flat["velocity"]
    _deployments(events, flat, th, hh, t_lift, t_apo, h_apo, pulses, messages)
    for name, t in stated.items():
        if name == "liftoff":
            continue
        found = events.get(name)
        messages.append(
            f"{name}: {t - t_lift:.3f} s after liftoff as the rocket.toml states "
            + (f"(found from the data: {found.t:.3f} s)" if found else "(not found)")
        )
        events[name] = Event(
            t - t_lift,
            "stated in the rocket.toml's [log.stated_events]",
            float(np.interp(t, th, hh)),
        )
    return t_lift, events, pad


def _auto_axis(flat, t_lift, messages):
    acc = [flat.get(n) for n in ("accel_x", "accel_y", "accel_z")]
    if any(a is None for a in acc):
        return
    best, sign, name = 0.0, 1.0, ""
    for n, a in zip(("accel_x", "accel_y", "accel_z"), acc, strict=False):
        sel = (a.t >= t_lift) & (a.t <= t_lift + 1.0)
        if sel.any():
            m = float(np.median(a.v[sel]))
            if abs(m) > best:
                best, sign, name = abs(m), np.sign(m), n
    if not name:
        return
    a = flat[name]
    spec = dataclasses.replace(
        a.spec, name="accel_axial", factor=a.spec.factor * sign, gravity="included"
    )
    flat["accel_axial"] = Series(a.t, a.v * sign, a.rows, spec, a.file)
    messages.append(
        f"{a.where}: accel_axial is {'-' if sign < 0 else '+'}{name}, the axis that "
        "reads most along the boost"
    )


def _deployments(events, flat, th, hh, t_lift, t_apo, h_apo, pulses, messages):
    t_bo = events["burnout"].t + t_lift if "burnout" in events else t_lift
    after = 0.5 * (t_bo + t_apo)
    marks: list[tuple[float, str]] = [
        (p, "a pressure pulse the altitude returns from (an ejection charge)")
        for p in pulses
    ]
    for name in ("accel_axial", "accel_x", "accel_y", "accel_z"):
        if name in flat and not flat[name].spec.filtered:
            s = flat[name]
            for t in shocks(s.t, s.v, after):
                marks.append((t, f"an opening shock on {name}"))
    marks.sort()
    changes = descent_changes(th, hh, t_apo, h_apo)
    landing = None
    mains = []
    for t, before, after_rate in changes:
        h_here = float(np.interp(t, th, hh))
        if h_here < 0.05 * h_apo and after_rate < 0.3 * before:
            landing = (t, before, after_rate) if landing is None else landing
        else:
            mains.append((t, before, after_rate))
    if mains:
        t, before, after_rate = mains[0]
        near = [m for m in marks if t - 3.0 <= m[0] <= t + 1.0]
        how = (
            f"the descent rate falls from {before:.3g} to {after_rate:.3g} m/s "
            "(two straight lines through the descent altitude)"
        )
        if near:
            t, what = near[0]
            how = f"{what}, where {how}"
        events["main"] = Event(t - t_lift, how, float(np.interp(t, th, hh)))
    t_main = events["main"].t + t_lift if "main" in events else np.inf
    early = [m for m in marks if m[0] < t_main - 1.0]
    if early:
        t, what = early[0]
        events["drogue"] = Event(t - t_lift, what, float(np.interp(t, th, hh)))
    if landing is not None:
        t, before, after_rate = landing
        events["landing"] = Event(
            t - t_lift,
            f"the descent stops: {before:.3g} m/s, then {after_rate:.3g} m/s (two "
            "straight lines through the descent altitude)",
            float(np.interp(t, th, hh)),
        )
    elif th[-1] > t_apo:
        messages.append(
            f"the log ends {th[-1] - t_lift:.1f} s after liftoff at {hh[-1]:.4g} m, "
            "still descending: no landing"
        )


def _zero_not_the_pad(t, h, after: float, where: str) -> list[str]:
    """A log that starts airborne `after` s past liftoff: its climb rate over its
    first half second (at least 3 samples) from rest in that time takes an
    acceleration; above 60 g, more than any boost that carries a flight computer,
    the log's altitude zero is not the pad (a record cut and re-zeroed in flight)."""
    n = max(3, int(np.count_nonzero(t - t[0] <= 0.5)))
    if len(t) < n or after <= 0:
        return []
    rate = float(np.polyfit(t[:n] - t[0], h[:n], 1)[0])
    if rate / after <= 60 * G0:
        return []
    return [
        f"{where}: the log starts at {h[0]:.3g} m already climbing at {rate:.0f} m/s, "
        f"{after:.2f} s after the liftoff its altitude puts on the pad: "
        f"{rate / after / G0:.0f} g, more than any boost; its altitude zero is not "
        "the pad (a record cut and re-zeroed in flight?), its heights and apogee are "
        "above its first sample"
    ]
