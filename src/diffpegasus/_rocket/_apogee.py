"""How far to trust a predicted apogee: the fit's covariance and the held
atmosphere's uncertainty carried to the apogee through the flight model.

The apogee of a [`RocketFit`][] is a function of its parameters alone (the flight
flown from the pad, RK4 at the record's step); [`apogee_function`][] writes it in
JAX, so its gradient is exact to the integrator. [`apogee_band`][] propagates the
estimates' covariance (coloured-residual standard errors and their correlations,
as `CD`'s band) through that gradient, and adds what the parameters the fit held
contribute at a stated physical uncertainty (by default the day's temperature and
lapse rate, which a few seconds of log cannot tell from the drag).
"""

import dataclasses

import numpy as np


# K: the pad's temperature as the rocket file states it (a thermometer or a
# weather report near the pad) or, without one, the standard atmosphere's at the
# pad's pressure, from which a day departs by tens of kelvin with the season
TEMPERATURE_SIGMA = {True: 2.0, False: 10.0}
# K/km: a day's mean lapse below a few km lies between the dry adiabat (-9.8) and
# about -3; taken uniform over that range about the standard -6.5: 6.8/sqrt(12)
LAPSE_SIGMA = 2.0


@dataclasses.dataclass(frozen=True)
class ApogeeBand:
    """A predicted apogee and its standard error.

    **Fields:** `apogee` m (barometric, as the log reports it; the fit's own),
    `stderr` m (all terms), `stderr_fit` m (the estimated parameters' covariance
    alone), `gradient` (name -> m per unit of the parameter, estimated and held,
    the estimates fixed), `held` (name -> `(sigma, contribution m)`, the held
    parameters' terms, the estimates following them), `held_gradient` (name -> m
    per unit of the held parameter, the estimates following it).
    """

    apogee: float
    stderr: float
    stderr_fit: float
    gradient: dict
    held: dict
    held_gradient: dict = dataclasses.field(default_factory=dict)

    @property
    def half_width(self) -> float:
        """m, the 95% half-width (1.96 standard errors)."""
        return 1.96 * self.stderr


def held_sigmas(result) -> dict:
    """name -> the physical standard uncertainty of the held parameters the band
    carries: the pad temperature (K; 2 stated in the rocket file, 10 from the
    standard atmosphere) and the lapse rate (K/km, 2), where the fit held them."""
    free = dict(zip(result.fit.model.parameters, result.fit.free, strict=True))
    stated = result.rocket.surface_temperature is not None
    sigmas = {"temperature": TEMPERATURE_SIGMA[stated], "lapse_rate": LAPSE_SIGMA}
    return {k: v for k, v in sigmas.items() if k in free and not free[k]}


def apogee_function(result, extra: float = 30.0):
    """`params (params,) -> apogee` m, the barometric apogee of `result`'s flight
    flown from the pad with the full parameter vector `params` (the model's order),
    a jitted JAX function: the flight as the engine flies it (`flown_states`, RK4
    at the record's step over the record and `extra` s beyond it), the peak sample
    within the trajectory's own cut (`apogee_cut`: up to a second after the climb
    rate's first sign change), refined by the parabola through it and its
    neighbours (smooth in the parameters where the sample maximum steps)."""
    import jax
    import jax.numpy as jnp

    from .._estimate._fit import flown_states
    from ._identify import _long_record, _observed, apogee_cut

    model = result.fit.model
    record = result.record
    t, inputs, long = _long_record(record, extra)
    n = len(t)
    names = model.parameters
    flight = result.flight

    def apogee(params):
        xs = flown_states(model, long, params)
        baro = _observed(flight, t, xs, inputs, params, names)[:, 0]
        within = jnp.arange(n) < apogee_cut(jnp.asarray(t), xs[:, 5], record.dt)
        i = jnp.argmax(jnp.where(within, jax.lax.stop_gradient(baro), -jnp.inf))
        i = jnp.clip(i, 1, n - 2)
        y0, y1, y2 = baro[i - 1], baro[i], baro[i + 1]
        curve = y0 - 2.0 * y1 + y2
        # the parabola's vertex; `safe` keeps the branch not taken finite, so that
        # reverse mode does not carry its NaN into the gradient where curve is 0
        safe = jnp.where(curve < 0, curve, -1.0)
        return jnp.where(curve < 0, y1 - (y2 - y0) ** 2 / (8.0 * safe), y1)

    return jax.jit(apogee)


