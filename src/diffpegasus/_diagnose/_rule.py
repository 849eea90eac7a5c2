"""The decision rule of a diagnosis, one function for every path: the engine's
[`score_candidates`][] / [`diagnose_model`][] (`diagnose --vehicle/--model`) and the
Pegasus workflow ([`diffpegasus.discrepancy.diagnose`][]).

A candidate is **significant** when its score statistic (1 degree of freedom,
variance with the residuals' colour and their covariance between outputs) exceeds
a **threshold taken from the log itself**: the `1 - significance` point of the
largest statistic over all candidates when residuals are drawn from the
autoregression fitted to the fit's residuals (a sieve bootstrap, [`calibrate`][]), so it holds the family-wise false-alarm level
`significance` for the whole diagnosis whatever the residuals' colour, their
correlation between outputs, how many candidates there are and how alike they
are. No constant is tuned on any simulator. Effects are found one at a time: the
others are tested again given each one found ([`DecisionRule.decide`][]).

Why not chi-square: the statistic's variance is estimated from one record of
coloured residuals, and that estimate scatters; the studentised statistic's null
has much heavier tails than chi-square (see the validation page "decision rule").

An actuator delay is significant only if it also exceeds half a log sample interval
(where an input's steps fall between samples moves each by up to that much, so a
smaller one is a `resolution_limit`, not physics); a lead (negative delay) is never
significant. The predicted fall of det(R) (`cost_reduction`, the candidate's share
of the misfit) is reported, not decided on. Significant candidates are listed
first.

What no resampling of residuals can do: tell a structural misfit of the baseline
that happens to look like a candidate (it is systematic, aligned with the
manoeuvre like an effect) from the effect. Such a misfit, once the noise is low
enough, is reported as the effect it resembles, with its size.
"""

import dataclasses
from collections.abc import Sequence

import numpy as np

from ._calibration import calibrate, Calibration, statistics


DELAY_EFFECT = "actuator_delay"

# sensitivities (free unknowns projected out) correlated beyond this are said to be
# hard to tell apart: with |rho| = 0.9 a 1-sigma difference in one is 2.3 sigma of
# the difference of the two (1 / sqrt(1 - rho^2))
_ALIKE = 0.9


