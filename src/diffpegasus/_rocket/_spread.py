"""The model's structural error as the log shows it: the sensors disagree.

A fit to a barometer and an accelerometer together returns one `CD(Mach)` whose
band carries the noise. Where the model cannot be right for both sensors (another
simulator's atmosphere table, its weathercocking, its boost), the joint fit puts the
misfit into `CD` and the wind, and the residuals after the fit look like noise. Each
sensor alone, with the same model, wants its own curve; where it differs from the
joint one beyond the noise, the excess measures the structural error from the log,
as metrology treats laboratories whose results disagree beyond their uncertainties
(a random effect, its variance by the moment rule of DerSimonian and Laird), and
that variance joins the band. No constant is chosen: with consistent sensors it is
zero.

[`sensor_estimates`][] fits the same model to each sensor's residuals alone, from
the joint optimum to the sensor's own converged minimum (the parameters another
sensor cannot determine on its own held at the joint values, [`determined`][]), with its
coloured-residual covariance there (Morelli and Klein's correction, as the fit's
own band); [`between_variance`][] is the random-effects variance of a difference of
two estimates, component by component; [`structural_spread`][] puts them together
for a rocket fit's drag knots.
"""

import dataclasses

import numpy as np
from jaxtyping import Float


@dataclasses.dataclass(frozen=True)
class Spread:
    """The sensors' disagreement over the drag knots.

    **Fields:** `outputs` the sensors compared; `knots` `(sensors, knots)` each
    sensor's power-off `CD` at the knots and `covariances` `(sensors, knots,
    knots)` their coloured-residual covariances; `tau` `(knots,)` the structural
    standard deviation (CD units) at each knot, carried to any Mach by the knots'
    interpolation weights in absolute value (fully correlated) and added to the
    band in quadrature; `birge` the Birge ratio of the joint knots' difference from
    a sensor's own against its noise (the largest over the sensors; above 1 they
    disagree beyond it); `fitted` `(sensors, knots)` which sensor estimated each
    knot (the others held it at the joint value); `converged` `(sensors,)` whether
    each sensor's own fit stopped at a minimum; `note` why the sensors' term was
    not computed (then `tau` is zero, the band the noise's, and the sensors'
    fields NaN), `None` when it was.
    """

    outputs: tuple[str, ...]
    knots: np.ndarray
    covariances: np.ndarray
    tau: np.ndarray
    birge: float
    fitted: np.ndarray | None = None
    converged: np.ndarray | None = None
    note: str | None = None


def between_variance(
    difference: Float[np.ndarray, " k"], variance: Float[np.ndarray, " k"]
) -> Float[np.ndarray, " k"]:
    """Random-effects variance, component by component, of a difference of two
    estimates `d` whose noise variance is `v`: the moment estimate with two
    results (DerSimonian and Laird's, metrology's treatment of laboratories that
    disagree beyond their uncertainties), `max(0, d^2 - v)`; zero where the
    difference lies within its noise."""
    d = np.asarray(difference, float)
    v = np.clip(np.asarray(variance, float), 0.0, None)
    return np.clip(d**2 - v, 0.0, None)


# Levenberg-Marquardt on one channel's residuals: stop when the cost falls by less
# than this share in an accepted step (the engine's det(R) tolerance), or when no
# damping finds a lower cost (a minimum to the model's numerical precision)
RTOL = 1e-7
MAX_STEPS = 100


@dataclasses.dataclass(frozen=True)
class SensorFits:
    """Each output channel's own converged fit from a joint output-error fit.

    **Fields:** `estimates` `(channels, k)` and `covariances` `(channels, k, k)` of
    the compared parameters (a parameter a channel holds: the joint value, variance
    0) at its own minimum; `difference` `(channels, k, k)` the noise covariance of
    the joint estimate less the channel's own (Hausman's: both linearised at the
    joint optimum as functions of every channel's noise, the held parameters'
    joint values included, coloured by each channel's residual autocovariance;
    zero rows and columns where the channel holds the parameter); `fitted`
    `(channels, k)` whether the channel estimated it; `converged`
    `(channels,)` whether its fit stopped at a minimum (else its step budget ran
    out); `steps` `(channels,)` accepted steps.
    """

    estimates: np.ndarray
    covariances: np.ndarray
    difference: np.ndarray
    fitted: np.ndarray
    converged: np.ndarray
    steps: np.ndarray


def _marginal(m: np.ndarray, keep: np.ndarray) -> np.ndarray:
    # the diagonal of the pseudo-inverse of `m` over `keep` (inf elsewhere)
    var = np.full(m.shape[0], np.inf)
    if keep.any():
        scale = np.sqrt(np.diag(m)[keep])
        ms = m[np.ix_(keep, keep)] / np.outer(scale, scale)
        var[keep] = np.diag(np.linalg.pinv(ms, rcond=1e-12, hermitian=True)) / scale**2
    return var


