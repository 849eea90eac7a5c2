"""Which physical effects a rocket flight's fit is missing.

Each candidate is one of the model's parameters held at "absent" in the base fit
(drag knots, motor time and the accelerometer's offset and the day's atmosphere or
its scale estimated; the thrust at the catalogue's, the sensors and the wind at
none). The burn's length is held at the estimate of the fit `rocket fit` runs
where the accelerometer spans the boost (1 without one; `held_burn_scale`) and
is no candidate: free beside a held thrust it takes up part of a thrust difference,
and without an accelerometer the barometer cannot tell it from the drag (its
multiple correlation with the other parameters 0.99997 on an altitude-only flight),
so no test could name it. At the fit, every candidate held is scored at once on the
one path ([`score_candidates`][]: the score test with the free unknowns re-adjusted, its
statistic's variance from the residuals' colour), against a threshold taken from this
log (the largest statistic over all candidates in sieve-bootstrap replicates of the
fit's own residuals, at a family-wise false-alarm level), no constant. The first
finding joins the model, the flight is refitted from there, and the rest are scored
again (at most `rounds` findings). The thrust scale is one of the candidates, judged
by the same rule in the same family (a fixed chi-square quantile for its Wald
statistic had named a 0.16% thrust difference on a clean simulated flight: the
coloured-residual standard error does not carry the model's structural misfit, the
bootstrap's null does). A Mach dependence of `CD` is not a candidate:
the base fit estimates `CD` at knots over the flight's Mach range, so the model already
has it (a flat `CD` is no rocket's "absent" value; the curve with its band beside the
team's is the comparison to read). Nothing is named when no statistic passes.

A statistic that passes says an effect is there. A sensor's own effect (the
barometer's lag and its static-pressure and transonic errors, the accelerometer's
scale: each changes one sensor's reading and nothing else) must also be what the
fit's misfit is made of: freeing it must take at least half of what the fit leaves
(the predicted det(R) at most half of the fit's; `SHARE`). With thousands of samples
a barometer that departs from the model's one-lapse-rate atmosphere by less than its
noise is significant, and on an ascent it takes the lag's and the static-pressure
error's shapes (both functions of height there): RocketPy's standard-atmosphere
table (up to 3 m) made a lag pass at 33.6 and 65.5 against thresholds of 9.6 and
10.1 on two clean flights, explaining 14% and 6% of what the fit left, where every
planted barometer effect explained 91% or more (docs/rockets/simulated.md). An
effect on the flight (wind, thrust, mass, rail friction, the day's air) moves both
sensors' readings, which no sensor's own error does, and is judged by its statistic
alone: a planted 9 m/s tail wind passes at 85.6 against 8.8 while explaining 3.4%
(after it, an accelerometer scale passes at 20.1 against 9.4 explaining 0.8%, and
is not named). A round whose strongest candidate is a sensor's own effect too small
to name names nothing and ends the diagnosis: the candidates below it are scored on
the same residuals, whose largest structured part it is (on RocketPy's clean Calisto
flight a wind passes at 26.2 against 10.1 beside the lag, explaining 4%). With the GNSS position among
the outputs the wind's east and north components are candidates instead of the one
along the rail (a cross wind drifts the rocket at first order, where the barometer
and the accelerometer see it at second), flight effects judged by their statistic
alone. Without an accelerometer or a GNSS position every effect shows in the
barometer alone, and every finding must explain half (a clean 10 Hz pressure log's rail friction,
"or thrust scale or mass error or wind or barometer lag", 49.1 against 8.0,
explaining 9.9%).
"""

import dataclasses

import numpy as np

from ._identify import fit_rocket, Problem


@dataclasses.dataclass(frozen=True)
class Candidate:
    """A named effect and the parameters that carry it (their absent values are the
    problem's start values)."""

    name: str
    parameters: tuple[str, ...]


# the thrust scale: the base fit holds it at the catalogue's thrust (the motor's
# start time stays estimated); a misaligned thrust reads the same to first order
THRUST = Candidate("thrust scale (or thrust misalignment)", ("thrust_scale",))
THRUST_ABSENT = 1.0

# the share of the fit's misfit (the predicted fall of det(R)) a sensor's own effect
# explains to be named (see the module)
SHARE = 0.5
ONE_SENSOR = ("baro_lag", "static_error", "transonic_error", "accel_scale")
# with a GNSS position: the wind's components, which it alone reads at first order
GNSS_ONLY = ("wind_east", "wind_north")


def explains_enough(
    parameter: str, cost_ratio: float, barometer_alone: bool = False, gnss=False
) -> bool:
    """Whether a candidate whose statistic passes is named: one that shows in one
    sensor alone (a sensor's own effect, `ONE_SENSOR`, every effect on a log with
    the barometer alone, `barometer_alone`, and with a GNSS position, `gnss`, the
    wind's components, `GNSS_ONLY`) where freeing it leaves at most `1 - SHARE` of
    det(R) (`cost_ratio`), any other always."""
    if one_sensor(parameter, barometer_alone, gnss):
        return cost_ratio <= 1.0 - SHARE
    return True