@dataclasses.dataclass(frozen=True)
class DecisionRule:
    """`significance`: the family-wise false-alarm level of a diagnosis;
    `replicates`: bootstrap replicates of the null (at least `5 / significance`);
    `seed`: of the bootstrap (the same log gives the same threshold)."""

    significance: float = 0.01
    replicates: int = 2000
    seed: int = 0

    def calibrate(self, rows, residuals, curvature, slope, resample=None, basis=None):
        """The null of a score test's parts (valid samples) from its own
        residuals (`resample`, default `residuals`, is the series resampled;
        `basis` the fit's refit operator, see [`calibrate`][])."""
        import jax

        return calibrate(
            rows,
            residuals,
            curvature,
            slope,
            level=self.significance,
            replicates=self.replicates,
            key=jax.random.key(self.seed),
            resample=resample,
            basis=basis,
        )

    def decide(
        self,
        test,
        effects: Sequence[str],
        parameters: Sequence[str],
        *,
        delays: Sequence[bool],
        resolution: float,
    ) -> tuple[list[dict], list[Calibration]]:
        """Judge every candidate of a score test, one effect at a time.

        The largest statistic is judged against the threshold of its family (all
        candidates not yet found); if it passes, the effect is found, and the rest
        are tested again **given** it: their sensitivities and scores with the
        found one's projected out, the residuals with its step taken (to first
        order what a refit with the effect added gives), against a threshold
        calibrated again on those residuals. So a strong effect's signature, which
        every correlated candidate partly picks up, makes one finding, not several.
        Only the first finding is `significant`: the later ones (`found_given`)
        were judged given it to first order, and a large effect's step leaves a
        remainder the others pick up (a planted 0.04 s delay on a 200 Hz
        Pegasus-like flight: three more "found" given it); they are confirmed by
        adding the first and diagnosing again.
        A lead or a sub-resolution delay is never found, but when it passes, the
        rest are tested given it too (its signature, the log's timing, is in the
        residuals).

        **Arguments:** `test` a [`ScoreTest`][] of the `k` candidates; `effects` and
        `parameters` their names (effect, and the parameter it estimates); `delays`
        which are input delays; `resolution` half the log's sample interval, s.

        **Returns:** `(ranking, calibrations)` (one calibration per step): one row
        per candidate, significant ones first (in the order found), the others by
        predicted fall of det(R): `effect`, `parameter`, `cost_reduction`,
        `statistic` and `p_value` (family-wise) at the fit as given, `estimate`,
        `stderr`, `significant`, `resolution_limit`, `lead` (a negative delay),
        `hard_to_tell_from` (`[{"effect", "correlation"}]`), `threshold`,
        `false_alarm_level`, `null_replicates`, `null_order` (the first step's
        calibration); after a finding, `given` (the effects found before) with
        `statistic_given` and `threshold_given` (where it was last judged).
        """
        valid = np.asarray(test.valid, bool)
        rows = np.asarray(test.rows)[valid]
        resid = np.array(np.asarray(test.residuals)[valid], float)
        basis = getattr(test, "basis", None)
        if basis is not None:
            basis = np.asarray(basis)[valid]
            # held unknowns have zero columns: only the free ones are resampled
            basis = basis[..., np.any(basis != 0.0, axis=(0, 1))]
        rows, s, g, informed = informed_parts(rows, test.curvature, test.slope)
        est = np.asarray(test.estimate, float)
        with np.errstate(invalid="ignore", divide="ignore"):
            start = est + g / s  # the held values
        corr = np.where(np.outer(informed, informed), test.correlation, 0.0)
        corr[~informed, ~informed] = 1.0
        h = corr * np.sqrt(np.outer(s, s))
        pool = informed.copy()
        found: list[int] = []
        taken: list[int] = []  # found, and signatures that are not findings
        judged: dict[int, tuple[float, float, list[str]]] = {}
        cals = []
        while True:
            stat = statistics(rows, resid, s, g)
            top = int(np.argmax(np.where(pool, stat, -np.inf)))
            # the null of this step resamples the residuals the fit would leave
            # with the strongest candidate freed: the baseline's other misfit
            # stays in, the tested signature does not widen its own null
            resample = resid - (g[top] / s[top]) * rows[..., top]
            cal = self.calibrate(rows, resid, s, g, resample, basis)
            cals.append(cal)
            now = start - g / s
            given = [effects[j] for j in taken]
            for i in np.flatnonzero(pool):
                judged[i] = (float(stat[i]), cal.threshold, given)
            ok = pool & (stat > cal.threshold)
            if not ok.any():
                break
            j = int(np.argmax(np.where(ok, stat, -np.inf)))
            taken.append(j)
            # a lead or a sub-sample delay is never a finding, but its signature is
            # in the residuals (the log's timing): the rest are tested given it too
            if not (delays[j] and (now[j] < 0.0 or abs(now[j]) < resolution)):
                found.append(j)
            # first order: the fit with j freed (its step taken, the others'
            # directions and scores with j projected out; a Schur complement)
            c = h[:, j] / s[j]
            resid = resid - (g[j] / s[j]) * rows[..., j]
            rows = rows - rows[..., j][..., None] * c[None, None, :]
            g = g - c * g[j]
            s_new = s - c * h[j, :]
            h = h - np.outer(c, h[j, :])
            pool[j] = False
            # what j explains entirely (a collinear candidate) leaves the family
            gone = pool & (s_new <= 1e-9 * s)
            pool &= ~gone
            out = ~pool
            rows[..., out] = 0.0
            g[out] = 0.0
            s = np.where(out, 1.0, s_new)
        first = cals[0]
        stat0 = np.asarray(test.statistic, float)
        p = first.p_values(stat0)
        reduction = 1.0 - np.asarray(test.cost_ratio, float)
        ranking = []
        for i, name in enumerate(effects):
            passes = bool(informed[i] and stat0[i] > first.threshold)
            lead = bool(delays[i] and est[i] < 0.0)
            limited = bool(delays[i] and passes and abs(est[i]) < resolution)
            close = [
                {"effect": effects[j], "correlation": float(corr[i, j])}
                for j in np.argsort(-np.abs(corr[i]))
                if j != i and abs(corr[i, j]) > _ALIKE
            ]
            row = {
                "effect": name,
                "parameter": parameters[i],
                "cost_reduction": float(reduction[i]),
                "statistic": float(stat0[i]),
                "p_value": float(p[i]),
                "estimate": float(est[i]),
                "stderr": float(np.asarray(test.stderr)[i]),
                # the first finding; later ones were judged given it to first
                # order only (a large effect's step leaves a remainder the others
                # pick up): confirmed by adding it and diagnosing again
                "significant": bool(found) and i == found[0],
                "found_given": i in found[1:],
                "resolution_limit": limited,
                "lead": bool(lead and passes),
                # no sensitivity in this log: not scored (its statistic undefined)
                "uninformed": not bool(informed[i]),
                "hard_to_tell_from": close,
                "threshold": first.threshold,
                "false_alarm_level": first.level,
                "null_replicates": int(first.maxima.shape[0]),
                "null_order": first.order,
            }
            if i in judged and judged[i][2]:
                row["given"] = judged[i][2]
                row["statistic_given"] = judged[i][0]
                row["threshold_given"] = judged[i][1]
            ranking.append(row)
        order = {j: n for n, j in enumerate(found)}
        ranking.sort(
            key=lambda r: (
                order.get(effects.index(r["effect"]), len(found)),
                r["uninformed"],
                -np.nan_to_num(r["cost_reduction"], nan=-np.inf),
            )
        )
        return ranking, cals