def determined(information: Float[np.ndarray, "channels k k"]) -> np.ndarray:
    """`(channels, k)` which parameters each channel determines on its own: those
    whose marginal variance from the channel's information alone (every other
    parameter it determines free) is at most the number of channels times the
    joint one (the summed information's): the channel carries at least an equal
    share of what the joint fit knows of them. From all the parameters it carries
    information on, the one furthest beyond its share is held, and the rest tried
    again, until every one left is within it. A barometer alone cannot tell drag
    from thrust and the day's air, an accelerometer alone barely tells the day's
    air (its own fit of a simulated clean flight, the air free, ran to 381 +/- 35 K
    for 287 +/- 1 jointly, and the drag with it): what only the sensors together
    determine is held at the joint values in each sensor's own fit."""
    info = np.asarray(information, float)
    channels, k = info.shape[:2]
    joint = _marginal(info.sum(0), np.ones(k, bool))
    out = np.zeros((channels, k), bool)
    for o, m in enumerate(info):
        scale = np.sqrt(np.clip(np.diag(m), 0, None))
        keep = scale > 1e-8 * max(float(scale.max()), 1e-300)
        while keep.any():
            excess = _marginal(m, keep) / (channels * joint)
            worst = int(np.argmax(np.where(keep, excess, -np.inf)))
            if excess[worst] <= 1.0:
                break
            keep[worst] = False
        out[o] = keep
    return out


def sensor_estimates(fit, compared: tuple[str, ...]) -> SensorFits:
    """Each output channel's own estimate of the parameters `compared`, from a
    joint output-error `fit`: the same model fitted to that channel's residuals
    alone (the other channels weighted out) by Levenberg-Marquardt from the joint
    optimum to its own converged minimum, the parameters it determines on its own
    ([`determined`][], from each channel's information at the joint optimum) free
    and the others held at the joint values (the shooting nodes too); with its
    coloured-residual covariance at its own minimum (Morelli and Klein's
    correction, as the fit's own band), and the noise covariance of its difference
    from the joint estimate.

    **Returns:** a [`SensorFits`][], channels in the model's output order.
    """
    import equinox as eqx
    import jax.numpy as jnp

    from .._estimate._engine import coloured_information, evaluate, row_jacobian

    model = fit.model
    names = list(model.parameters)
    nx, p = len(model.states), len(names)
    z0 = np.asarray(fit.z, float)
    w = 1.0 / np.sqrt(np.asarray(fit.R))
    free = np.flatnonzero(np.asarray(fit.free))
    cols = np.zeros((z0.size, free.size))
    cols[fit.nodes.size + free, np.arange(free.size)] = 1.0
    # the samples only: a segment's padding would count in the autocovariance's
    # normalisation (161 samples padded to 176 read 9% less variance)
    valid = np.asarray(fit.layout.valid).reshape(-1)
    at = eqx.filter_jit(evaluate)

    def whitened(z):
        ev = at(model, fit.layout, jnp.asarray(z), nx, p)
        jy = np.where(
            np.asarray(fit.layout.valid)[..., None, None], -np.asarray(ev.jy), 0
        )
        jw = np.asarray(
            row_jacobian(
                fit.layout, jnp.asarray(jy * w[None, None, :, None]), cols, nx, p
            )
        )
        ew = (np.asarray(ev.e) * w[None, None, :]).reshape(-1, len(w))
        return jw[valid], ew[valid]

    jw0, ew0 = whitened(z0)
    mask = determined(np.einsum("roa,rob->oab", jw0, jw0))
    idx = [list(free).index(names.index(c)) for c in compared]
    channels = jw0.shape[1]
    estimates = np.tile(np.asarray(fit.params)[free][idx], (channels, 1))
    covariances = np.zeros((channels, len(idx), len(idx)))
    difference = np.zeros((channels, len(idx), len(idx)))
    # the joint estimate's influence rows (rows, channels, parameters): its
    # linearised change for a change of each whitened sample (j is the residual's
    # Jacobian, minus the model's: the estimate moves by -M^-1 J^T e)
    normal = np.einsum("roa,rob->ab", jw0, jw0)
    joint_rows = -np.einsum(
        "ab,rob->roa", np.linalg.pinv(normal, rcond=1e-12, hermitian=True), jw0
    )
    fitted = np.zeros((channels, len(idx)), bool)
    converged = np.ones(channels, bool)
    steps = np.zeros(channels, int)
    for o in range(channels):
        mine = np.flatnonzero(mask[o])
        if mine.size == 0:
            continue
        held = np.setdiff1d(np.arange(free.size), mine)
        js, jh = jw0[:, o][:, mine], jw0[:, o][:, held]
        inverse = np.linalg.pinv(js.T @ js, rcond=1e-12, hermitian=True)
        # the channel's own estimate moves with its own samples and with the held
        # parameters' joint values (themselves moved by every channel's samples)
        own_rows = -np.einsum(
            "ab,rob->roa", inverse @ (js.T @ jh), joint_rows[:, :, held]
        )
        own_rows[:, o, :] -= js @ inverse
        rows = joint_rows[:, :, mine] - own_rows
        between = np.asarray(coloured_information(jnp.asarray(rows), jnp.asarray(ew0)))
        at_z = fit.nodes.size + free[mine]
        z, (jw, ew) = z0.copy(), (jw0, ew0)
        cost = float(np.sum(ew[:, o] ** 2))
        damping, done = 1e-3, False
        while steps[o] < MAX_STEPS and not done:
            j, e = jw[:, o, mine], ew[:, o]
            m = j.T @ j
            g = j.T @ e
            d = np.sqrt(np.clip(np.diag(m), 1e-300, None))
            ms = m / np.outer(d, d)
            while True:
                # j is the residual's Jacobian (minus the model's): the step is -J^+ e
                step = -np.linalg.solve(ms + damping * np.eye(mine.size), g / d) / d
                trial = z.copy()
                trial[at_z] += step
                jt, et = whitened(trial)
                new = float(np.sum(et[:, o] ** 2))
                if np.isfinite(new) and new < cost:
                    done = (cost - new) <= RTOL * cost
                    z, jw, ew, cost = trial, jt, et, new
                    damping = max(damping / 10, 1e-12)
                    steps[o] += 1
                    break
                damping *= 10
                if damping > 1e12:
                    done = True
                    break
        converged[o] = done
        j, e = jw[:, o, mine], ew[:, o]
        scale = np.sqrt(np.clip(np.sum(j**2, axis=0), 1e-300, None))
        js = j / scale
        inv = np.linalg.pinv(js.T @ js, rcond=1e-12, hermitian=True)
        outer = np.asarray(coloured_information(js[:, None, :], e[:, None]))
        cov = np.zeros((free.size, free.size))
        cov[np.ix_(mine, mine)] = (inv @ outer @ inv) / np.outer(scale, scale)
        estimates[o] = z[fit.nodes.size + free][idx]
        covariances[o] = cov[np.ix_(idx, idx)]
        fitted[o] = mask[o][idx]
        full = np.zeros((free.size, free.size))
        full[np.ix_(mine, mine)] = between
        difference[o] = full[np.ix_(idx, idx)]
    return SensorFits(estimates, covariances, difference, fitted, converged, steps)


