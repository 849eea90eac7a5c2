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

[`sensor_estimates`][] linearises the joint fit and takes, for each sensor, the
Gauss-Newton step its residuals alone ask for (the parameters it does not see held),
with its coloured-residual covariance (Morelli and Klein's correction, as the fit's
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
    disagree beyond it).
    """

    outputs: tuple[str, ...]
    knots: np.ndarray
    covariances: np.ndarray
    tau: np.ndarray
    birge: float


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


def sensor_estimates(fit, compared: tuple[str, ...]):
    """Each output channel's own estimate of the parameters `compared`, from a
    joint output-error `fit`: one Gauss-Newton step from the joint optimum on that
    channel's residuals alone (the estimated parameters it carries information on
    free, the others held at the joint values), and its coloured-residual
    covariance (the joint fit's residual autocorrelation, per channel).

    **Returns:** `(estimates (channels, k), covariances (channels, k, k))`, channels
    in the model's output order.
    """
    import equinox as eqx
    import jax.numpy as jnp

    from .._estimate._engine import coloured_information, evaluate, row_jacobian

    model = fit.model
    names = list(model.parameters)
    nx, p = len(model.states), len(names)
    z = jnp.asarray(fit.z)
    ev = eqx.filter_jit(evaluate)(model, fit.layout, z, nx, p)
    w = 1.0 / np.sqrt(np.asarray(fit.R))
    jy = np.where(np.asarray(fit.layout.valid)[..., None, None], -np.asarray(ev.jy), 0)
    jyw = jy * w[None, None, :, None]
    ew = (np.asarray(ev.e) * w[None, None, :]).reshape(-1, len(w))
    free = np.flatnonzero(np.asarray(fit.free))
    cols = np.zeros((z.shape[0], free.size))
    cols[fit.nodes.size + free, np.arange(free.size)] = 1.0
    jw = np.asarray(row_jacobian(fit.layout, jnp.asarray(jyw), cols, nx, p))
    # the samples only: a segment's padding would count in the autocovariance's
    # normalisation (161 samples padded to 176 read 9% less variance)
    valid = np.asarray(fit.layout.valid).reshape(-1)
    jw, ew = jw[valid], ew[valid]
    idx = [list(free).index(names.index(c)) for c in compared]
    params = np.asarray(fit.params)[free]
    estimates, covariances = [], []
    for o in range(jw.shape[1]):
        j, e = jw[:, o, :], ew[:, o]
        m = j.T @ j
        scale = np.sqrt(np.diag(m))
        # a parameter this channel carries (numerically) no information on is held
        seen = scale > 1e-8 * np.sqrt(np.max(np.diag(m)))
        js = j[:, seen] / scale[seen]
        inv = np.linalg.pinv(js.T @ js, rcond=1e-12)
        step = np.zeros(free.size)
        # j is the residual's Jacobian (minus the model's): the step is -J^+ e
        step[seen] = -(inv @ (js.T @ e)) / scale[seen]
        outer = np.asarray(coloured_information(js[:, None, :], e[:, None]))
        cov = np.zeros((free.size, free.size))
        cov[np.ix_(seen, seen)] = (inv @ outer @ inv) / np.outer(
            scale[seen], scale[seen]
        )
        estimates.append((params + step)[idx])
        covariances.append(cov[np.ix_(idx, idx)])
    return np.array(estimates), np.array(covariances)


def structural_spread(result) -> Spread | None:
    """The [`Spread`][] of a rocket fit's drag knots between each of its sensors
    alone and the joint fit (`None` with one sensor: nothing to compare).

    A barometer alone tells drag from thrust and the day's atmosphere hardly at all
    (its own knots' standard errors above 1 on RocketPy's flights), so the two
    sensors' curves are not compared with each other but each with the joint fit,
    as Hausman's test compares an efficient estimator with a consistent one: with a
    model right for both, the joint knots and one sensor's differ by noise of
    covariance `C_sensor - C_joint`; beyond it, by the model's structural error.
    Each knot's `tau` is the larger of the sensors' [`between_variance`][], over
    the sensors that tell that knot from zero on their own; the Birge ratio is the whole difference's against that covariance (in the directions
    where it is positive).
    """
    if result.fit is None or len(result.outputs) < 2:
        return None
    fit = result.fit
    names = list(fit.model.parameters)
    knots = result.knots.names
    idx = [names.index(k) for k in knots]
    if not all(fit.free[i] for i in idx):
        return None
    x, c = sensor_estimates(fit, knots)
    scale = float(fit.params[names.index("cd_scale")])
    x, c = x * scale, c * scale**2
    sd = np.asarray(fit.stderr_corrected)[idx] * scale
    joint_cov = np.asarray(fit.correlation)[np.ix_(idx, idx)] * np.outer(sd, sd)
    joint = np.asarray(fit.params)[idx] * scale
    tau2 = np.zeros(len(knots))
    birge = 0.0
    for xs, cs in zip(x, c, strict=True):
        d, v = joint - xs, cs - joint_cov
        # a knot this sensor alone cannot tell from zero (its own 95% band wider
        # than its estimate) it does not measure: a barometer alone, its drag
        # confounded with thrust and the day's air, steps 3 CD units away with
        # standard errors of 2, far outside the linearisation
        told = np.abs(xs) > 1.96 * np.sqrt(np.clip(np.diag(cs), 0, None))
        tau2 = np.maximum(tau2, np.where(told, between_variance(d, np.diag(v)), 0))
        w, u = np.linalg.eigh((v + v.T) / 2)
        keep = w > 1e-12 * max(float(w.max()), 1e-300)
        if keep.any():
            q = float(np.sum((u[:, keep].T @ d) ** 2 / w[keep]))
            birge = max(birge, float(np.sqrt(q / keep.sum())))
    return Spread(tuple(result.outputs), x, c, np.sqrt(tau2), birge)