def informed_parts(rows, curvature, slope):
    """The score test's parts as the rule reads them: `(rows, curvature, slope,
    informed)`, a candidate this log holds no information on (no sensitivity: a
    rail's friction on a vertical rail) with zero rows, unit curvature and zero
    slope, so that it leaves the family as a padded one does (statistic 0) instead
    of making every threshold undefined. `rows` `(samples, ..., k)`; new arrays."""
    rows = np.array(rows, float)
    s = np.array(curvature, float)
    g = np.array(slope, float)
    informed = (
        np.isfinite(s)
        & (s > 0.0)
        & np.isfinite(g)
        & np.all(np.isfinite(rows), axis=tuple(range(rows.ndim - 1)))
    )
    rows[..., ~informed] = 0.0
    g = np.where(informed, g, 0.0)
    s = np.where(informed, s, 1.0)
    return rows, s, g, informed


def rule_summary(ranking: list[dict]) -> dict:
    """The rule a ranking was decided by, as JSON: `{"text", "threshold",
    "false_alarm_level", "replicates", "null_order", "method"}` (from its rows,
    as [`DecisionRule.decide`][] makes them)."""
    if not ranking:
        return {"text": "no candidate was tested"}
    r = ranking[0]
    return {
        "text": (
            f"significant: score statistic above {r['threshold']:.3g}, the "
            f"{100 * (1 - r['false_alarm_level']):g}% point of the largest statistic "
            f"over all candidates in {r['null_replicates']} sieve-bootstrap "
            f"replicates of this fit's residuals (an autoregression of order "
            f"{r['null_order']} fitted to them): a false-alarm level of {r['false_alarm_level']:g} for the "
            "whole diagnosis; an actuator delay also needs at least half a log "
            "sample, a lead never is; the cost fall is the share of the misfit, "
            "reported, not decided on"
        ),
        "threshold": r["threshold"],
        "false_alarm_level": r["false_alarm_level"],
        "replicates": r["null_replicates"],
        "null_order": r["null_order"],
        "method": "parametric bootstrap: residuals from the autoregression fitted "
        "to the fit's residuals (sieve), through the efficient score at the "
        "fitted Jacobian, max over candidates",
    }


def _names(row) -> list[str]:
    return [c if isinstance(c, str) else c["effect"] for c in row["hard_to_tell_from"]]


