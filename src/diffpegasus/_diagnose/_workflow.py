"""Compare, localise, diagnose, add and refit: the discrepancy workflow on any
vehicle's model, the one engine ([`fit`][]) and the one diagnosis
([`diagnose_model`][], [`score_candidates`][]).

A vehicle's registry entry ([`AbstractVehicleEntry`][]) builds the model and the
records from the logs (with every candidate effect composed and held at zero, so
the baseline, the diagnosis and every refit share one compiled program); these
functions fit it, measure the fit per channel and by flight regime, rank the
candidates and refit with effects added.
"""

import dataclasses
from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._estimate._fit import Fit, fit as engine_fit
from .._estimate._modelfile import ModelSpec
from ._candidates import diagnosis_message, score_candidates
from ._metrics import binned_misfit, channel_metrics, residual_noise_sigma
from ._rule import rule_summary


# A fit runs to convergence: None is the engine's adaptive budget (it stops when the
# cost settles; the launch vehicle's baselines converge in 4-10 iterations at 50 Hz)
MAX_ITER = None


@dataclasses.dataclass(frozen=True)
class FlightFit:
    """A fit of a vehicle's model to one log, with what the workflow reports.

    **Fields:** `spec` (the model and its candidates), `result` (the engine's
    [`Fit`][]), `added` (the library effects estimated with the model).
    """

    spec: ModelSpec
    result: Fit
    added: tuple[str, ...] = ()

    @property
    def record(self):
        return self.result.records[0]

    @property
    def name(self) -> str:
        return self.record.name

    @property
    def outputs(self) -> tuple[str, ...]:
        return self.result.model.outputs

    @property
    def t(self) -> np.ndarray:
        return self.record.t

    @property
    def measured(self) -> np.ndarray:
        return self.record.measured

    @property
    def model(self) -> np.ndarray:
        return self.result.outputs[0]

    @property
    def residuals(self) -> np.ndarray:
        """Measured minus model outputs, `(samples, outputs)`, SI units."""
        return self.measured - self.model

    @property
    def cost(self) -> float:
        return float(self.result.cost)

    @property
    def converged(self) -> bool:
        return self.result.converged

    def channel(self, name: str) -> np.ndarray | None:
        """An input or output of the record by name, `(samples,)`, or `None`."""
        m = self.result.model
        if name in m.outputs:
            return self.measured[:, m.outputs.index(name)]
        if name in m.inputs:
            return self.record.inputs[:, m.inputs.index(name)]
        return None

    def effect_estimates(self) -> dict[str, dict]:
        """Each added effect: its parameter's estimate and standard error
        (corrected for coloured residuals; the plain Cramér-Rao bound beside it)."""
        from .._vehicle._parts import effect_parameter

        names = list(self.result.model.parameters)
        out = {}
        for effect in self.added:
            k = names.index(effect_parameter(effect))
            out[effect] = {
                "parameter": names[k].split(".", 1)[1],
                "estimate": float(self.result.params[k]),
                "stderr": float(self.result.stderr_corrected[k]),
                "stderr_crb": float(self.result.stderr[k]),
            }
        return out


def fit_log(
    entry,
    log,
    add: Sequence[str] = (),
    *,
    start: FlightFit | None = None,
    max_iter: int | None = MAX_ITER,
    say=None,
) -> FlightFit:
    """Fit `entry`'s model (a vehicle's registry entry) to one log with the
    library effects `add` estimated and the vehicle's other candidates held at
    zero; `start`: a previous fit whose estimates start this one; `say(text)`: told
    when the log has been read and the fit begins."""
    add = tuple(add)
    spec, records = entry.problem([log], add=add, candidates=True)
    if say is not None:
        say(spec.model)
    model = spec.model
    if start is not None:
        model = model.replace(start=start.result.estimates())
    result = engine_fit(
        model,
        records,
        shooting=spec.shooting,
        initial_state=spec.initial_state,
        biases=spec.biases,
        max_iter=max_iter,
        throw=False,
    )
    return FlightFit(dataclasses.replace(spec, model=model), result, add)


def channel_noise(ff: FlightFit) -> np.ndarray:
    """White-noise sigma of every output, SI units: [`residual_noise_sigma`][] of
    the fit's residual (its spectrum above the model's bandwidth), from the log
    itself, whatever its sidecar says."""
    return np.array(
        [residual_noise_sigma(ff.residuals[:, i]) for i in range(len(ff.outputs))]
    )


