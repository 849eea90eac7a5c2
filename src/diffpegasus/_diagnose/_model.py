"""The global-aerodynamics model the discrepancy workflow fits and diagnoses.

Per-window derivatives would absorb a missing physical term (a constant offset turns
into biased derivatives, not into misfit), so this model's aerodynamics are global
over the record: each coefficient is a polynomial in alpha (no constant term) plus a
term in the elevator, with every coefficient a smooth function of Mach, a clamped
cubic B-spline with `knots` functions (breakpoints placed by [`mach_breakpoints`][]):

    CL = sum_k B_k(M) (a_k1 alpha + a_k2 alpha^2 + ... + b_k de + c_k alpha de),
    likewise CD, CM

(CM about the cp station), plus any effects of the library through their hooks. The
spline is scheduled on the measured Mach (a known input, as gain schedules are). The
alpha powers stand for the alpha dependence of the derivative tables
(`CL = CLa(alpha, M) alpha`); the default order 3 keeps the structural error of the
Pegasus database below what the diagnosis can see on clean flights. The `alpha de`
term stands for elevator derivatives that vary with alpha (`CLde(alpha, M)`, as in
any table over alpha and Mach): without it, a change of trim deflection at one Mach
number leaves a misfit that a constant moment offset explains (measured on the
independent generator of `tests/independent_generator.py`: moment_offset flagged on
clean flights with a score statistic of about 100).

States `[u, w, q, theta, h]` (inertial body velocities, m/s; rad/s; rad; m); known
inputs `[de, thrust, mass, Iyy, Iyy_dot, xcg, xcp, B_1..B_K]`; outputs
[`OUTPUTS`][] in SI units. Parameters: the aerodynamic coefficients (ordered CL, CD,
CM; within each by term `alpha^1..alpha^n, de, alpha de`, then spline function), then each
effect's main parameter in SI units.
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._log._format import FlightLog
from .._vehicle._atmosphere import isa
from .._vehicle._effects import AbstractEffect, make_effect
from .._vehicle._flight import elevator_delay, has_delay, pitch_plane
from .._vehicle._gravity import gravity


OUTPUTS = ("ax", "az", "q", "qdot", "alpha", "V", "theta", "h")
KNOWN = ("de", "thrust", "mass", "Iyy", "Iyy_dot", "xcg", "xcp")
STATE_SCALE = np.array([0.5, 0.5, 2e-3, 1e-3, 5.0])


def bspline_basis(x: np.ndarray, knots: np.ndarray, degree: int = 3) -> np.ndarray:
    """Clamped B-spline basis, shape `(len(x), len(knots) + degree - 1)`, by the
    Cox-de Boor recursion; `knots` are the breakpoints (increasing), `x` is clipped
    to their range. The basis functions sum to one at every point."""
    x = np.clip(np.asarray(x, float), knots[0], knots[-1])
    t = np.concatenate([[knots[0]] * degree, knots, [knots[-1]] * degree])
    b = np.zeros((len(x), len(t) - 1))
    for i in range(len(t) - 1):
        b[:, i] = (t[i] <= x) & (x < t[i + 1])
    b[x >= knots[-1], len(knots) + degree - 2] = 1.0
    for d in range(1, degree + 1):
        nb = np.zeros((len(x), len(t) - 1 - d))
        for i in range(len(t) - 1 - d):
            left = t[i + d] - t[i]
            right = t[i + d + 1] - t[i + 1]
            if left > 0:
                nb[:, i] += (x - t[i]) / left * b[:, i]
            if right > 0:
                nb[:, i] += (t[i + d + 1] - x) / right * b[:, i + 1]
        b = nb
    return b


PLACEMENTS = ("quantile", "blend")


def mach_breakpoints(mach: np.ndarray, n_breaks: int, placement: str = "quantile"):
    """`n_breaks` increasing breakpoints over the range of `mach`, shape `(n_breaks,)`.

    `"quantile"` (the default): each interval holds the same share of the record.
    `"blend"`: equal steps of half the share of the record's samples at or below a
    Mach number plus half its share of the record's Mach range, so every interval
    gets at least half a step of either. Quantiles spend an interval on a dwell at
    one Mach number (a drop before ignition: a sixth of a 30 s record between Mach
    0.797 and 0.81) and can leave a fast passage through a wide range (the transonic
    climb after ignition) in one interval, where a vehicle's derivatives change
    fastest; breakpoints even in Mach leave few samples to a range crossed fast.
    The blend is not the default: with 6 functions it removes the
    thrust-misalignment-shaped false alarms on the independent generator's 1 kHz
    logs (0 of 20 flights flagged, 4 with quantiles), but 5 of those 20 fits hit
    the iteration cap and planted refits move away from the truth (ours: Cmq -10
    from 2.5 to 3.4 standard errors, accelerometer offset 0.5 from 2.7 to 3.6; the
    independent generator's Cmq -3 at 1 kHz from 1.4 to 7.1); see the README,
    "Trust on data we did not make".
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


def mach_basis(
    mach: np.ndarray, n_coefficients: int, placement: str = "quantile"
) -> np.ndarray:
    """Cubic B-spline basis over Mach with `n_coefficients` functions, breakpoints by
    [`mach_breakpoints`][] over `mach`; shape `(len(mach), n_coefficients)`."""
    if n_coefficients < 4:
        raise ValueError(
            f"knots must be at least 4 (cubic spline), got {n_coefficients}"
        )
    breaks = mach_breakpoints(mach, n_coefficients - 2, placement)
    if np.any(np.diff(breaks) <= 0):
        raise ValueError(
            "the log's Mach number does not vary enough for "
            f"{n_coefficients} spline knots; use fewer"
        )
    return bspline_basis(mach, breaks)


class ModelSpec(eqx.Module):
    """The structure of a global model: what is static about it.

    **Fields:** `s_ref` (m^2), `c_ref` (m); `knots` (spline functions over Mach)
    and `knot_placement` (`"quantile"` or `"blend"`, see [`mach_breakpoints`][]);
    `alpha_order` (highest power of alpha in each coefficient: 1 linear, 2 adds a
    Mach-dependent alpha^2 term, the database's non-linearity); `effects`
    (canonical effect names, e.g. `sensor_bias:az`, in the model at zero unless
    estimated).
    """

    s_ref: float = eqx.field(static=True)
    c_ref: float = eqx.field(static=True)
    knots: int = eqx.field(static=True, default=6)
    knot_placement: str = eqx.field(static=True, default="quantile")
    alpha_order: int = eqx.field(static=True, default=3)
    alpha_elevator: bool = eqx.field(static=True, default=True)
    effects: tuple[str, ...] = eqx.field(static=True, default=())

    @property
    def terms(self) -> tuple[str, ...]:
        """Regressors of each coefficient: `a1 = alpha`, `a2 = alpha^2`, ..., `de`,
        and `a1de = alpha de` if `alpha_elevator`."""
        cross = ("a1de",) if self.alpha_elevator else ()
        return tuple(f"a{p}" for p in range(1, self.alpha_order + 1)) + ("de",) + cross

    @property
    def n_aero(self) -> int:
        return 3 * len(self.terms) * self.knots

    @property
    def n_params(self) -> int:
        return self.n_aero + len(self.effects)

    def parameter_names(self) -> list[str]:
        """`CL.a1[0]` ... `CM.de[K-1]`, then each effect's `name.parameter`."""
        aero = [
            f"{c}.{term}[{k}]"
            for c in ("CL", "CD", "CM")
            for term in self.terms
            for k in range(self.knots)
        ]
        return aero + [effect_parameter_name(e) for e in self.effects]

    def effect_index(self, name: str) -> int:
        return self.n_aero + self.effects.index(name)


def effect_parameter_name(spec: str) -> str:
    """`pitch_damping` -> `pitch_damping.Cmq`, `sensor_bias:az` -> `sensor_bias:az.bias`."""
    return f"{spec}.{make_effect(spec).parameter}"


def scheduling_basis(
    log: FlightLog | dict, index: np.ndarray, spec: ModelSpec
) -> np.ndarray:
    """The Mach spline basis at the samples `index` of `log` (a log or a dict of
    channels), `(len(index), knots)`."""
    return mach_basis(log["mach"][index], spec.knots, spec.knot_placement)


def aero_columns(basis, alpha, de, spec: ModelSpec):
    """Regressors of one coefficient, `(n, len(terms) * knots)`: the basis times
    alpha, alpha^2, ..., de (and alpha de) (works on numpy and JAX arrays)."""
    xp = jnp if isinstance(basis, jax.Array) else np
    powers = [alpha**p for p in range(1, spec.alpha_order + 1)] + [de]
    if spec.alpha_elevator:
        powers.append(alpha * de)
    return xp.concatenate([basis * v[..., None] for v in powers], axis=-1)


def _effects(spec: ModelSpec, theta) -> tuple[AbstractEffect, ...]:
    return tuple(
        make_effect(name, theta[spec.n_aero + i]) for i, name in enumerate(spec.effects)
    )


def _coefficients(spec: ModelSpec, u, theta, alpha, de):
    """CL, CD, CM (about the cp) of the baseline aerodynamics."""
    basis = u[len(KNOWN) :]
    cols = aero_columns(basis[None, :], alpha[None], de[None], spec)[0]
    return theta[: spec.n_aero].reshape(3, -1) @ cols


def _evaluate(spec: ModelSpec, t, x, u, theta):
    """State rates and the noise-free output channels, effects included: the one
    flight model ([`pitch_plane`][]) with the spline aerodynamics and the log's
    known inputs."""
    effects = _effects(spec, theta)
    uu, ww, q, pitch, h = x
    de, thrust, mass, iyy, iyy_dot, xcg, xcp = u[: len(KNOWN)]
    atm = isa(h)

    def aero(c):
        cl, cd, cm = _coefficients(spec, u, theta, c.alpha, c.de)
        return cl, cd, cm

    pp = pitch_plane(
        t,
        uu,
        ww,
        q,
        pitch,
        h,
        de=de,
        aero=aero,
        effects=effects,
        s_ref=spec.s_ref,
        c_ref=spec.c_ref,
        density=atm.density,
        speed_of_sound=atm.speed_of_sound,
        g=gravity(h),
        thrust=thrust,
        mass=mass,
        iyy=iyy,
        iyy_dot=iyy_dot,
        xcg=xcg,
        xcp=xcp,
    )
    rates = jnp.stack([pp.udot, pp.wdot, pp.qdot, q, pp.hdot])
    return rates, jnp.stack([pp.channels[c] for c in OUTPUTS])


class _Rates(eqx.Module):
    """The global model's state rates `(t, x, u, theta) -> x'`: a value (equal for
    equal specs, picklable), so that compiled and kept programs are shared."""

    spec: ModelSpec = eqx.field(static=True)

    def __call__(self, t, x, u, theta):
        return _evaluate(self.spec, t, x, u, theta)[0]


class _Outputs(eqx.Module):
    """The global model's outputs `(t, x, u, theta) -> y` (see [`_Rates`][])."""

    spec: ModelSpec = eqx.field(static=True)

    def __call__(self, t, x, u, theta):
        return _evaluate(self.spec, t, x, u, theta)[1]


class _InputDelay(eqx.Module):
    """The known inputs' delays `theta -> (inputs,)`: the elevator's (see
    [`_Rates`][])."""

    spec: ModelSpec = eqx.field(static=True)

    def __call__(self, theta):
        tau = elevator_delay(_effects(self.spec, theta))
        n_inputs = len(KNOWN) + self.spec.knots
        return jnp.zeros(n_inputs).at[0].set(tau)


@functools.cache
def make_model(spec: ModelSpec):
    """`(rates, outputs, input_delay)` of the global model, cached per structure so
    that fits of different logs share compiled code."""
    for name in spec.effects:
        eff = make_effect(name)
        if getattr(eff, "channel", None) is not None and eff.channel not in OUTPUTS:
            raise ValueError(
                f"{name}: channel {eff.channel!r} is not a model output "
                f"({', '.join(OUTPUTS)})"
            )
    delays = has_delay(tuple(make_effect(n) for n in spec.effects))
    return _Rates(spec), _Outputs(spec), (_InputDelay(spec) if delays else None)


def measured_states(log: FlightLog | dict, index: np.ndarray) -> Float[Array, "n 5"]:
    """`[u, w, q, theta, h]` from the measured V, alpha, q, theta, h at `index`."""
    v, alpha = log["V"][index], log["alpha"][index]
    return jnp.asarray(
        np.column_stack(
            [
                v * np.cos(alpha),
                v * np.sin(alpha),
                log["q"][index],
                log["theta"][index],
                log["h"][index],
            ]
        )
    )
