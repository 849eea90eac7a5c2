"""A rocket flight's events from its own data: liftoff, burnout, apogee, the
deployments and landing, each with the rule that found it.

Every rule is a property of powered flight, not a time or a level tuned to some
logs: liftoff is where the altitude leaves the pad on a constant-acceleration arc
(or the accelerometer leaves its pad reading by more than its own noise), burnout
where the specific force along the axis turns negative (thrust no longer beats
drag), apogee the vertex of a parabola of curvature -g/2 through the top before
the record's first fall faster than free fall, a deployment where the descent rate
falls by more than air density alone can explain, landing where the descent stops.
"""

import dataclasses

import numpy as np
import scipy.interpolate
import scipy.ndimage


G0 = 9.80665
# Detection margins in units of a signal's own noise (robust sigma): the usual
# conventions for "clearly above the noise", not fitted to any log.
_K_NOISE = 5.0
# Under one canopy the descent rate scales with 1/sqrt(density): at most ~25 %
# slower from 5 km to the ground; a main canopy slows the descent 2-5 times.
_DEPLOY_RATIO = 0.6
# the descent's breaks are searched on at most this many bin averages (a 4 kHz log
# descends for 10^6 samples; the breaks need no more than ~0.05 s)
_MOST_DESCENT = 4000
# No canopy lets a rocket down slower than 1 m/s: below it the rocket is not descending
_MIN_DESCENT = 1.0


@dataclasses.dataclass(frozen=True)
class Event:
    """A flight event found in the data.

    **Fields:**

    - `t`: time, s since liftoff (liftoff itself is at 0).
    - `how`: one sentence saying from which channel and by which rule it was found.
    - `value`: the quantity that marks it, where one does (apogee altitude in m,
      burnout speed in m/s, ...), else `nan`.
    """

    t: float
    how: str
    value: float = float("nan")


def robust_sigma(x: np.ndarray) -> float:
    """Noise of a sampled signal from its second differences (MAD, Gaussian
    scaled): insensitive to the trend, so usable on a whole flight. Values held
    over several samples (a sensor read slower than it is logged) count once."""
    x = x[np.concatenate([[True], np.diff(x) != 0])]
    if len(x) < 4:
        return 0.0
    d2 = np.diff(x, 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0))


def quantum(x: np.ndarray) -> float:
    """The smallest step between distinct values (a sensor's resolution)."""
    d = np.abs(np.diff(x))
    d = d[d > 0]
    return float(d.min()) if d.size else 0.0


def isa_height(p: np.ndarray, p0: float) -> np.ndarray:
    """Standard-atmosphere height above the level where the pressure is `p0`, m;
    used to find events in a log with pressure only."""
    return 44330.77 * (1.0 - (p / p0) ** 0.190263)


