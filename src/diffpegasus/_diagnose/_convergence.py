"""When the workflow's global fit stops: a budget rather than a cap, and, when it does
not converge, why and what to try, in words (a diagnosis at such a fit measures the
fit's leftovers, not the log, so no effect is declared significant there)."""

import dataclasses
import sys

import equinox as eqx
import jax.numpy as jnp
import numpy as np


def progress(message: str) -> None:
    """A progress line on the terminal (standard error, so JSON output stays
    clean)."""
    print(message, file=sys.stderr, flush=True)


def fit_budget(fit, iterations: int, settings):
    """`fit` (a `ModelFit` of one or more rounds) with its total `iterations`."""
    del settings
    result = eqx.tree_at(lambda g: g.iterations, fit.result, jnp.asarray(iterations))
    return dataclasses.replace(fit, result=result)


def why_not_converged(fit, max_iter: int) -> str | None:
    """`None` for a converged fit; else why it stopped and what to try, in one
    sentence.

    **Arguments:** `fit` a `ModelFit`; `max_iter` the budget it was given.
    """
    result = fit.result
    if bool(result.converged):
        return None
    its = int(result.iterations)
    defect = float(result.defect)
    if not np.isfinite(fit.cost) or not np.all(np.isfinite(np.asarray(result.params))):
        return (
            f"the fit stopped after {its} iterations on non-finite values (a "
            "shooting segment diverged): try a shorter --node-interval, check the "
            "log's units and sample times with `diffpegasus check`"
        )
    reasons = [f"det(R) was still falling after {its} iterations (the budget)"]
    if defect > 1.0:
        reasons.append(
            f"the shooting segments do not join (largest continuity defect {defect:.2g} "
            "of the state scale)"
        )
    tries = [f"--max-iter {max(2 * max_iter, its + 100)}"]
    if defect > 1.0:
        tries.append("a shorter --node-interval")
    tries.append("a lower --knots or --alpha-order if the log excites little")
    return (
        f"the output-error fit did not converge: {'; '.join(reasons)}. Try "
        f"{', or '.join(tries)}. The effects' statistics at an unconverged fit measure "
        "the fit's leftovers, so none is declared significant"
    )