def fit_metrics(ff: FlightFit) -> dict:
    """`{"cost": det R, "converged", "iterations", "message", "channels": {name:
    metrics}}` (see [`channel_metrics`][]; the residual-input cross-correlation
    with the model's first input)."""
    first = ff.record.inputs[:, 0]
    noise = channel_noise(ff)
    channels = {
        name: channel_metrics(ff.measured[:, i], ff.model[:, i], first, noise[i])
        for i, name in enumerate(ff.outputs)
    }
    return {
        "cost": ff.cost,
        "converged": ff.converged,
        "iterations": int(ff.result.iterations),
        "message": ff.result.message,
        "defect": float(ff.result.defect),
        "channels": channels,
    }


# Flight-condition channels a misfit is binned by, where the model has them.
REGIMES = {
    "alpha": ("alpha_deg", np.rad2deg(1.0)),
    "V": ("V", 1.0),
    "h": ("h_km", 1e-3),
}


def localise(ff: FlightFit, bins: int = 5, segment: float = 5.0) -> dict:
    """Where the misfit is: residual RMS over the noise sigma (1: noise only) per
    channel, by time segment, by bins of the flight condition (alpha, airspeed,
    altitude, where the model has them) and by thrust on and off (where the
    model reads thrust)."""
    r = ff.residuals
    noise = channel_noise(ff)
    noise = np.where(noise > 0, noise, 1.0)
    t = ff.t
    out = {
        "channels": list(ff.outputs),
        "noise": noise.tolist(),
        "time": binned_misfit(r, noise, t, np.arange(t[0], t[-1] + segment, segment)),
    }

    def quant(x):
        return np.unique(np.quantile(x, np.linspace(0, 1, bins + 1)))

    for name, (key, factor) in REGIMES.items():
        x = ff.channel(name)
        if x is not None:
            out[key] = binned_misfit(r, noise, x * factor, quant(x * factor))
    thrust = ff.channel("thrust")
    out["thrust"] = []
    if thrust is not None and np.max(np.abs(thrust)) > 0:
        on = thrust > 0.01 * np.max(np.abs(thrust))
        out["thrust"] = [
            {
                "regime": name,
                "samples": int(sel.sum()),
                "misfit_ratio": (
                    np.sqrt(np.mean(r[sel] ** 2, axis=0)) / noise
                ).tolist(),
            }
            for name, sel in (("off", ~on), ("on", on))
            if sel.sum() >= 10
        ]
    worst = []
    for key in ["time"] + [k for k, _ in REGIMES.values()]:
        for row in out.get(key, []):
            for i, c in enumerate(ff.outputs):
                worst.append((row["misfit_ratio"][i], c, key, row["low"], row["high"]))
    worst.sort(reverse=True)
    out["worst"] = [
        {"channel": c, "variable": k, "low": lo, "high": hi, "misfit_ratio": v}
        for v, c, k, lo, hi in worst[:5]
    ]
    return out


@eqx.filter_jit
def _speed_of_sound(
    atmosphere, h: Float[Array, " samples"]
) -> Float[Array, " samples"]:
    """The atmosphere's speed of sound (m/s) at each altitude `h` (m): one compiled
    program over the samples (called sample by sample, operation by operation, a
    30 s log at 50 Hz took 3.5-5 CPU-s; compiled, 0.3 the first time)."""
    return jax.vmap(lambda x: atmosphere.at(x)[1])(h)


@eqx.filter_jit
def _secant_derivatives(aerodynamics, names: tuple[str, ...], geometry, theta, m, a):
    """The secant derivatives `(CLa, CDa, CMa, CLde, CDde, CMde)` (1/rad) of an
    aerodynamics part at Mach `m` and alpha `a` (rad), and their Jacobian in the
    parameters `theta` `(params,)` named `names`; `geometry` `(c_ref, s_ref)` (m,
    m^2). One compiled program per part and parameter names (static), so a second
    log's table compiles nothing (a closure made per call compiled two programs
    every time)."""
    from .._vehicle._effects import FlightCondition

    c_ref, s_ref = geometry

    def coefficients(th, de, alpha):
        zero = jnp.zeros(())
        c = FlightCondition(
            t=zero,
            alpha=alpha,
            alpha_dot=zero,
            airspeed=zero + 1.0,
            mach=m,
            qbar=zero,
            q=zero,
            qdot=zero,
            theta=zero,
            h=zero,
            de=de,
            thrust=zero,
            c_ref=c_ref,
            s_ref=s_ref,
            mass=zero + 1.0,
            xcg=zero,
        )
        p = {name: th[i] for i, name in enumerate(names)}
        return jnp.stack(aerodynamics.coefficients(c, p))

    def derivatives(th):
        zero = jnp.zeros(())
        secant = (coefficients(th, zero, a) - coefficients(th, zero, zero)) / a
        slope = jax.jacfwd(lambda de: coefficients(th, de, a))(zero)
        return jnp.concatenate([secant, slope])

    return derivatives(theta), jax.jacfwd(derivatives)(theta)


