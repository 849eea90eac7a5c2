"""Global aerodynamics for a vehicle whose flight condition sweeps Mach: each
coefficient a polynomial in alpha and the elevator, every coefficient of it a
smooth function of Mach (a clamped cubic B-spline).

    CL = sum_k B_k(M) (a_k1 alpha + a_k2 alpha^2 + ... + b_k de + c_k alpha de),
    likewise CD, CM (CM about the geometry's cp station)

Per-window derivatives would absorb a missing physical term (a constant offset
turns into biased derivatives, not into misfit), so a diagnosis fits this part
global over the record. The alpha powers stand for the alpha dependence of
derivative tables (`CL = CLa(alpha, M) alpha`); the order 3 default keeps the
structural error of the Pegasus database below what the diagnosis sees on clean
flights. The `alpha de` term stands for elevator derivatives that vary with alpha
(`CLde(alpha, M)`, as in any table over alpha and Mach): without it a change of
trim deflection at one Mach number leaves a misfit that a constant moment offset
explains.

The part is a value like any other (see [`AbstractAerodynamics`][]): its
breakpoints and start values are data-dependent, so [`fit_mach_spline`][] builds
it from a record's channels (breakpoints over its Mach range, start values by one
equation-error regression of the reconstructed coefficients).
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._parts import AbstractAerodynamics


COEFFICIENTS = ("CL", "CD", "CM")
PLACEMENTS = ("quantile", "blend")


def bspline_basis(x, breaks, degree: int = 3):
    """Clamped B-spline basis `(..., len(breaks) + degree - 1)` at `x` (NumPy or
    JAX; clipped to the breakpoints' range), by the Cox-de Boor recursion. `breaks`
    `(n,)` increasing, NumPy or JAX (traced breakpoints are fine: which knot
    intervals are empty is known from the clamping alone). The functions sum to
    one at every point."""
    numeric = isinstance(x, np.ndarray | float | int) and isinstance(
        breaks, np.ndarray | tuple | list
    )
    xp = np if numeric else jnp
    breaks = xp.asarray(breaks, float)
    nb_ = breaks.shape[0]
    x = xp.clip(xp.asarray(x, float), breaks[0], breaks[-1])
    # knot j of the clamped sequence is breakpoint index[j]
    index = [0] * degree + list(range(nb_)) + [nb_ - 1] * degree
    t = [breaks[j] for j in index]
    n_int = len(t) - 1
    last = nb_ + degree - 2  # the interval that holds the right end
    b = []
    for i in range(n_int):
        if index[i] == index[i + 1]:
            inside = xp.zeros_like(x, dtype=bool)
        else:
            inside = (t[i] <= x) & (x < t[i + 1])
        if i == last:
            inside = inside | (x >= breaks[-1])
        b.append(xp.where(inside, 1.0, 0.0))
    for d in range(1, degree + 1):
        nb = []
        for i in range(n_int - d):
            term = 0.0 * x
            if index[i + d] != index[i]:
                term = term + (x - t[i]) / (t[i + d] - t[i]) * b[i]
            if index[i + d + 1] != index[i + 1]:
                term = term + (t[i + d + 1] - x) / (t[i + d + 1] - t[i + 1]) * b[i + 1]
            nb.append(term)
        b = nb
    return xp.stack(b, axis=-1)


def mach_breakpoints(mach, n_breaks: int, placement: str = "quantile") -> np.ndarray:
    """`n_breaks` increasing breakpoints over the range of `mach`, `(n_breaks,)`.

    `"quantile"` (the default): each interval holds the same share of the record.
    `"blend"`: equal steps of half the share of the record's samples at or below a
    Mach number plus half its share of the record's Mach range, so every interval
    gets at least half a step of either (quantiles spend an interval on a dwell at
    one Mach number and can leave a fast passage through a wide range in one).
    """
    m = np.sort(np.asarray(mach, float))
    if placement == "quantile":
        return np.quantile(m, np.linspace(0.0, 1.0, n_breaks))
    if placement != "blend":
        raise ValueError(f"placement must be one of {PLACEMENTS}, got {placement!r}")
    span = m[-1] - m[0]
    if span <= 0:
        return np.full(n_breaks, m[0])
    m = np.concatenate([m[:1], m])
    share = np.arange(len(m)) / (len(m) - 1)
    measure = 0.5 * share + 0.5 * (m - m[0]) / span
    return np.interp(np.linspace(0.0, 1.0, n_breaks), measure, m)


class MachSplineAerodynamics(AbstractAerodynamics):
    """CL, CD, CM polynomial in alpha (no constant term) and the elevator, each
    coefficient a cubic B-spline over Mach (see the module).

    **Fields:** `knots` (spline functions, at least 4); `alpha_order` (highest
    power of alpha); `alpha_elevator` (the `alpha de` term).

    Parameters: `CL.a1[k]` ... `CM.de[k]`, `CM.a1de[k]`, the term's coefficient
    on spline function `k` (per rad^p for `a<p>`, per rad for `de`), start 0; and
    the Mach breakpoints `mach_break[j]`, `j < knots - 2`, increasing, which a
    fit holds (parameters rather than fields, so that fits of logs over other
    Mach ranges share one compiled program). [`fit_mach_spline`][] gives start
    values for a record.
    """

    knots: int = eqx.field(static=True, default=6)
    alpha_order: int = eqx.field(static=True, default=3)
    alpha_elevator: bool = eqx.field(static=True, default=True)

    def __check_init__(self):
        if self.knots < 4:
            raise ValueError(
                f"knots must be at least 4 (cubic spline), got {self.knots}"
            )

    @property
    def terms(self) -> tuple[str, ...]:
        """Regressors of each coefficient: `a1 = alpha`, `a2 = alpha^2`, ..., `de`,
        and `a1de = alpha de` with `alpha_elevator`."""
        cross = ("a1de",) if self.alpha_elevator else ()
        return tuple(f"a{p}" for p in range(1, self.alpha_order + 1)) + ("de",) + cross

    def coefficient_names(self) -> tuple[str, ...]:
        return tuple(
            f"{c}.{term}[{k}]"
            for c in COEFFICIENTS
            for term in self.terms
            for k in range(self.knots)
        )

    def break_names(self) -> tuple[str, ...]:
        return tuple(f"mach_break[{j}]" for j in range(self.knots - 2))

    def start(self):
        breaks = np.linspace(0.5, 3.0, self.knots - 2)  # replaced by a fit's start
        return {
            **dict.fromkeys(self.coefficient_names(), 0.0),
            **dict(zip(self.break_names(), breaks.tolist(), strict=True)),
        }

    def regressors(self, mach, alpha, de, breaks):
        """`(..., len(terms) * knots)`: the basis at `mach` times alpha, alpha^2,
        ..., de (and alpha de); NumPy or JAX arrays."""
        xp = np if isinstance(mach, np.ndarray) else jnp
        basis = bspline_basis(mach, breaks)
        powers = [alpha**p for p in range(1, self.alpha_order + 1)] + [de]
        if self.alpha_elevator:
            powers.append(alpha * de)
        return xp.concatenate([basis * xp.asarray(v)[..., None] for v in powers], -1)

    def coefficients(self, c, p):
        breaks = jnp.stack([p[n] for n in self.break_names()])
        cols = self.regressors(c.mach, c.alpha, c.de, breaks)
        theta = jnp.stack([p[n] for n in self.coefficient_names()]).reshape(3, -1)
        cl, cd, cm = theta @ cols
        return cl, cd, cm


def fit_mach_spline(
    part: MachSplineAerodynamics,
    mach,
    alpha,
    de,
    coefficients: tuple,
    placement: str = "quantile",
) -> dict[str, float]:
    """Start values of `part` for a record: breakpoints over the range of `mach`
    ([`mach_breakpoints`][]) and the coefficients of one least-squares regression
    of the measured `coefficients` `(CL, CD, CM)` (each `(n,)`, e.g. reconstructed
    from accelerometers) on its regressors at `mach`, `alpha` (rad), `de` (rad)."""
    breaks = mach_breakpoints(mach, part.knots - 2, placement)
    if np.any(np.diff(breaks) <= 0):
        raise ValueError(
            "the log's Mach number does not vary enough for "
            f"{part.knots} spline knots; use fewer"
        )
    a = part.regressors(
        np.asarray(mach, float), np.asarray(alpha), np.asarray(de), breaks
    )
    values = np.concatenate(
        [np.linalg.lstsq(a, np.asarray(y), rcond=None)[0] for y in coefficients]
    )
    return {
        **dict(zip(part.coefficient_names(), values.tolist(), strict=True)),
        **dict(zip(part.break_names(), breaks.tolist(), strict=True)),
    }


class KnotChoice(eqx.Module):
    """How many Mach functions a record supports ([`choose_knots`][]).

    **Fields:** `knots` (the choice); `candidates` (the counts tried, `(m,)`);
    `loss` (cross-validated loss of each, `sum over CL, CD, CM of log(mean
    squared prediction error)`, `(m,)`); `excess` (each count's mean excess over
    the lowest, per left-out segment, and its standard error: `(m,)` each);
    `segments` (the number of left-out segments); `placement`.
    """

    knots: int = eqx.field(static=True)
    candidates: tuple[int, ...] = eqx.field(static=True)
    loss: tuple[float, ...] = eqx.field(static=True)
    excess: tuple[float, ...] = eqx.field(static=True)
    excess_stderr: tuple[float, ...] = eqx.field(static=True)
    segments: int = eqx.field(static=True)
    placement: str = eqx.field(static=True)

    def summary(self) -> dict:
        """JSON-ready: the rule in words, the choice and the table."""
        return {
            "rule": (
                "Mach functions per coefficient term chosen from the log: the fewest "
                "whose equation-error regression of CL, CD and CM predicts left-out "
                "shooting segments within one standard error of the best count "
                f"({self.segments} segments left out one at a time; "
                f"{self.placement} breakpoints)"
            ),
            "knots": self.knots,
            "candidates": list(self.candidates),
            "loss": list(self.loss),
            "excess": list(self.excess),
            "excess_stderr": list(self.excess_stderr),
        }


def choose_knots(
    mach,
    alpha,
    de,
    coefficients: tuple,
    segment,
    *,
    placement: str = "quantile",
    alpha_order: int = 3,
    alpha_elevator: bool = True,
    smallest: int = 4,
    largest: int = 12,
) -> KnotChoice:
    """The number of Mach functions the record carries, by cross-validation across
    its segments.

    For each count from `smallest` to `largest` the coefficients `(CL, CD, CM)`
    (each `(n,)`, reconstructed from the record) are regressed on the part's
    regressors at `mach`, `alpha` (rad), `de` (rad) with one segment left out at
    a time (`segment` `(n,)` integer labels, e.g. the shooting segments), and the
    left-out samples predicted. The loss of a count is `sum_c log(PRESS_c)` (the
    log-determinant of the diagonal prediction-error covariance, the measure an
    output-error fit minimises); per segment, its excess over the best count is
    that segment's share of the three normalised squared errors. The choice is the
    fewest functions whose mean excess lies within one standard error (over
    segments) of the best count: a finer spline must predict data it was not
    fitted to, in whole segments, so a misfit that is coloured in time cannot pass
    for resolution, and among counts the data cannot tell apart the coarsest is
    kept (it leaves a constant term least room to hide in the Mach functions).

    Counts are bounded by the record: at most half as many breakpoint intervals
    as segments (`knots - 3 <= segments / 2`), distinct breakpoints, and fewer
    regressors than samples in every training set.
    """
    mach = np.asarray(mach, float)
    y = np.column_stack([np.asarray(c, float) for c in coefficients])
    labels = np.unique(np.asarray(segment))
    folds = [np.asarray(segment) == s for s in labels]
    counts, per_fold = [], []
    for k in range(smallest, largest + 1):
        if k - 3 > len(labels) / 2:
            break
        breaks = mach_breakpoints(mach, k - 2, placement)
        if np.any(np.diff(breaks) <= 0):
            break
        part = MachSplineAerodynamics(
            knots=k, alpha_order=alpha_order, alpha_elevator=alpha_elevator
        )
        a = part.regressors(
            mach, np.asarray(alpha, float), np.asarray(de, float), breaks
        )
        if a.shape[1] >= len(mach) - max(f.sum() for f in folds):
            break
        # normal equations less each segment's share: one pass over the record
        a = a / np.maximum(np.sqrt(np.mean(a**2, axis=0)), 1e-300)
        gram, rhs = a.T @ a, a.T @ y
        sse = np.zeros((len(folds), y.shape[1]))
        for i, out in enumerate(folds):
            ao = a[out]
            theta = np.linalg.lstsq(gram - ao.T @ ao, rhs - ao.T @ y[out], rcond=None)[
                0
            ]
            sse[i] = np.sum((y[out] - ao @ theta) ** 2, axis=0)
        counts.append(k)
        per_fold.append(sse)
    if not counts:
        raise ValueError(
            f"the log's Mach number does not vary enough for {smallest} spline knots"
        )
    per_fold = np.array(per_fold)  # (counts, folds, 3)
    press = per_fold.sum(axis=1)
    loss = np.log(press).sum(axis=1)
    best = int(np.argmin(loss))
    # each segment's normalised squared error, to first order the loss difference
    share = (per_fold / press[best]).sum(axis=2) * len(folds)  # (counts, folds)
    diff = share - share[best]
    excess = diff.mean(axis=1)
    stderr = diff.std(axis=1, ddof=1) / np.sqrt(len(folds))
    pick = next(i for i in range(len(counts)) if excess[i] <= stderr[i])
    return KnotChoice(
        knots=counts[pick],
        candidates=tuple(counts),
        loss=tuple(float(v) for v in loss),
        excess=tuple(float(v) for v in excess),
        excess_stderr=tuple(float(v) for v in stderr),
        segments=len(folds),
        placement=placement,
    )
