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
    `statistic` (each count's likelihood-ratio statistic against the finest,
    `(m,)`), `dof` (its degrees of freedom, `(m,)`) and `p_value` (`(m,)`);
    `effective_samples` (per coefficient equation, from the finest count's
    residual correlation); `level`; `placement`; `pitch_rate` (the moment judged
    through the pitch rate).
    """

    knots: int = eqx.field(static=True)
    candidates: tuple[int, ...] = eqx.field(static=True)
    statistic: tuple[float, ...] = eqx.field(static=True)
    dof: tuple[int, ...] = eqx.field(static=True)
    p_value: tuple[float, ...] = eqx.field(static=True)
    effective_samples: tuple[float, ...] = eqx.field(static=True)
    level: float = eqx.field(static=True)
    placement: str = eqx.field(static=True)
    pitch_rate: bool = eqx.field(static=True, default=False)

    def summary(self) -> dict:
        """JSON-ready: the rule in words, the choice and the table."""
        moment = (
            "CM through the pitch rate integrated over each shooting segment"
            if self.pitch_rate
            else "CM"
        )
        return {
            "rule": (
                "Mach functions per coefficient term chosen from the log: the fewest "
                "whose equation-error regressions of CL, CD and "
                f"{moment} fit as well as the finest count the record supports "
                "(likelihood ratio on effective sample sizes from the finest "
                f"count's residual correlation, level {self.level:g}; "
                f"{self.placement} breakpoints)"
            ),
            "knots": self.knots,
            "candidates": list(self.candidates),
            "statistic": list(self.statistic),
            "dof": list(self.dof),
            "p_value": list(self.p_value),
            "effective_samples": list(self.effective_samples),
        }


def segment_centred(x, segment):
    """`x` `(n,)` or `(n, k)` less its mean over each run of equal `segment`
    labels `(n,)`."""
    x = np.asarray(x, float)
    segment = np.asarray(segment)
    start = np.concatenate([[True], segment[1:] != segment[:-1]])
    run = np.cumsum(start) - 1
    sums = np.zeros((run[-1] + 1,) + x.shape[1:])
    np.add.at(sums, run, x)
    counts = np.bincount(run).reshape((-1,) + (1,) * (x.ndim - 1))
    return x - (sums / counts)[run]


def segment_integrals(x, t, segment):
    """Running trapezoid integrals of `x` `(n,)` or `(n, k)` over time `t` `(n,)`
    (s), restarted at the first sample of every run of equal `segment` labels, then
    less each run's mean ([`segment_centred`][]), `(n,)` or `(n, k)`: the
    integrated form of a rate equation over shooting segments whose start values
    are unknown (a segment's mean stands in for its start value)."""
    x = np.asarray(x, float)
    segment = np.asarray(segment)
    shape = (-1,) + (1,) * (x.ndim - 1)
    step = 0.5 * (x[1:] + x[:-1]) * np.diff(np.asarray(t, float)).reshape(shape)
    step = np.concatenate([np.zeros_like(x[:1]), step])
    start = np.concatenate([[True], segment[1:] != segment[:-1]])
    step[start] = 0.0
    total = np.cumsum(step, axis=0)
    run = np.cumsum(start) - 1
    return segment_centred(total - total[np.flatnonzero(start)[run]], segment)


class PitchRate(eqx.Module):
    """The pitch-rate form of the moment equation for [`choose_knots`][]:
    `qdot = gain CM + known`, judged on the measured pitch rate integrated over
    each segment rather than on a CM reconstructed from a pitch acceleration.

    **Fields:** `t` (s), `q` (rad/s), `gain` (`qbar S c / Iyy`, rad/s^2 per unit
    CM), `known` (the rest of qdot from logged channels, rad/s^2); each `(n,)`.
    """

    t: np.ndarray
    q: np.ndarray
    gain: np.ndarray
    known: np.ndarray


def effective_samples(r) -> float:
    """Samples of a residual `r` `(n,)` worth as many independent ones, from its
    lag-one correlation `rho` (first-order autoregression: `n (1 - rho) / (1 +
    rho)`, `rho` clipped to `[0, 1)`)."""
    r = np.asarray(r, float) - np.mean(r)
    rho = float(np.sum(r[1:] * r[:-1]) / np.sum(r * r))
    rho = min(max(rho, 0.0), 1.0 - 1e-12)
    return len(r) * (1.0 - rho) / (1.0 + rho)


def _residual(x, y):
    """`y - x theta` at the least-squares `theta` (normal equations of unit-rms
    columns: cheap for many more samples than regressors)."""
    x = x / np.maximum(np.sqrt(np.mean(x**2, axis=0)), 1e-300)
    return y - x @ np.linalg.lstsq(x.T @ x, x.T @ y, rcond=None)[0]


def choose_knots(
    mach,
    alpha,
    de,
    coefficients: tuple,
    segment,
    *,
    pitch: PitchRate | None = None,
    placement: str = "quantile",
    alpha_order: int = 3,
    alpha_elevator: bool = True,
    smallest: int = 4,
    largest: int = 12,
    level: float = 0.01,
) -> KnotChoice:
    """The number of Mach functions the record carries: the fewest that fit it as
    well as the finest count it supports, by a likelihood-ratio test on effective
    sample sizes.

    For each count from `smallest` to `largest` the coefficients (each `(n,)`,
    reconstructed from the record, e.g. `(CL, CD, CM)`) are regressed on the
    part's regressors at `mach`, `alpha` (rad), `de` (rad). With `pitch`
    ([`PitchRate`][]) the last coefficient (the moment) enters in its integrated
    form instead: the measured pitch rate less the integral of `known`, regressed
    on the integrals of `gain` times the regressors, both over each `segment`
    `(n,)` (integer labels, the shooting segments) and less their segment means
    ([`segment_integrals`][]): that is how an output-error fit with a node per
    segment sees the moment, and a pitch-acceleration channel's noise hides a slow
    moment misfit that the pitch rate shows.

    Each count's statistic against the finest count `K` is `sum_c n_c log(RSS_c,k
    / RSS_c,K)`, with `n_c` the effective samples of equation `c`'s residual at
    `K` ([`effective_samples`][]: the residuals are coloured by what misfit `K`
    leaves and by the integration, so counting samples would call every extra
    function significant), chi-squared with the difference in regressors; the
    choice is the fewest functions whose p-value is at least `level` (the finest
    always qualifies). Counts are bounded by the record: at most half as many
    breakpoint intervals as segments (`knots - 3 <= segments / 2`), distinct
    breakpoints, and fewer regressors than samples.
    """
    from scipy.stats import chi2

    mach = np.asarray(mach, float)
    alpha = np.asarray(alpha, float)
    de = np.asarray(de, float)
    segment = np.asarray(segment)
    ys = [np.asarray(c, float) for c in coefficients]
    if pitch is not None:
        ys[-1] = segment_centred(pitch.q, segment) - segment_integrals(
            pitch.known, pitch.t, segment
        )
    segments = len(np.unique(segment))
    counts, rss, params, finest = [], [], [], None
    for k in range(smallest, largest + 1):
        if k - 3 > segments / 2:
            break
        breaks = mach_breakpoints(mach, k - 2, placement)
        if np.any(np.diff(breaks) <= 0):
            break
        part = MachSplineAerodynamics(
            knots=k, alpha_order=alpha_order, alpha_elevator=alpha_elevator
        )
        a = part.regressors(mach, alpha, de, breaks)
        if a.shape[1] >= len(mach):
            break
        designs = [a] * len(ys)
        if pitch is not None:
            designs[-1] = segment_integrals(
                np.asarray(pitch.gain, float)[:, None] * a, pitch.t, segment
            )
        residuals = [_residual(x, y) for x, y in zip(designs, ys, strict=True)]
        counts.append(k)
        params.append(a.shape[1])
        rss.append([float(np.sum(r**2)) for r in residuals])
        finest = residuals
    if not counts:
        raise ValueError(
            f"the log's Mach number does not vary enough for {smallest} spline knots"
        )
    n_eff = np.array([effective_samples(r) for r in finest])
    rss = np.array(rss)  # (counts, equations)
    statistic = (n_eff * np.log(rss / rss[-1])).sum(axis=1)
    dof = [len(ys) * (params[-1] - p) for p in params]
    p_value = [
        1.0 if d == 0 else float(chi2.sf(s, d))
        for s, d in zip(statistic, dof, strict=True)
    ]
    pick = next(i for i, p in enumerate(p_value) if p >= level)
    return KnotChoice(
        knots=counts[pick],
        candidates=tuple(counts),
        statistic=tuple(float(v) for v in statistic),
        dof=tuple(dof),
        p_value=tuple(p_value),
        effective_samples=tuple(float(v) for v in n_eff),
        level=level,
        placement=placement,
        pitch_rate=pitch is not None,
    )