def derivative_table(ff: FlightFit, points: int = 5) -> list[dict] | None:
    """The fitted aerodynamic derivatives (1/rad) with Cramér-Rao standard errors
    at `points` Mach numbers spread over the record, each at the record's mean
    alpha there, in the secant form `CL = CLa(alpha, M) alpha + CLde de` of a
    derivative table: `CLa = (CL(alpha) - CL(0)) / alpha` and `CLde = dCL/dde`
    at zero elevator, from the vehicle's aerodynamics part (any part), with
    standard errors by the delta method: `{"mach", "alpha", "CLa": [est, sd],
    ...}`. `None` for a model that is not a vehicle, or without airspeed."""

    vehicle = ff.spec.vehicle
    v, alpha = ff.channel("V"), ff.channel("alpha")
    if vehicle is None or v is None or alpha is None:
        return None
    h = ff.channel("h")
    h = np.zeros_like(v) if h is None else h
    sound = np.asarray(_speed_of_sound(vehicle.atmosphere, jnp.asarray(h)))
    mach = v / sound
    model = ff.result.model
    free = np.asarray(ff.result.free)
    sd = np.asarray(ff.result.stderr)
    cov = np.asarray(ff.result.correlation) * np.outer(sd, sd)
    theta = np.asarray(ff.result.params)

    geometry = (float(vehicle.geometry.c_ref), float(vehicle.geometry.s_ref))
    rows = []
    for chunk in np.array_split(np.argsort(mach), points):
        m, a = float(mach[chunk].mean()), float(alpha[chunk].mean())
        d, g = _secant_derivatives(
            vehicle.aerodynamics,
            model.parameters,
            geometry,
            jnp.asarray(theta),
            jnp.asarray(m),
            jnp.asarray(a),
        )
        d, g = np.asarray(d), np.asarray(g)[:, free]
        var = np.einsum("ij,jk,ik->i", g, cov[np.ix_(free, free)], g)
        row = {"mach": m, "alpha": a}
        for k, label in enumerate(("CLa", "CDa", "CMa", "CLde", "CDde", "CMde")):
            row[label] = [float(d[k]), float(np.sqrt(max(var[k], 0.0)))]
        rows.append(row)
    return rows


def diagnose(ff: FlightFit, *, level: float = 0.01) -> dict:
    """Rank the held candidates of `ff`'s model by score test at its fit and
    decide by the decision rule calibrated on this fit's residuals (see
    [`score_candidates`][]): `level` is the family-wise false-alarm level.

    **Returns:** `{"ranking": [...], "significant": [effects], "message",
    "rule"}`, significant rows first, each ranking row as [`score_candidates`][]'s
    with `hard_to_tell_from` as `[{"effect", "correlation"}]` and `parameter` the
    effect's own parameter name; `rule` holds the threshold used and the
    false-alarm level it holds.
    """
    ranking = score_candidates(ff.result, ff.spec.candidates, level)
    return ranking_report(ff, ranking)


def ranking_report(ff: FlightFit, ranking) -> dict:
    """The diagnosis dict of a ranking (see [`diagnose`][])."""
    message = diagnosis_message(ranking, ff.result)
    rows = []
    for r in ranking:
        row = dict(r)
        if "parameter" in row and "." in row["parameter"]:
            row["parameter"] = row["parameter"].split(".", 1)[1]
        row["hard_to_tell_from"] = [
            {"effect": c.split(".")[0], "correlation": None}
            if isinstance(c, str)
            else c
            for c in r.get("hard_to_tell_from", [])
        ]
        rows.append(row)
    return {
        "ranking": rows,
        "significant": [r["effect"] for r in rows if r["significant"]],
        "message": message,
        "rule": rule_summary(ranking),
        # how the entry chose the baseline's resolution from the log, if it did
        **({"baseline": ff.spec.notes["baseline"]} if ff.spec.notes else {}),
    }