def verdict(ranking: list[dict], resolution: float) -> str:
    """The message of a diagnosis: every significant candidate with its statistic
    against the threshold, its family-wise p-value (the evidence) and its share of
    det(R) (how much of the misfit it explains), said apart, and which candidates
    the data cannot tell it from; or plainly that none is; every delay that is only
    a resolution limit of the log, and every lead. Rows as
    [`DecisionRule.decide`][] makes them."""
    if not ranking:
        return "no candidate effect was tested"
    threshold = ranking[0]["threshold"]
    significant = [r for r in ranking if r["significant"]]
    if not significant:
        # a lead or a sub-sample delay is never a finding (said below): the
        # strongest candidate that could have been one is the one to report
        possible = [
            r
            for r in ranking
            if not (r.get("lead") or r.get("resolution_limit") or r.get("uninformed"))
        ]
        if not possible:
            return (
                "no candidate effect was scored: this log holds no information on any"
            )
        strongest = max(possible, key=lambda r: r["statistic"])
        if strongest["statistic"] > threshold and strongest.get("given"):
            where = (
                f"above the threshold {threshold:.3g} from this log's residuals "
                f"alone, but given {', '.join(strongest['given'])} "
                f"{strongest['statistic_given']:.3g}, below the threshold "
                f"{strongest['threshold_given']:.3g} there"
            )
        else:
            where = f"below the threshold {threshold:.3g} from this log's residuals"
        message = (
            "no candidate effect is significant: the model explains the data as "
            "well as any single library effect would (the strongest, "
            f"{strongest['effect']}, has statistic {strongest['statistic']:.3g}, "
            f"{where}; family-wise p {strongest['p_value']:.2g})"
        )
    else:
        parts = []
        for r in significant:
            if r.get("given"):
                evidence = (
                    f"given {', '.join(r['given'])}: score statistic "
                    f"{r['statistic_given']:.3g} > threshold {r['threshold_given']:.3g}"
                )
            else:
                evidence = (
                    f"score statistic {r['statistic']:.3g} > threshold "
                    f"{threshold:.3g}, family-wise p {r['p_value']:.2g}"
                )
            text = (
                f"{r['effect']} is significant ({evidence}) and explains "
                f"{100 * r['cost_reduction']:.0f}% of det(R): "
                f"{r['parameter']} = {r['estimate']:.4g} +/- {r['stderr']:.2g}"
            )
            close = _names(r)
            if close:
                text += f"; the data cannot tell it apart from {', '.join(close)}"
            parts.append(text)
        message = ". ".join(parts)
    later = [r["effect"] for r in ranking if r.get("found_given")]
    if later:
        message += (
            f". Given it, {', '.join(later)} also pass (to first order): add "
            f"{significant[0]['effect']} and diagnose again to tell"
        )
    for r in ranking:
        if r.get("uninformed"):
            message += (
                f". {r['effect']} was not scored: this log holds no information on "
                "it (its sensitivity is zero)"
            )
        if r["resolution_limit"]:
            message += (
                f". {r['effect']} = {r['estimate']:.2g} s is below half a log sample "
                f"({resolution:.2g} s): a resolution limit of the log (where input "
                "steps fall between samples), not physics"
            )
        if r.get("lead"):
            message += (
                f". {r['effect']} = {r['estimate']:.2g} s would be a lead (the "
                "surface moving before its command): not physical, never "
                "significant; check the time stamps of the logged input"
            )
    return message


def ranking_lines(ranking: list[dict], top: int = 8) -> list[str]:
    """The ranking for a terminal: significant rows marked `*`, and beside every
    row the candidates the data cannot tell it from."""
    lines = [
        f"  {'effect':>24s} {'statistic':>9s} {'p (fw)':>8s} {'cost fall':>9s} "
        f"{'estimate':>12s} {'std err':>9s}"
    ]
    for r in ranking[:top]:
        mark = "*" if r["significant"] else " "
        line = (
            f"{mark} {r['effect']:>24s} {r['statistic']:9.1f} {r['p_value']:8.2g} "
            f"{100 * r['cost_reduction']:8.1f}% {r['estimate']:12.4g} "
            f"{r['stderr']:9.2g}"
        )
        if not r["significant"] and r.get("given"):
            line += (
                f"  given {', '.join(r['given'])}: {r['statistic_given']:.1f} "
                f"{'<' if r['statistic_given'] <= r['threshold_given'] else '>'} "
                f"{r['threshold_given']:.3g}"
            )
        close = _names(r)
        if close:
            line += f"  cannot be told from {', '.join(close)}"
        lines.append(line)
    return lines