def structural_spread(result) -> Spread | None:
    """The [`Spread`][] of a rocket fit's drag knots between each of its sensors
    alone and the joint fit (`None` with one sensor: nothing to compare).

    Each knot is fitted by the sensors that determine it on their own
    ([`determined`][]) and compared with the joint fit's, as Hausman's test compares
    an efficient estimator with a consistent one: with a model right for both,
    they differ by noise (of covariance `C_sensor - C_joint` when the sensor holds
    nothing; [`SensorFits`][]`.difference` with its held parameters at the joint
    values); beyond it, by the model's structural error. Each knot's `tau` is that
    sensor's [`between_variance`][] (the larger over the sensors); the Birge ratio is the whole difference's
    against its noise covariance (in the directions where it is positive).

    Only at a converged joint fit: the comparison is of minima (each sensor's
    own fit starts at the joint one and its noise is linearised there), and a
    joint fit stopped on its budget is at neither. Then no sensor is fitted, `tau`
    is zero (the band is the noise's) and `note` says why.
    """
    if result.fit is None or len(result.outputs) < 2:
        return None
    fit = result.fit
    names = list(fit.model.parameters)
    knots = result.knots.names
    idx = [names.index(k) for k in knots]
    if not all(fit.free[i] for i in idx):
        return None
    if not bool(fit.converged):
        n, k = len(result.outputs), len(knots)
        return Spread(
            tuple(result.outputs),
            np.full((n, k), np.nan),
            np.full((n, k, k), np.nan),
            np.zeros(k),
            float("nan"),
            note="the joint fit did not converge: the sensors' term not computed "
            "(it compares each sensor's own minimum with the joint one); "
            "the band is the noise's",
        )
    own = sensor_estimates(fit, knots)
    scale = float(fit.params[names.index("cd_scale")])
    x, c = own.estimates * scale, own.covariances * scale**2
    joint = np.asarray(fit.params)[idx] * scale
    tau2 = np.zeros(len(knots))
    birge = 0.0
    for xs, vs, mine in zip(x, own.difference * scale**2, own.fitted, strict=True):
        if not mine.any():
            continue
        d, v = (joint - xs)[mine], vs[np.ix_(mine, mine)]
        tau2[mine] = np.maximum(tau2[mine], between_variance(d, np.diag(v)))
        w, u = np.linalg.eigh((v + v.T) / 2)
        keep = w > 1e-12 * max(float(w.max()), 1e-300)
        if keep.any():
            q = float(np.sum((u[:, keep].T @ d) ** 2 / w[keep]))
            birge = max(birge, float(np.sqrt(q / keep.sum())))
    return Spread(
        tuple(result.outputs), x, c, np.sqrt(tau2), birge, own.fitted, own.converged
    )
