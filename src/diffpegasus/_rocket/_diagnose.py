"""Which physical effects a rocket flight's fit is missing.

Each candidate is a set of the model's parameters held at "absent" in the base fit
(drag knots, thrust scale, motor time, accelerometer offset). Forward selection: every
candidate not yet in the model is added in turn and refitted; its Wald statistic
`theta' C^-1 theta` (the estimates of its parameters, `C` their covariance from the
coloured-residual standard errors) is compared with the chi-square quantile at a
5% family-wise level over the candidates tried (Bonferroni); the one that lowers
det(R) most among the significant joins the model, and the search repeats. The base
fit's thrust scale is tested against 1 and its knots against a constant `CD` the same
way. Nothing is named when no statistic passes.
"""

import dataclasses

import numpy as np
from scipy import stats

from ._identify import fit_rocket, Problem


@dataclasses.dataclass(frozen=True)
class Candidate:
    """A named effect and the parameters that carry it (their absent values are the
    problem's start values)."""

    name: str
    parameters: tuple[str, ...]


def candidates(problem: Problem, top_mach: float) -> list[Candidate]:
    """The candidates this flight can show: the transonic pressure error only when
    the flight came within three widths of Mach 1, air-brake drag only when the
    rocket has air brakes."""
    from .._vehicle._rocket._sensors import TRANSONIC_WIDTH

    out = [
        Candidate("wind", ("wind_east", "wind_north")),
        Candidate("rail friction", ("rail_friction",)),
        Candidate("barometer lag", ("baro_lag",)),
        Candidate("static-pressure error", ("static_error",)),
        Candidate("mass error", ("mass_offset",)),
    ]
    if top_mach > 1.0 - 3 * TRANSONIC_WIDTH:
        out.append(Candidate("transonic static-pressure error", ("transonic_error",)))
    if problem.record.inputs[:, 0].any():
        out.append(Candidate("air-brake drag", ("airbrake_cd",)))
    if "accel" in problem.outputs:
        out.append(Candidate("pad temperature (atmosphere)", ("temperature",)))
    return out


def _wald(result, names, centre):
    fit = result.fit
    idx = [fit.model.parameters.index(n) for n in names]
    d = fit.params[idx] - np.asarray(centre, float)
    sd = fit.stderr_corrected[idx]
    cov = fit.correlation[np.ix_(idx, idx)] * np.outer(sd, sd)
    try:
        return float(d @ np.linalg.solve(cov, d))
    except np.linalg.LinAlgError:
        return 0.0


def diagnose(problem: Problem, *, level: float = 0.05, rounds: int = 3):
    """Forward selection of missing effects (see the module docstring).

    **Returns:** `(named, rows, final)`: the names found in order, one row per test
    (`round`, `candidate`, `statistic`, `threshold`, `cost_ratio`, `estimates`), and
    the fit with the named effects added.
    """
    base = fit_rocket(problem, free=(), throw=False)
    top = float(np.max(base.mach))
    pool = candidates(problem, top)
    rows, named, free = [], [], ()
    knots = problem.flight.knots.names
    # tests on the base fit: thrust scale against 1, knots against a constant CD
    n_tests = len(pool) + 2
    chi = lambda k: float(stats.chi2.ppf(1 - level / n_tests, k))  # noqa: E731
    s = _wald(base, ("thrust_scale",), (1.0,))
    rows.append(
        {
            "round": 0,
            "candidate": "thrust scale",
            "statistic": s,
            "threshold": chi(1),
            "cost_ratio": 1.0,
            "estimates": {"thrust_scale": base.estimate("thrust_scale")[0]},
        }
    )
    if s > chi(1):
        named.append("thrust scale (or thrust misalignment)")
    fit = base.fit
    idx = [fit.model.parameters.index(n) for n in knots]
    sd = fit.stderr_corrected[idx]
    cov = fit.correlation[np.ix_(idx, idx)] * np.outer(sd, sd)
    diff = np.diff(np.eye(len(idx)), axis=0)
    d = diff @ fit.params[idx]
    try:
        s = float(d @ np.linalg.solve(diff @ cov @ diff.T, d))
    except np.linalg.LinAlgError:
        s = 0.0
    rows.append(
        {
            "round": 0,
            "candidate": "Mach dependence of CD",
            "statistic": s,
            "threshold": chi(len(idx) - 1),
            "cost_ratio": 1.0,
            "estimates": {},
        }
    )
    if s > chi(len(idx) - 1):
        named.append("Mach dependence of CD")
    current = base
    for r in range(1, rounds + 1):
        best = None
        for c in pool:
            if c.name in named:
                continue
            # from the current fit, the candidate at its absent value
            warm = dict(zip(current.fit.model.parameters, current.fit.params))
            warm.update({n: problem.start[n] for n in c.parameters})
            trial = fit_rocket(
                problem, free=free + c.parameters, start=warm, throw=False
            )
            centre = [problem.start[n] for n in c.parameters]
            s = _wald(trial, c.parameters, centre)
            ratio = trial.fit.cost / current.fit.cost
            ok = trial.fit.converged and s > chi(len(c.parameters)) and ratio < 1
            rows.append(
                {
                    "round": r,
                    "candidate": c.name,
                    "statistic": s,
                    "threshold": chi(len(c.parameters)),
                    "cost_ratio": ratio,
                    "estimates": {n: trial.estimate(n)[0] for n in c.parameters},
                }
            )
            if ok and (best is None or ratio < best[1]):
                best = (c, ratio, trial)
        if best is None:
            break
        named.append(best[0].name)
        free += best[0].parameters
        current = best[2]
    return named, rows, current