def liftoff_from_altitude(
    t: np.ndarray, h: np.ndarray, apogee: float
) -> tuple[float, bool, str]:
    """Liftoff time from altitude (m above the pad or anything with the pad near
    0): the break of `h = L` (pad) then `L + c (t - t0)^2` fitted to the samples up
    to 1 % of the climb (or ten times the altitude noise); when no pad sample
    precedes it (the log starts airborne) the arc is extrapolated back to `h = 0`.
    Returns `(t0, late, how)`."""
    h0 = float(np.median(h[: max(1, min(5, len(h) // 20))]))
    climb = apogee - h0
    # the arc up to 1 % of the climb, or ten times the altitude's noise if more:
    # from the last sample below that level before the climb's top
    top = int(np.argmax(h))
    level = max(0.01 * climb, 10 * robust_sigma(h))
    below = np.flatnonzero(h[:top] - h0 <= level)
    end = int(below[-1]) + 1 if below.size else 0
    # at least 8 samples, but not past 10 % of the climb: a coarse log's (1 Hz)
    # first 8 samples span the boost and the coast, which no one arc fits
    within = np.flatnonzero(h[:top] - h[0] <= 0.1 * climb)
    cap = max(end + 1, int(within[-1]) + 1 if within.size else 0, 2)
    end = min(len(h), max(end + 1, min(8, cap)))
    tw, hw = _binned(t[:end], h[:end], 2000)

    def sse(t0, fix_pad):
        s = np.maximum(tw - t0, 0.0) ** 2
        if fix_pad:
            c = np.dot(s, hw) / max(np.dot(s, s), 1e-300)
            return float(np.sum((hw - c * s) ** 2))
        a = np.column_stack([np.ones_like(s), s])
        coef, *_ = np.linalg.lstsq(a, hw, rcond=None)
        return float(np.sum((hw - a @ coef) ** 2))

    def best(lo, hi, fix_pad):
        grid = np.linspace(lo, hi, 201)
        costs = [sse(g, fix_pad) for g in grid]
        k = int(np.argmin(costs))
        step = grid[1] - grid[0]
        fine = np.linspace(grid[k] - step, grid[k] + step, 101)
        return float(fine[int(np.argmin([sse(g, fix_pad) for g in fine]))])

    t0 = best(t[0], tw[-1], False)
    if np.count_nonzero(t < t0) >= 2:
        return (
            t0,
            False,
            "altitude leaves the pad: break of a pad level and a constant-"
            "acceleration arc fitted to the first 1 % of the climb",
        )
    span = max(tw[-1] - t[0], 1.0)
    t0 = best(t[0] - span, t[0], True)
    return (
        t0,
        True,
        "the log starts airborne: a constant-acceleration arc through the first 1 % "
        "of the climb, extrapolated back to the pad (altitude 0)",
    )


def accel_pad(t: np.ndarray, x: np.ndarray, t_guess: float) -> np.ndarray:
    """Indices of an accelerometer's pad samples: those before the boost's first
    rise to half its peak (the peak within 1 s of `t_guess`) that sit within
    `_K_NOISE` noise of the level of the earliest half of them. Empty when fewer
    than five (a log that starts at ignition)."""
    window = np.flatnonzero((t >= t_guess - 1.0) & (t <= t_guess + 1.0))
    if window.size == 0:
        return np.array([], int)
    first = float(np.median(x[: max(1, min(5, window[0] + 1))]))
    peak = float(x[window].max())
    rise = np.flatnonzero(x > first + 0.5 * (peak - first))
    end = int(rise[0]) if rise.size else 0
    if end < 5:
        return np.array([], int)
    early = x[: max(1, end // 2)]
    level = float(np.median(early))
    sigma = max(1.4826 * float(np.median(np.abs(early - level))), 0.5 * quantum(early))
    pad = np.flatnonzero(np.abs(x[:end] - level) <= _K_NOISE * sigma)
    return pad if pad.size >= 5 else np.array([], int)


def liftoff_from_accel(t: np.ndarray, x: np.ndarray, t_guess: float) -> float | None:
    """Refine liftoff with an accelerometer: the start of the rise from its pad
    reading by more than `_K_NOISE` of its pad noise that leads to the boost
    (walking back from half the boost peak). A log that starts at ignition (fewer
    than five pad samples) takes its first samples as the pad level and the
    record's noise. `None` if the log starts above half the boost or no boost
    stands out."""
    window = np.flatnonzero((t >= t_guess - 1.0) & (t <= t_guess + 1.0))
    if window.size == 0:
        return None
    pad = accel_pad(t, x, t_guess)
    if pad.size:
        level = float(np.median(x[pad]))
        sigma = max(
            1.4826 * float(np.median(np.abs(x[pad] - level))), 0.5 * quantum(x[pad])
        )
    else:
        # a log that starts at ignition: its first samples (before half the boost)
        # are the pad, its noise that of the whole record
        first = x[: max(1, min(3, int(window[0]) + 1))]
        level = float(np.median(first))
        sigma = max(robust_sigma(x), 0.5 * quantum(x))
        if x[0] > level + 0.5 * (float(x[window].max()) - level) or sigma == 0:
            return None
    peak = float(x[window].max())
    if peak - level < 4 * _K_NOISE * sigma:
        return None
    i = int(window[np.argmax(x[window] > level + 0.5 * (peak - level))])
    while i > 0 and x[i - 1] > level + _K_NOISE * sigma:
        i -= 1
    return float(t[i])


def burnout_from_accel(t: np.ndarray, sf: np.ndarray, t_lift: float) -> float | None:
    """The first time after the boost's peak that the specific force along the axis
    (gravity included), as a running median of three samples (one noisy sample is
    not a burnout), turns negative: thrust below drag. Linear interpolation between
    the samples around the crossing."""
    after = np.flatnonzero(t >= t_lift)
    if after.size < 10:
        return None
    # the boost peak: largest in the first samples after liftoff, not a later shock
    head = after[t[after] <= t_lift + max(1.0, 0.05 * (t[after[-1]] - t_lift))]
    k = int(head[np.argmax(sf[head])]) if head.size else int(after[0])
    neg = _median3(sf[k:]) < 0
    if not neg.any():
        return None
    i = k + int(np.argmax(neg))
    if i == 0:
        return float(t[0])
    a, b = sf[i - 1], sf[i]
    return float(t[i - 1] + (t[i] - t[i - 1]) * a / (a - b)) if a > 0 else float(t[i])


def _binned(t, h, most: int):
    """At most `most` points: longer series averaged in bins of equal count."""
    if len(t) <= most:
        return t, h
    edges = np.linspace(0, len(t), most + 1).astype(int)
    counts = np.diff(edges)
    return (
        np.add.reduceat(t, edges[:-1]) / counts,
        np.add.reduceat(h, edges[:-1]) / counts,
    )


def _spline(t, h, most: int = 120):
    """A cubic smoothing spline whose smoothing generalised cross-validation
    chooses, through at most `most` points (the GCV search costs ~3 ms a point)."""
    return scipy.interpolate.make_smoothing_spline(*_binned(t, h, most))


def first_fall(t: np.ndarray, h: np.ndarray, t_lift: float) -> int | None:
    """Index of the first sample that falls from the highest altitude so far faster
    than free fall from rest there allows (`g dt^2 / 2`), by more than five times
    the noise plus `g w^2 / 2` (`w` a tenth of the climb time: near the top a
    barometer's wobbles are far smaller, an ejection charge's pulse far larger),
    from a top above half the record's highest that the climb reached at a rate
    gravity alone ends within `w`; or `None`. A rocket that has begun to fall
    cannot climb back: what the record shows after such a fall (an ejection
    charge's pressure pulse and the barometer's recovery from it, which may read
    higher than the top) is no apogee. A drop while the rocket still climbs fast
    (a transonic pressure jump) is not such a fall."""
    m = _median3(h)
    s = np.flatnonzero(t >= t_lift)
    if s.size < 3:
        return None
    ts, ms = t[s], m[s]
    run = np.maximum.accumulate(ms)
    at_top = np.maximum.accumulate(np.where(ms >= run, np.arange(len(ms)), 0))
    climb = np.maximum(ts[at_top] - ts[0], 1.0)
    w = 0.1 * climb
    margin = _K_NOISE * robust_sigma(h) + quantum(h) + 0.5 * G0 * w**2
    falls = np.flatnonzero(run - ms > 0.5 * G0 * (ts - ts[at_top]) ** 2 + margin)
    if falls.size == 0:
        return None
    j, w = at_top[falls], w[falls]
    rate = (run[falls] - np.interp(ts[j] - w, ts, ms)) / w
    # the top must be up there: a pulse reads far less than twice the climb (the
    # pad's own falls and wobbles are not apogees)
    high = run[falls] - ms[0] > 0.5 * (ms.max() - ms[0])
    ok = np.flatnonzero((rate < G0 * w) & high)
    return int(s[falls[ok[0]]]) if ok.size else None


def first_pulse(t: np.ndarray, h: np.ndarray, t_lift: float) -> int | None:
    """Index of the last sample before the first pressure pulse above the top, or
    `None`. A pulse is a rise to a new highest altitude after the record stayed at
    or below its top for longer than three of the sensor's own steps between
    readings (and longer than the flight's climb rate into that top, averaged over
    a tenth of the climb time, needs to gain five times the noise), by more than
    that climb rate allows since the top plus five times the noise, to a peak the
    record then falls from faster than free fall (`first_fall`'s margin) and back
    below where the rise began before it ever reads higher, from a top above half
    the record's highest. A rocket slowing to its apogee cannot
    speed up again, and what it reaches it cannot leave faster than free fall:
    such a spike is an ejection charge's or a gust's pressure, not the apogee; a
    stall in a fast climb that the climb then resumes (a transonic pressure
    wobble) is not one."""
    m = _median3(h)
    s = np.flatnonzero(t >= t_lift)
    if s.size < 3:
        return None
    ts, ms = t[s], m[s]
    run = np.maximum.accumulate(ms)
    # where the record first reached its highest so far (a later equal reading
    # does not restart the pause)
    new_high = np.concatenate([[True], ms[1:] > run[:-1]])
    at_top = np.maximum.accumulate(np.where(new_high, np.arange(len(ms)), 0))
    w = 0.1 * np.maximum(ts[at_top] - ts[0], 1.0)
    rate = (run - np.interp(ts[at_top] - w, ts, ms)) / w
    margin = _K_NOISE * robust_sigma(h) + quantum(h)
    fall = run - ms > 0.5 * G0 * (ts - ts[at_top]) ** 2 + margin + 0.5 * G0 * w**2
    moved = np.flatnonzero(np.diff(h) != 0)
    step = float(np.median(np.diff(t[moved]))) if moved.size > 1 else 0.0
    k = np.arange(1, len(ms))
    top = at_top[k - 1]
    pause = ts[k - 1] - ts[top]
    new = np.flatnonzero(
        (ms[k] > run[k - 1])
        & (pause > 3 * step)
        & (pause * np.maximum(rate[top], 0.0) > margin)
        & (run[k - 1] - ms[0] > 0.5 * (ms.max() - ms[0]))
    )
    for i in k[new]:
        base, i0, v = run[i - 1], at_top[i - 1], max(rate[at_top[i - 1]], 0.0)
        p = i
        while p + 1 < len(ms) and ms[p + 1] >= ms[p]:
            p += 1
        fast = ms[i : p + 1] - base > v * (ts[i : p + 1] - ts[i0]) + margin
        # a pulse falls back below where it rose from before the record climbs
        # above its peak (a climb resumed after a stall goes higher)
        higher = np.flatnonzero(ms[p + 1 :] > ms[p])
        back = np.flatnonzero(ms[p + 1 :] < base)
        end = higher[0] if higher.size else len(ms)
        if fast.any() and back.size and back[0] < end and fall[p + 1 :][:end].any():
            return int(s[i - 1])
    return None


def top_end(t: np.ndarray, h: np.ndarray, t_lift: float) -> int | None:
    """Where the apogee search ends (exclusive index): at the record's first fall
    faster than free fall (`first_fall`) or just after the last sample before its
    first pulse (`first_pulse`), whichever comes first; `None` if neither."""
    fall, pulse = first_fall(t, h, t_lift), first_pulse(t, h, t_lift)
    ends = [e for e in (fall, None if pulse is None else pulse + 1) if e is not None]
    return min(ends) if ends else None


def apogee(t: np.ndarray, h: np.ndarray, t_lift: float) -> tuple[float, float]:
    """Apogee time and altitude: the vertex of `H - g (t - ta)^2 / 2` fitted to the
    samples within 5 % of the climb time of the highest one (at least five on each
    side) before the first fall faster than free fall or pulse (`top_end`). Near apogee
    the vertical speed is near zero, so drag leaves gravity alone to bend the path;
    the fixed curvature makes the vertex robust to noise. Samples off the arc by
    more than five times the fit's own scatter (a pressure pulse) are left out and
    the arc fitted again."""
    end = top_end(t, h, t_lift)
    if end is not None and end >= 3:
        t, h = t[:end], h[:end]
    i = int(np.argmax(_median3(h)))
    w = 0.05 * max(t[i] - t_lift, 1.0)
    lo = min(int(np.searchsorted(t, t[i] - w)), max(i - 5, 0))
    hi = max(int(np.searchsorted(t, t[i] + w, "right")), min(i + 6, len(t)))
    tw, hw = t[lo:hi] - t[i], h[lo:hi]
    if len(tw) < 3:
        return float(t[i]), float(h[i])
    # h + g t^2 / 2 = (H - g ta^2 / 2) + g ta t: a straight line in t
    a = np.column_stack([np.ones_like(tw), tw])
    y = hw + 0.5 * G0 * tw**2
    keep = np.ones(len(tw), bool)
    floor = robust_sigma(h) + quantum(h) / _K_NOISE
    for _ in range(3):
        (c0, c1), *_ = np.linalg.lstsq(a[keep], y[keep], rcond=None)
        # a pressure pulse's samples (far off the arc by the fit's own scatter)
        # do not bend it
        r = y - a @ np.array([c0, c1])
        mid = float(np.median(r[keep]))
        scale = max(1.4826 * float(np.median(np.abs(r[keep] - mid))), floor)
        inside = np.abs(r - mid) <= _K_NOISE * scale
        if inside.sum() < 3 or np.array_equal(inside, keep):
            break
        keep = inside
    ta = c1 / G0
    if not (tw[0] <= ta <= tw[-1]):
        return float(t[i]), float(h[i])
    return float(t[i] + ta), float(c0 + 0.5 * G0 * ta**2)


def burnout_from_altitude(
    t: np.ndarray, h: np.ndarray, t_lift: float, t_apogee: float
) -> tuple[float, float]:
    """Time and value of the greatest climb rate of a smoothing spline through the
    ascent (no accelerometer: burnout is where the speed stops rising)."""
    sel = np.flatnonzero((t >= t_lift) & (t <= t_apogee))
    if sel.size < 8:
        return float("nan"), float("nan")
    s = _spline(t[sel], h[sel])
    fine = np.linspace(t[sel[0]], t[sel[-1]], 20 * min(sel.size, 120))
    v = s.derivative()(fine)
    k = int(np.argmax(v))
    return float(fine[k]), float(v[k])


def _median3(h):
    if len(h) < 3:
        return h
    m = np.median(np.stack([h[:-2], h[1:-1], h[2:]]), axis=0)
    return np.concatenate([h[:1], m, h[-1:]])


def _two_lines(t, h):
    """Best break of a continuous two-line fit `a + b t + c (t - t_k)_+` (least
    squares, every sample a candidate break, from cumulative sums): (index, slope
    before, slope after)."""
    n = len(t)
    if n < 12:
        return None
    t = t - t.mean()
    h = h - h.mean()
    k = np.arange(5, n - 5)
    tk = t[k]

    def suffix(v):  # sum over i >= k
        c = np.concatenate([np.cumsum(v[::-1])[::-1], [0.0]])
        return c[k]

    s1, st, stt, sh, sth = (suffix(v) for v in (np.ones(n), t, t * t, h, t * h))
    # sums over the hinge u = (t - tk)_+
    su = st - tk * s1
    suu = stt - 2 * tk * st + tk**2 * s1
    stu = stt - tk * st
    shu = sth - tk * sh
    m = np.empty((len(k), 3, 3))
    m[:, 0, 0], m[:, 0, 1], m[:, 1, 1] = n, t.sum(), (t * t).sum()
    m[:, 0, 2] = m[:, 2, 0] = su
    m[:, 1, 2] = m[:, 2, 1] = stu
    m[:, 1, 0] = m[:, 0, 1]
    m[:, 2, 2] = suu
    rhs = np.stack([np.full(len(k), h.sum()), np.full(len(k), (t * h).sum()), shu], 1)
    ok = np.linalg.det(m) > 0
    coef = np.zeros((len(k), 3))
    coef[ok] = np.linalg.solve(m[ok], rhs[ok][..., None])[..., 0]
    # SSE = h.h - coef . rhs
    sse = np.where(ok, (h * h).sum() - np.einsum("ij,ij->i", coef, rhs), np.inf)
    j = int(np.argmin(sse))
    return int(k[j]), float(coef[j, 1]), float(coef[j, 1] + coef[j, 2])


def descent_changes(
    t: np.ndarray, h: np.ndarray, t_apogee: float, h_apogee: float
) -> list[tuple[float, float, float]]:
    """Where the descent rate drops by more than `_DEPLOY_RATIO`: [(time, rate
    before, rate after)], m/s positive down, by binary segmentation (the best break
    of a continuous two-line fit, then each side again, three levels deep), each
    break then fitted again between its neighbours."""
    sel = np.flatnonzero((t > t_apogee) & (h < h_apogee - 0.03 * abs(h_apogee)))
    if sel.size < 12:
        return []
    tt, hh = _binned(t[sel], h[sel], _MOST_DESCENT)
    found = []

    def search(a, b, depth):
        if depth == 0 or b - a < 12:
            return
        r = _two_lines(tt[a:b], hh[a:b])
        if r is None:
            return
        k, s1, s2 = r
        k += a
        if (
            -s1 > _MIN_DESCENT
            and -s2 < _DEPLOY_RATIO * -s1
            and tt[b - 1] - tt[k] >= 1.0
        ):
            found.append((float(tt[k]), -s1, -s2))
        search(a, k, depth - 1)
        search(k, b, depth - 1)

    search(0, len(tt), 3)
    found.sort()
    # each break again between its neighbours, free of the other changes' bends
    cuts = [0] + [int(np.searchsorted(tt, f[0])) for f in found] + [len(tt)]
    refined = []
    for i in range(1, len(cuts) - 1):
        a, b = cuts[i - 1], cuts[i + 1]
        while b - a >= 12:
            r = _two_lines(tt[a:b], hh[a:b])
            if r is None:
                break
            k = a + r[0]
            if -r[1] > _MIN_DESCENT and -r[2] < _DEPLOY_RATIO * -r[1]:
                refined.append((float(tt[k]), -r[1], -r[2]))
                break
            # another bend before it (a canopy's slow deceleration over a long
            # descent outweighs a landing in the log's last seconds): that bend is
            # the neighbour before. The drop must still hold up to the next
            # change (or the log's end): one that fails there was a local wiggle
            if k < cuts[i] - 5:
                a = k
            else:
                break
    return refined


def shocks(t: np.ndarray, x: np.ndarray, t_from: float) -> list[float]:
    """Times after `t_from` where an accelerometer jumps from its running median by
    more than 10 of its own noise and more than 2 g: opening shocks. One time per
    burst (samples within 1 s are one burst)."""
    sel = np.flatnonzero(t > t_from)
    if sel.size < 10:
        return []
    y = x[sel]
    med = scipy.ndimage.median_filter(y, 11, mode="nearest")
    dev = np.abs(y - med)
    sigma = max(1.4826 * float(np.median(dev)), 0.5 * quantum(y))
    hits = np.flatnonzero((dev > 2 * _K_NOISE * sigma) & (dev > 2 * G0))
    out: list[float] = []
    for i in hits:
        ti = float(t[sel[i]])
        if not out or ti - out[-1] > 1.0:
            out.append(ti)
    return out