def one_sensor(parameter: str, barometer_alone: bool, gnss: bool) -> bool:
    """Whether `parameter` shows in one sensor alone at first order (see
    `explains_enough`)."""
    return (
        parameter in ONE_SENSOR or barometer_alone or (gnss and parameter in GNSS_ONLY)
    )


def barometer_alone(problem: Problem) -> bool:
    """Whether the log's barometer is its only sensor of the flight's path (no
    accelerometer, no GNSS position)."""
    return not {"accel", "gnss_e"} & set(problem.outputs)


def candidates(problem: Problem, top_mach: float) -> list[Candidate]:
    """The candidates this flight can show: the transonic pressure error only when
    the flight came within three widths of Mach 1, air-brake drag only when the
    rocket has air brakes."""
    from .._vehicle._rocket._sensors import TRANSONIC_WIDTH

    if "gnss_e" in problem.outputs:
        # the GNSS position drifts with either component at first order
        wind = [
            Candidate("east wind", ("wind_east",)),
            Candidate("north wind", ("wind_north",)),
        ]
    else:
        # the wind along the rail's heading: a cross wind has no first-order
        # effect on the barometer and the accelerometer
        wind = [Candidate("wind", ("wind_along",))]
    out = wind + [
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
        # each scored only where the base fit holds it (see accel_covers_ascent)
        out.append(Candidate("pad temperature (atmosphere)", ("temperature",)))
        out.append(Candidate("lapse rate (atmosphere)", ("lapse_rate",)))
        out.append(Candidate("accelerometer scale", ("accel_scale",)))
    return out


def diagnose(problem: Problem, *, level: float = 0.01, rounds: int = 3):
    """Missing effects, one finding at a time (see the module docstring).

    The fits it scores at are single shooting (one segment from the pad): at a
    multiple-shooting fit the score test's first-order step let the node states
    take up a barometer's static-pressure error (RocketPy's flight with lag and
    static error planted: its statistic 12 against 74, the step predicting det(R)
    to fall to 0.37 of the base fit's where a refit takes it to 0.0004), while at
    the single-shooting fit of the same flight it scores 1586 against 43.

    **Returns:** `(named, rows, final)`: the names found in order (a finding the log
    cannot tell from other candidates, their sensitivities correlated above 0.9,
    named with them: "mass error or thrust scale", never one of the two alone), one
    row per test
    (`round`, `candidate`, `statistic`, `threshold`, `cost_ratio` (predicted det(R)
    after freeing it over det(R) now), `estimates`, `significant` (the round's
    strongest, past the threshold), `explains_enough` (see `explains_enough`),
    `not_judged` (past the threshold in a round whose strongest was too small to
    name), `uninformed`, `smallest_named`, `cannot_be_told_from`, `burn_scale_held`
    and `burn_scale_from` (see `held_burn_scale`)), and the fit with the named
    effects added.
    """
    from .._diagnose._candidates import score_candidates

    # the base fit holds the thrust at the catalogue's: a thrust scale is a
    # candidate like every other, judged by the same calibrated rule. The burn's
    # length is held too (see held_burn_scale): estimated beside a held thrust it
    # takes up part of a thrust difference (RocketPy's flight planted with a 0.94
    # thrust scale: nothing named, the static-pressure error 69.9 against 70.0;
    # held, both found as before)
    held_thrust = ("thrust_scale", "burn_scale")
    single = float(problem.record.t[-1] - problem.record.t[0]) + 1.0
    burn, burn_from = held_burn_scale(problem)
    base = fit_rocket(
        problem,
        free=(),
        hold=held_thrust,
        start={"thrust_scale": THRUST_ABSENT, "burn_scale": burn},
        shooting_interval=single,
        throw=False,
        spread=False,  # the scores do not read the band
    )
    top = float(np.max(base.mach))
    gnss = "gnss_e" in problem.outputs
    pool = [THRUST] + candidates(problem, top)
    rows, found_names, named, free = [], [], [], ()
    current = base
    for r in range(1, rounds + 1):
        model = current.fit.model
        held = {
            c.parameters[0]: c
            for c in pool
            if c.name not in found_names
            and not model.free[model.parameters.index(c.parameters[0])]
        }
        if not held:
            break
        ranking = score_candidates(current.fit, list(held), level)
        found = None
        for row in ranking:
            c = held[row["parameter"]]
            ratio = 1.0 - float(row["cost_reduction"])
            rows.append(
                {
                    "round": r,
                    "candidate": c.name,
                    "statistic": float(row["statistic"]),
                    "threshold": float(row["threshold"]),
                    "cost_ratio": ratio,
                    "estimates": {row["parameter"]: float(row["estimate"])},
                    "significant": bool(row["significant"]),
                    # what the fit's misfit is made of (see the module)
                    "explains_enough": explains_enough(
                        row["parameter"], ratio, barometer_alone(problem), gnss
                    ),
                    # no sensitivity in this log (a vertical rail's friction)
                    "uninformed": bool(row.get("uninformed", False)),
                    "smallest_named": _smallest_named(
                        row, ratio, barometer_alone(problem), gnss
                    ),
                    "cannot_be_told_from": [
                        held[c].name for c in row["hard_to_tell_from"] if c in held
                    ],
                    "burn_scale_held": burn,
                    "burn_scale_from": burn_from,
                }
            )
            if row["significant"] and rows[-1]["explains_enough"] and found is None:
                found = c
        if found is None:
            # the round's strongest is a sensor's own effect too small to name: the
            # candidates below it are scored on the same residuals, whose largest
            # structured part it is, and where they pass they take up that part too
            # (RocketPy's clean Calisto flight: a lag explaining 6%, then a wind 26.2
            # against 10.1 explaining 4%); they are not judged
            for q in rows:
                if q["round"] == r and not q["significant"]:
                    q["not_judged"] = bool(q["statistic"] > q["threshold"])
            break
        found_names.append(found.name)
        alike = next(
            q["cannot_be_told_from"]
            for q in rows
            if q["round"] == r and q["candidate"] == found.name
        )
        named.append(" or ".join([found.name, *alike]))
        free += found.parameters
        # from the current fit, the effect at its absent value
        warm = dict(zip(current.fit.model.parameters, current.fit.params, strict=True))
        warm.update({n: problem.start[n] for n in found.parameters})
        held_thrust = tuple(h for h in held_thrust if h not in free)
        current = fit_rocket(
            problem,
            free=free,
            hold=held_thrust,
            start=warm,
            shooting_interval=single,
            throw=False,
            spread=False,
        )
    _aliases(rows, found_names)
    return named, rows, current


def held_burn_scale(problem: Problem) -> tuple[float, str]:
    """The burn's length the diagnosis holds: where the accelerometer spans the boost,
    the estimate of the fit `rocket fit` runs (thrust and burn free, the default
    effects; the accelerometer's equation-error reading, the problem's start, where
    that fit fails), else the start (1 without an accelerometer). The reading is a
    start on a 0.01 grid from a drag guess: on RocketPy's flights written as a user
    would it read 0.99 on 8 of 10 where the fit finds 0.9994 to 1.0003, and held at
    0.99 the thrust scale was named on three clean flights (72 to 188 against 16 to
    36); held at the fit's, 0.0 to 8.2 against 8.5 to 34.

    **Returns:** `(burn scale, where from)`: "fit", "start" (no accelerometer over the
    boost) or "reading (the full fit did not converge)"."""
    from ._identify import accel_covers_boost

    start = float(problem.start["burn_scale"])
    covers = "accel" in problem.outputs and accel_covers_boost(
        problem.record, problem.rocket, problem.start["motor_time"]
    )
    if not covers:
        return start, "start"
    full = fit_rocket(problem, throw=False, spread=False)
    if not full.fit.converged:
        return start, "reading (the full fit did not converge)"
    return float(full.fit.params[full.fit.model.parameters.index("burn_scale")]), "fit"


def _smallest_named(row, ratio: float, barometer_alone: bool, gnss: bool) -> float:
    """The smallest effect this test names on this log: its threshold in standard
    errors, or, for an effect one sensor alone shows, the size at which it would
    explain `SHARE` of the misfit if that is larger (the predicted fall of det(R)
    grows as the estimate squared: what the fit leaves with the effect, `ratio`,
    against what it takes, `1 - ratio`)."""
    by_statistic = float(np.sqrt(row["threshold"]) * row.get("stderr", np.nan))
    taken = 1.0 - ratio
    alone = one_sensor(row["parameter"], barometer_alone, gnss)
    if not alone or not 0.0 < taken < 1.0:
        return by_statistic
    by_share = abs(float(row["estimate"])) * np.sqrt(
        ratio / taken * SHARE / (1.0 - SHARE)
    )
    return float(max(by_statistic, by_share))


def _aliases(rows, named):
    """A candidate significant in one round and not in the next, after the round's
    finding joined the model, was that finding's signature: it cannot be told from
    it on this log (a boost-coast climb's barometer lag and static-pressure error
    both peak at burnout). Added to the later row's `cannot_be_told_from`."""
    for r in rows:
        before = [
            q
            for q in rows
            if q["round"] == r["round"] - 1 and q["candidate"] == r["candidate"]
        ]
        was = bool(before) and before[0]["significant"]
        if r["round"] > 1 and not r["significant"] and was:
            finding = next(
                (
                    q["candidate"]
                    for q in rows
                    if q["round"] == r["round"] - 1
                    and q["significant"]
                    and q["candidate"] in named
                ),
                None,
            )
            if finding and finding not in r["cannot_be_told_from"]:
                r["cannot_be_told_from"] = r["cannot_be_told_from"] + [finding]