def outputs_function(result):
    """`params (params,) -> outputs (samples, outputs)`, the measured channels of
    `result`'s flight flown from the pad at its record's samples (zero where the
    record has no sample: past the prediction's cut, a channel's gaps), a jitted
    JAX function (the single-shooting model of the fit's data, `flown_states`)."""
    import jax
    import jax.numpy as jnp

    from .._estimate._fit import flown_states
    from ._identify import _long_record, _observed, observed_columns

    model = result.fit.model
    record = result.record
    t, inputs, long = _long_record(record, 0.0)
    n, k = len(record.t), len(result.outputs)
    has = jnp.asarray(record.inputs[:n, 1 : 1 + k])
    names = model.parameters
    flight = result.flight

    def outputs(params):
        xs = flown_states(model, long, params)
        ys = _observed(flight, t[:n], xs[:n], inputs[:n], params, names)
        return ys[:, jnp.asarray(observed_columns(result.outputs))] * has

    return jax.jit(outputs)


def apogee_band(result, held: dict | None = None) -> ApogeeBand:
    """The 95% band's ingredients of `result`'s apogee: the gradient of
    [`apogee_function`][] (forward-mode JAX) with respect to the estimated
    parameters and the held ones in `held` (name -> standard uncertainty in the
    parameter's units; by default `held_sigmas`), the estimates' covariance
    (`stderr_corrected` and `correlation`, coloured residuals allowed for) carried
    through it, and each held parameter's total derivative times its uncertainty
    added in quadrature (independent of the estimates). Linearised, the fit's own
    optimum moving with a held parameter is followed: off by `dc`, it moves the
    estimates by `S dc`, `S = -(J^T W J)^-1 J^T W J_c` from the Jacobians `J`, `J_c`
    of the single-shooting outputs (`outputs_function`) over the log the fit
    read, weighted by its residual variances `W = R^-1` (a consider parameter's
    term, `|dA/dc + dA/dtheta S| sigma_c`). NaN standard errors for a fit whose
    covariance is not finite."""
    import jax
    import jax.numpy as jnp

    fit = result.fit
    names = list(fit.model.parameters)
    held = held_sigmas(result) if held is None else dict(held)
    free = [i for i, f in enumerate(fit.free) if f]
    fixed = [names.index(k) for k in held]
    idx = free + fixed
    params = jnp.asarray(fit.params, float)
    apogee = apogee_function(result)

    def along(sub):
        return apogee(params.at[jnp.asarray(idx)].set(sub))

    grad = np.asarray(jax.jacfwd(along)(params[jnp.asarray(idx)]))
    g_free, g_held = grad[: len(free)], grad[len(free) :]
    cov = fit.covariance_of()  # the estimated parameters, in the model's order
    var_fit = float(g_free @ cov @ g_free)
    total = g_held
    if held:
        out = outputs_function(result)

        def outputs_along(sub):
            return out(params.at[jnp.asarray(idx)].set(sub))

        # (samples, outputs, estimated + held), whitened by the residual variances
        jac = np.asarray(jax.jacfwd(outputs_along)(params[jnp.asarray(idx)]))
        r = np.asarray(fit.R, float)
        w = 1.0 / np.sqrt(np.where(r > 0, r, np.nan))
        a = (jac * w[None, :, None]).reshape(-1, len(idx))
        if np.all(np.isfinite(a)):
            moved = -np.linalg.lstsq(a[:, : len(free)], a[:, len(free) :], rcond=None)[
                0
            ]
            total = g_held + g_free @ moved
        else:  # a flight the model cannot fly through, or no residual variance
            total = np.full(len(held), np.nan)
    terms = {
        k: (float(held[k]), float(abs(g) * held[k]))
        for k, g in zip(held, total, strict=True)
    }
    var = var_fit + sum(c**2 for _, c in terms.values())
    return ApogeeBand(
        apogee=float(result.apogee),
        stderr=float(np.sqrt(var)) if np.isfinite(var) else float("nan"),
        stderr_fit=float(np.sqrt(max(var_fit, 0.0)))
        if np.isfinite(var_fit)
        else float("nan"),
        gradient={names[i]: float(g) for i, g in zip(idx, grad, strict=True)},
        held=terms,
        held_gradient={k: float(g) for k, g in zip(held, total, strict=True)},
    )
