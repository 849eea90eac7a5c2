"""The decision rule of a diagnosis, shared by the Pegasus workflow
([`diagnose`][diffpegasus.discrepancy.diagnose]) and the engine's
[`score_candidates`][] / [`diagnose_model`][] (`diagnose --vehicle/--model`).

A candidate is **significant** when (1) its score statistic (chi-square, 1 degree of
freedom, with a variance that includes the residuals' colour and their covariance
between outputs, so a baseline's own structural misfit counts as noise, once) gives a
Bonferroni-corrected p-value below `significance`, and (2) the statistic exceeds the
penalty `min_statistic`, set above what the baseline's structural misfit alone reaches
on clean flights (measured on two independent simulators; see the documentation's
decision-rule validation page). The predicted fall of det(R) (`cost_reduction`, the candidate's share
of the misfit) is reported beside it but does not decide: how much of det(R) an effect
removes depends on the log's noise level.

An actuator delay is judged by the log's resolution instead of the penalty: it is
significant when its p-value passes and its estimate is at least half a log sample
interval; a smaller one is a `resolution_limit` (where an input's steps fall
between samples moves each by up to half a sample, so such a delay is not physics);
a negative delay (a lead) is never significant.
"""

import dataclasses


DELAY_EFFECT = "actuator_delay"


@dataclasses.dataclass(frozen=True)
class DecisionRule:
    """`significance`: family-wise level of the Bonferroni-corrected score test;
    `min_statistic`: the penalty (coloured score statistic a candidate must exceed;
    150, above the largest measured on clean flights, 102, see the module)."""

    significance: float = 0.01
    min_statistic: float = 150.0

    def judge(
        self,
        *,
        statistic: float,
        p_value: float,
        estimate: float,
        tested: int,
        is_delay: bool,
        resolution: float,
    ) -> dict:
        """`{"p_value", "significant", "resolution_limit"}` of one candidate:
        `p_value` is the raw one (1 dof chi-square) of `statistic`, returned
        Bonferroni-corrected over the `tested` candidates; `estimate` is the
        candidate's one-step estimate (a delay in s); `resolution` half the log's
        sample interval, s."""
        p = float(min(1.0, p_value * tested))
        passes = p < self.significance
        if is_delay:
            significant = bool(passes and estimate >= resolution)
            limited = bool(abs(estimate) < resolution and not significant)
        else:
            significant = bool(passes and statistic > self.min_statistic)
            limited = False
        return {"p_value": p, "significant": significant, "resolution_limit": limited}

    def describe(self) -> str:
        return (
            f"significant: Bonferroni p < {self.significance:g} and coloured score "
            f"statistic > {self.min_statistic:g} (an actuator delay: p and at least "
            "half a log sample); the cost fall is the share of the misfit, reported, "
            "not decided on"
        )


def verdict(ranking: list[dict], rule: DecisionRule, resolution: float) -> str:
    """The message of a diagnosis: which candidate is significant, with its
    statistic and p-value (the evidence) and its share of det(R) (how much of the
    misfit it explains), said apart; or plainly that none is; and every delay
    that is only a resolution limit of the log. `ranking` rows need `effect`,
    `parameter`, `statistic`, `p_value`, `cost_reduction`, `estimate`, `stderr`,
    `significant`, `resolution_limit`, `hard_to_tell_from` (names)."""
    significant = [r for r in ranking if r["significant"]]
    if not significant:
        message = (
            "no candidate effect is significant: the model explains the data as "
            "well as any single library effect would"
        )
        strongest = max(ranking, key=lambda r: r["statistic"], default=None)
        if (
            strongest is not None
            and strongest["p_value"] < rule.significance
            and not strongest["resolution_limit"]
        ):
            message += (
                f" (the strongest, {strongest['effect']}, has statistic "
                f"{strongest['statistic']:.0f}, below the {rule.min_statistic:g} "
                "that a baseline's own structural misfit reaches on clean flights)"
            )
    else:
        top = significant[0]
        message = (
            f"{top['effect']} is significant (score statistic {top['statistic']:.0f}, "
            f"p {top['p_value']:.2g}) and explains {100 * top['cost_reduction']:.0f}% "
            f"of det(R): {top['parameter']} = {top['estimate']:.4g} +/- "
            f"{top['stderr']:.2g}"
        )
        close = [
            c if isinstance(c, str) else c["effect"] for c in top["hard_to_tell_from"]
        ]
        if close:
            message += f"; the data cannot tell it apart from {', '.join(close)}"
    for r in ranking:
        if r["resolution_limit"] and r["p_value"] < rule.significance:
            message += (
                f". {r['effect']} = {r['estimate']:.2g} s is below half a log sample "
                f"({resolution:.2g} s): a resolution limit of the log (where input "
                "steps fall between samples), not physics"
            )
    return message
