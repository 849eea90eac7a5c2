"""The Pegasus output-error model and estimator (thesis chapter 5).

States `[u, w, q, theta]`; known inputs from the log (elevator, net thrust, mass,
Iyy, Iyy_dot, CG and cp stations, altitude for density and gravity); per-window
parameters the body-axis derivatives `[CXa, CXde, CZa, CZde, CMa, CMde]` (the thesis
found them better conditioned than the lift/drag ones); outputs `[ax, az, q, qdot,
alpha, V]`. The same building blocks as the simulator (`pitch_plane_rates`,
`moment_about_cg`, `isa`, `gravity`) give the dynamics. The model is a `dp.Model`
([`thesis_model`][], the reference geometry the vehicle's), the decimated log a
`dp.Record` ([`thesis_record`][]); the per-window parameters are a layout of the
one output-error engine ([`fit_windowed`][]).

With `terms` (`parameters="window"` of [`estimate_oem`][]) the alpha derivatives
of a window may also change inside it, with time and with alpha: `CXa(t) = CXa +
CXa_t tau + CXa_alpha (alpha - alpha_w)` (likewise CZa, CMa; every parameter
constant per window), `tau` the time within the window over its length minus 1/2
(mean zero over the window's samples) and `alpha_w` the window's mean measured
alpha (both known inputs, after [`INPUTS`][]); the six reported derivatives are the
values at the window's mean time and alpha, so its mean to first order. Why: the
tables' derivatives are secants (`CL = CLa(alpha, M) alpha + CLde de`), and a
pull-up sweeps alpha by degrees within 0.5 s: a window's data fix the coefficient
and its slopes, and the slope in alpha of `CLa(alpha) alpha` is not `CLa`. Without
the terms the fit trades the two and the lift derivatives carry a structural bias
larger than their standard errors (2-sigma coverage 64% over the Monte Carlo
campaign with `linear`). Parameters continuous and linear in time over the record
cannot take the terms (measured by least squares on the exact coefficients of a
noise-free flight: the bias stays): the secant changes with alpha from one window to
the next faster than a continuous parameter may follow. The price is variance:
twice the unknowns per window (measured on the reference trajectory, see the
README).

`hybrid` gives the terms to the force derivatives in alpha only (CXa, CZa, each
constant per window with its two terms) and keeps the elevator and moment
derivatives continuous and linear in time. Least squares on the exact coefficients
of a noise-free campaign flight (C = c(t) alpha + d(t) de at the model's samples;
window-mean error against the truth, rms 1/rad, for CL, CD, CM): c and d linear
0.043, 0.065, 0.002; c per window with its terms and d linear 0.001, 0.003, 0.001;
both per window with terms 0.002, 0.001, 0.001. The moment derivatives need no
terms (linear leaves them 0.002) and per window they cost variance (the moment
derivatives' MSE 4x with `window`), the force derivatives in alpha need them.
`hybrid` is the Monte Carlo campaign's OEM: over its 100 flights the 2-sigma coverage
is 93-95% for all six derivatives, every fit converged.

A window's alpha terms (`NAME_alpha`) are estimated only where alpha departs from
its straight line in time inside the window by more than the noise of a measurement
that sees it ([`departs_from_trend`][]): the vane's alpha, or the loads alpha drives
(ax and az for the force derivatives, qdot for CMa; the elevator and thrust taken
out, as known inputs); elsewhere they are held at zero. Where alpha is a straight
line in time inside a window (before ignition, late in the climb), `alpha -
alpha_w` is `tau` times a constant and the two terms are collinear: the alpha term
then wanders along the flat direction (by 1e3-8e4 in the Monte Carlo campaign's
fits with it free) and keeps the det(R) rule from stopping (11 of 100 campaign fits
at the iteration cap). Holding it there loses nothing the data could tell. Why the
loads as well as the vane: at high dynamic pressure the accelerometers resolve
alpha changes far below the vane's noise, and there the term is determined (its
standard error 0.3/rad^2 at 30-100 kPa against 60-1400 in the windows that
wandered); holding it wherever the vane alone sees a straight line biased the lift
derivatives there (campaign coverage of CLa 85%, 77% at 30-100 kPa).

The fit runs at `1/decimate` of the log's rate, and every log channel enters it as
the mean of the `decimate` samples around each model sample: the measurements (their
noise averaged instead of discarded) and the known inputs alike. The model predicts
what was measured only if it sees the inputs over the same samples: the
accelerations and qdot follow the elevator without lag (`CZde de`), so where the
elevator's 20 ms ramp bends inside a 5 ms block the measured block mean of az is not
the model's az at the block's centre with the elevator sampled there (off by
0.009 m/s^2 at 60 kPa, 0.4 of az's block noise, at four samples of every pulse, the
same at every pulse); the fit took that as aerodynamics. With the elevator picked at
the sample, a campaign flight with a tenth of the sensor noise (bias then far above
the noise) had mean CLa errors of -0.0048/rad at 10-30 kPa and -0.0033 at 30-100
kPa, with the block-mean inputs -0.0009 and +0.0007 (standard errors 0.0026,
0.0009); over the campaign's first 10 flights the `hybrid` lift derivatives' 2-sigma
coverage went from 91% to 94% (30-100 kPa: 88% to 91%). To first order the mean of
the model's output over a block is its output at the block's centre with the inputs'
block means (the states and coefficients change smoothly over 5 ms; the inputs enter
the loads linearly); for the state rates the inputs' block means keep a step's
timing to within half a log sample (a picked sample moves it by up to a model
sample).
"""

import dataclasses
import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from .._log._format import FlightLog
from .._model import Model, Record
from .._vehicle._atmosphere import isa
from .._vehicle._axes import wind_body
from .._vehicle._flight import moment_about_cg, pitch_plane_rates
from .._vehicle._gravity import gravity
from .._vehicle._parts import Geometry
from .._vehicle._pegasus._aerodynamics import body_axis, load_database
from .._vehicle._pegasus._vehicle import C_REF, S_REF
from ._engine import iteration_bound, Layout, RESULTS, segment_solve, solve
from ._estimator import covariance
from ._lse import estimate_lse, window_truth
from ._result import Estimates
from ._windowed_oem import (
    fit_windowed_data,
    window_data,
    windowed_start,
    WindowedFit,
    Windows,
)
from ._windows import WindowLayout


INPUTS = ("de", "thrust", "mass", "Iyy", "Iyy_dot", "xcg", "xcp", "h")
OUTPUTS = ("ax", "az", "q", "qdot", "alpha", "V")
BODY_NAMES = ("CXa", "CXde", "CZa", "CZde", "CMa", "CMde")
WIND_NAMES = ("CLa", "CLde", "CDa", "CDde", "CMa", "CMde")
# Which alpha derivatives may change inside a window (`terms`), each with time (per
# window length, 1/rad) and with alpha (1/rad^2); all parameters are then constant
# per window (a continuous parameter cannot take the terms, see the module).
ALPHA_DERIVATIVES = ("CXa", "CZa", "CMa")  # body axes (CLa, CDa, CMa: wind axes)
WINDOW_TERMS = ALPHA_DERIVATIVES
# `parameters="hybrid"`: only the force derivatives in alpha change inside a window
# (body axes CXa, CZa; wind axes CLa, CDa), each constant per window with its
# terms; the elevator and moment derivatives stay continuous and linear in time.
HYBRID_TERMS = ("CXa", "CZa")
TERM_INPUTS = ("alpha_w", "tau")
# A window's alpha terms are estimated where the rms departure from the straight
# line in time (noise removed) of alpha or of a load it drives exceeds this many
# times that signal's noise: a signal-to-noise of one, chosen, not measured on a
# campaign (under noise alone the statistic is 1 +/- 0.14 for a window of 100
# samples, so a window passes only on a departure as large as the noise).
ALPHA_TERM_SNR = 1.0
PARAMETERS = ("hybrid", "linear", "window", "constant")


def linear_mask(parameters: str, terms: tuple[str, ...]) -> bool | tuple[bool, ...]:
    """`linear=` of [`fit_windowed`][] for a parameterisation: per parameter
    (the six derivatives, then [`term_names`][]) whether it is continuous and linear
    in time (else constant per window)."""
    if parameters == "linear":
        return True
    if parameters == "hybrid":
        six = tuple(n not in terms for n in BODY_NAMES)
        return six + (False,) * len(term_names(terms))
    return False


def term_names(terms: tuple[str, ...]) -> tuple[str, ...]:
    """The extra parameters of `terms` (names from [`ALPHA_DERIVATIVES`][]):
    `NAME_t` (change over the window, per window length) then `NAME_alpha`
    (change with alpha, 1/rad^2) for each."""
    return tuple(f"{n}_t" for n in terms) + tuple(f"{n}_alpha" for n in terms)


STATE_SCALE = np.array([10.0, 1.0, 0.01, 0.01])


def departs_from_trend(
    x: np.ndarray,
    tau: np.ndarray,
    window: int,
    extra: np.ndarray | None = None,
    snr: float = ALPHA_TERM_SNR,
) -> np.ndarray:
    """`(windows,)` whether a signal departs from its straight line in time inside
    each window (least squares on `[1, tau, extra]` within the window) by more than
    `snr` times its noise, rms, noise removed: `rss / (n - rank) > (1 + snr^2)
    sigma^2`.

    **Arguments:** `x` `(samples,)` the measured signal at the model's samples;
    `tau` `(samples,)` time in the window over its length; `window` samples per
    window (the last window may be shorter); `extra` `(samples, k)` known inputs
    whose effect is not a departure (the elevator, for an acceleration). The noise
    `sigma` is estimated from the whole record's second differences, robustly (their
    median square: a step in the signal, e.g. an acceleration at an elevator step,
    moves a few of them only): `sigma^2 = median(d2^2) / (6 * 0.4549)`, 0.4549 the
    median of a chi-square with one degree of freedom.
    """
    x = np.asarray(x, float)
    tau = np.asarray(tau, float)
    extra = np.zeros((x.size, 0)) if extra is None else np.asarray(extra, float)
    sigma2 = np.median(np.diff(x, 2) ** 2) / (6.0 * 0.4549)
    out = []
    for start in range(0, x.size, window):
        sl = slice(start, start + window)
        basis = np.column_stack([np.ones(x[sl].size), tau[sl], extra[sl]])
        coef, _, rank, _ = np.linalg.lstsq(basis, x[sl], rcond=1e-10)
        rss = np.sum((x[sl] - basis @ coef) ** 2)
        out.append(rss / max(x[sl].size - rank, 1) > (1.0 + snr**2) * sigma2)
    return np.array(out)


def _loads(x, u, p, s_ref, c_ref, wind_axes, terms=()):
    uu, ww, q, theta = x
    de, thrust, mass, iyy, iyy_dot, xcg, xcp, h = u[:8]
    alpha = jnp.arctan2(ww, uu)
    v = jnp.sqrt(uu**2 + ww**2)
    qbar = 0.5 * isa(h).density * v**2
    if terms:
        # the alpha derivatives inside the window: with time (u[9], tau) and with
        # alpha about the window's mean alpha u[8]
        tau, da = u[9], alpha - u[8]
        k = len(terms)
        for i, name in enumerate(terms):
            j = 2 * ALPHA_DERIVATIVES.index(name)
            p = p.at[j].add(p[6 + i] * tau + p[6 + k + i] * da)
    if wind_axes:
        cla, clde, cda, cdde, cma, cmde = p[:6]
        cx, cz = body_axis(cla * alpha + clde * de, cda * alpha + cdde * de, alpha)
    else:
        cxa, cxde, cza, czde, cma, cmde = p[:6]
        cx, cz = cxa * alpha + cxde * de, cza * alpha + czde * de
    fx_aero = qbar * s_ref * cx
    fz_aero = qbar * s_ref * cz
    moment = moment_about_cg(
        qbar, s_ref, c_ref, cma * alpha + cmde * de, fz_aero, xcg, xcp
    )
    return fx_aero + thrust, fz_aero, moment, alpha, v


def parameter_names(wind_axes: bool = False, terms: tuple[str, ...] = ()):
    """The thesis model's parameters: the six derivatives in body axes
    ([`BODY_NAMES`][]) or lift/drag form ([`WIND_NAMES`][]), then
    [`term_names`][] of `terms`."""
    return (WIND_NAMES if wind_axes else BODY_NAMES) + term_names(terms)


def thesis_model(
    geometry: Geometry | None = None,
    *,
    wind_axes: bool = False,
    terms: tuple[str, ...] = (),
) -> Model:
    """The thesis's output-error model of the Pegasus first stage as a `dp.Model`:
    states `[u, w, q, theta]` (m/s, m/s, rad/s, rad), known inputs [`INPUTS`][]
    (with `terms` also [`TERM_INPUTS`][]), outputs [`OUTPUTS`][], parameters
    [`parameter_names`][] (1/rad; the alpha terms per window length and 1/rad^2),
    the reference area and length from `geometry` (default the Pegasus vehicle's).
    With the windowed layout ([`fit_windowed`][]) the parameters are per window.
    Cached, so that fits of different logs share the compiled programs."""
    if geometry is None:
        geometry = Geometry(s_ref=S_REF, c_ref=C_REF)
    return _thesis_model(
        float(geometry.s_ref), float(geometry.c_ref), bool(wind_axes), tuple(terms)
    )


@functools.cache
def _thesis_model(s_ref: float, c_ref: float, wind_axes: bool, terms: tuple[str, ...]):
    geometry = (s_ref, c_ref, wind_axes, terms)
    return Model(
        states=("u", "w", "q", "theta"),
        inputs=INPUTS + (TERM_INPUTS if terms else ()),
        outputs=OUTPUTS,
        parameters=parameter_names(wind_axes, terms),
        rates=_Rates(*geometry),
        observe=_Outputs(*geometry),
        state_scale=tuple(float(v) for v in STATE_SCALE),
    )


def make_model(
    s_ref: float, c_ref: float, wind_axes: bool = False, terms: tuple[str, ...] = ()
):
    """`(rates, outputs)` of [`thesis_model`][] as functions of a parameter vector
    (in [`parameter_names`][]'s order), for the `OEMProblem` form (input design)."""
    model = _thesis_model(float(s_ref), float(c_ref), bool(wind_axes), tuple(terms))
    return model.rates, model.observe


def _vector(p, wind_axes, terms):
    # the parameters as a vector: a `dp.Model` passes a dict, the problem form a vector
    if isinstance(p, dict):
        return jnp.stack([p[n] for n in parameter_names(wind_axes, terms)])
    return p


class _Rates(eqx.Module):
    """The thesis model's state rates: a value (equal for equal geometry,
    picklable), so that fits of different logs share compiled and kept programs."""

    s_ref: float = eqx.field(static=True)
    c_ref: float = eqx.field(static=True)
    wind_axes: bool = eqx.field(static=True)
    terms: tuple[str, ...] = eqx.field(static=True)

    def __call__(self, t, x, u, p):
        p = _vector(p, self.wind_axes, self.terms)
        fx, fz, moment, _, _ = _loads(
            x, u, p, self.s_ref, self.c_ref, self.wind_axes, self.terms
        )
        udot, wdot, qdot = pitch_plane_rates(
            x[0], x[1], x[2], x[3], fx, fz, moment, u[2], u[3], u[4], gravity(u[7])
        )
        return jnp.stack([udot, wdot, qdot, x[2]])


class _Outputs(eqx.Module):
    """The thesis model's outputs (see [`_Rates`][])."""

    s_ref: float = eqx.field(static=True)
    c_ref: float = eqx.field(static=True)
    wind_axes: bool = eqx.field(static=True)
    terms: tuple[str, ...] = eqx.field(static=True)

    def __call__(self, t, x, u, p):
        p = _vector(p, self.wind_axes, self.terms)
        fx, fz, moment, alpha, v = _loads(
            x, u, p, self.s_ref, self.c_ref, self.wind_axes, self.terms
        )
        qdot = (moment - u[4] * x[2]) / u[3]
        return jnp.stack([fx / u[2], fz / u[2], x[2], qdot, alpha, v])


@jax.jit
def to_lift_drag(body, alpha):
    """Body-axis derivatives `(..., 6)` to `[CLa, CLde, CDa, CDde, CMa, CMde]` at the
    window-mean alpha (thesis eqs 5.41-5.44)."""
    cxa, cxde, cza, czde, cma, cmde = jnp.moveaxis(body, -1, 0)
    (cla, cda), (clde, cdde) = wind_body(cxa, cza, alpha), wind_body(cxde, czde, alpha)
    return jnp.stack([cla, clde, cda, cdde, cma, cmde], axis=-1)


@jax.jit
def to_body(lift_drag, alpha):
    """The inverse of [`to_lift_drag`][]."""
    cla, clde, cda, cdde, cma, cmde = jnp.moveaxis(lift_drag, -1, 0)
    (cxa, cza), (cxde, czde) = wind_body(cla, cda, alpha), wind_body(clde, cdde, alpha)
    return jnp.stack([cxa, cxde, cza, czde, cma, cmde], axis=-1)


def measured_states(log: FlightLog) -> np.ndarray:
    """`[u, w, q, theta]` at every sample, from the measured V, alpha, q, theta."""
    v, alpha = log["V"], log["alpha"]
    return np.column_stack(
        [v * np.cos(alpha), v * np.sin(alpha), log["q"], log["theta"]]
    )


def thesis_record(
    log: FlightLog,
    *,
    window: float = 0.5,
    decimate: int = 5,
    terms: tuple[str, ...] = (),
) -> tuple[Record, np.ndarray]:
    """The log as the thesis model's [`Record`][] at `1/decimate` of its rate,
    each measurement and each known input the mean of the `decimate` log samples
    around its model sample (see the module); returns it with the decimated sample
    indices. With `terms`, the window's mean measured alpha (rad) and `tau` are two
    more input columns ([`TERM_INPUTS`][])."""
    layout = WindowLayout.make(len(log), log.sample_rate, window)
    idx = np.arange(0, layout.used, decimate)
    rate = log.sample_rate / decimate
    w = int(round(window * rate))
    # the inputs averaged over the same samples as the measurements (see the module)
    columns = [_block_mean(log[c], idx, decimate) for c in INPUTS]
    if terms:
        alpha_w = np.asarray(layout.window_mean(jnp.asarray(log["alpha"])))
        win = np.minimum(idx // layout.per_window, layout.count - 1)
        columns.append(alpha_w[win])
        # time in the window over its length, mean zero over its model samples
        j = (idx - win * layout.per_window) // decimate
        columns.append((j + 0.5) / w - 0.5)
    record = Record(
        float(log.t[0]) + np.arange(len(idx)) * (decimate / log.sample_rate),
        np.column_stack(columns),
        np.column_stack([_block_mean(log[c], idx, decimate) for c in OUTPUTS]),
        name=log.path.name if log.path is not None else "log",
    )
    return record, idx


def _block_mean(x: np.ndarray, idx: np.ndarray, n: int) -> np.ndarray:
    """Mean of the `n` samples centred on each of `idx` (edges clamped): decimation
    that keeps the noise averaging of the dropped samples instead of discarding it."""
    offsets = np.arange(n) - (n - 1) // 2
    return x[np.clip(idx[:, None] + offsets[None, :], 0, len(x) - 1)].mean(axis=1)


def starting_values(
    log: FlightLog, layout: WindowLayout, start: str, key=None, lse=None
):
    """Per-window starting derivatives (lift/drag form, 1/rad): `lse` (equation-error
    estimates of the same windows; the database where LSE has none), `database` (the
    a-priori tables at the window-mean alpha and Mach) or `truth10` (the truth x
    U(0.9, 1.1), the thesis's shortcut). `lse`: the LSE estimates `(windows, 6)` if
    already computed."""
    alpha = np.asarray(layout.window_mean(jnp.asarray(log["alpha"])))
    mach = np.asarray(layout.window_mean(jnp.asarray(log["mach"])))
    prior = np.asarray(_prior(load_database(), alpha, mach))
    if start == "database":
        return prior
    if start == "lse":
        if lse is None:
            lse = estimate_lse(log, window=layout.per_window / layout.rate).values
        est = np.asarray(lse)
        return np.where(np.isfinite(est), est, prior)
    if start == "truth10":
        truth = window_truth(
            {k: jnp.asarray(v) for k, v in log.channels.items()}, layout
        )
        if truth is None:
            raise ValueError("start 'truth10' needs a log with true_* columns")
        key = jax.random.key(0) if key is None else key
        return np.asarray(truth) * np.asarray(
            jax.random.uniform(key, truth.shape, minval=0.9, maxval=1.1)
        )
    raise ValueError(f"start must be lse, database or truth10, got {start!r}")


@eqx.filter_jit
def _prior(db, alpha, mach):
    return jax.vmap(lambda a, m: db.derivatives(a, m).as_array())(alpha, mach)


class OEMSetup(eqx.Module):
    """One flight's windowed output-error fit, ready to run (stack several to fit
    a batch with `jax.vmap`): the thesis model (static), how the record is cut
    (`windows`, static), the record as the engine's data layout (`data`), starting
    parameters `(windows, 6)` (`(windows, 6 + 2 k)` with `k` window terms, which
    start at zero), starting nodes `(segments, 4)`, the window-mean alpha
    `(windows,)` (rad) for the axis conversion, which windows are fitted
    `(windows,)`, which parameters are held at their start in each window `(windows,
    params)` (the alpha terms where neither alpha nor the loads depart from their
    straight line, see the module) and `linear` (static, a bool or one per
    parameter); [`OEMSetup.fit`][] fits it."""

    model: Model
    windows: Windows
    data: Layout
    theta0: Float[Array, "windows params"]
    nodes0: Float[Array, "segments 4"]
    alpha: Float[Array, " windows"]
    active: Bool[Array, " windows"]
    held: Bool[Array, "windows params"]
    linear: bool | tuple[bool, ...] = eqx.field(static=True, default=False)

    def fit(self, **options) -> WindowedFit:
        """The windowed fit ([`fit_windowed`][]) of this setup from its start, with
        its windows, held parameters and parameterisation; `options` (`rtol`,
        `max_iter`) as there. Pure: `jax.vmap` batches it over stacked setups."""
        return fit_windowed_data(
            self.model,
            self.windows,
            self.data,
            windowed_start(
                self.model, self.windows, self.theta0, self.nodes0, self.linear
            ),
            linear=self.linear,
            active=self.active,
            held=self.held,
            **options,
        )


def oem_setup(
    log: FlightLog,
    *,
    window: float = 0.5,
    node_interval: float = 2.0,
    decimate: int = 5,
    start: str = "lse",
    axes: str = "body",
    single: bool = False,
    min_qbar: float = 2000.0,
    lse=None,
    parameters: str = "hybrid",
    geometry: Geometry | None = None,
) -> tuple[OEMSetup, np.ndarray]:
    """The windowed output-error fit of a log with its starting values (see
    [`estimate_oem`][] for the arguments; `parameters` as there, single shooting
    takes `constant`); returns it with the measured states `[u, w, q, theta]` at the
    decimated samples."""
    if axes not in ("body", "wind"):
        raise ValueError(f"axes must be body or wind, got {axes!r}")
    if parameters not in PARAMETERS:
        raise ValueError(
            f"parameters must be one of {', '.join(PARAMETERS)}, got {parameters!r}"
        )
    if single:
        parameters = "constant"
    terms = {"window": WINDOW_TERMS, "hybrid": HYBRID_TERMS}.get(parameters, ())
    log = _with_geometry(log, geometry)
    layout = WindowLayout.make(len(log), log.sample_rate, window)
    model = thesis_model(geometry, wind_axes=axes == "wind", terms=terms)
    record, idx = thesis_record(log, window=window, decimate=decimate, terms=terms)
    rate = log.sample_rate / decimate
    w = int(round(window * rate))
    windows = Windows.make(
        len(idx), w, w if single else int(round(node_interval * rate))
    )
    if windows.n_windows != layout.count:
        raise ValueError(
            "window layout mismatch after decimation; use a window that is "
            "a whole number of decimated samples"
        )
    alpha_w = jnp.asarray(layout.window_mean(jnp.asarray(log["alpha"])))
    theta0 = jnp.asarray(starting_values(log, layout, start, lse=lse))
    if axes == "body":
        theta0 = to_body(theta0, alpha_w)
    if terms:
        theta0 = jnp.concatenate(
            [theta0, jnp.zeros((theta0.shape[0], len(term_names(terms))))], axis=1
        )
    states = measured_states(log)[idx]
    nodes0 = jnp.asarray(states[windows.node_samples()])
    active = layout.window_mean(jnp.asarray(log["qbar"])) >= min_qbar
    held = np.zeros(theta0.shape, bool)
    if terms:
        k = len(terms)
        u = record.inputs
        y = record.measured
        tau = u[:, len(INPUTS) + TERM_INPUTS.index("tau")]
        known = np.column_stack(
            [
                u[:, INPUTS.index("de")],
                u[:, INPUTS.index("thrust")] / u[:, INPUTS.index("mass")],
            ]
        )

        # alpha departs from its line where the vane sees it or where the loads it
        # drives do (at high dynamic pressure the accelerometers resolve alpha
        # changes far below the vane's noise)
        seen = {"CXa": ("ax", "az"), "CZa": ("ax", "az"), "CMa": ("qdot",)}
        loads = {c for name in terms for c in seen[name]}
        departs = {
            c: departs_from_trend(y[:, OUTPUTS.index(c)], tau, w, known) for c in loads
        }
        alpha = departs_from_trend(y[:, OUTPUTS.index("alpha")], tau, w)
        for i, name in enumerate(terms):
            free = alpha.copy()
            for channel in seen[name]:
                free |= departs[channel]
            held[:, 6 + k + i] = ~free
    setup = OEMSetup(
        model,
        windows,
        window_data(model, record, windows),
        theta0,
        nodes0,
        alpha_w,
        active,
        jnp.asarray(held),
        linear=linear_mask(parameters, terms),
    )
    return setup, states


def _with_geometry(log: FlightLog, geometry: Geometry | None) -> FlightLog:
    """`log` with the vehicle's reference area and length in its metadata, for
    the equation-error start ([`estimate_lse`][] reads them there)."""
    if geometry is None:
        geometry = Geometry(s_ref=S_REF, c_ref=C_REF)
    meta = {**log.metadata, "S_ref": geometry.s_ref, "c_ref": geometry.c_ref}
    return dataclasses.replace(log, metadata=meta)


@eqx.filter_jit
def windowed_lift_drag(fit: WindowedFit, alpha: Float[Array, " windows"], axes: str):
    """A multiple-shooting fit as lift/drag derivatives per window: `(values, stderr
    (coloured-residual corrected), valid, flags)`; NaN where the fit failed. Only
    the six derivatives are reported (with the window terms, their standard errors
    and correlations are those of the full fit, so the terms' uncertainty is in
    them). Pure, so `jax.vmap` applies it to a batch of fits."""
    n_win = fit.params.shape[0]
    corr = fit.correlation[:, :6, :6]
    off = corr * (1.0 - jnp.eye(6))[None]
    flags = {
        "converged": jnp.full(n_win, fit.converged),
        "iterations": jnp.full(n_win, fit.iterations),
        "max_defect": jnp.full(n_win, fit.defect),
        "se_inflation": jnp.mean(
            fit.stderr_corrected[:, :6] / fit.stderr[:, :6], axis=1
        ),
        "max_correlation": jnp.max(jnp.abs(off), axis=(1, 2)),
        "terms_held": jnp.any(fit.held[:, 6:], axis=1),
    }
    ok = fit.converged & fit.active
    cov = covariance(fit.stderr_corrected[:, :6], corr)
    values, sd = _to_lift_drag_with_errors(fit.params[:, :6], cov, alpha, axes)
    return (
        jnp.where(ok[:, None], values, jnp.nan),
        jnp.where(ok[:, None], sd, jnp.nan),
        ok,
        flags,
    )


def _to_lift_drag_with_errors(body, body_cov, alpha, axes):
    """Values and standard errors in lift/drag form from body-axis values and their
    per-window covariance `(windows, 6, 6)` (CLa and CDa both mix CXa and CZa, so
    the correlation matters)."""
    if axes == "wind":
        return body, jnp.sqrt(jnp.clip(jnp.diagonal(body_cov, axis1=1, axis2=2), 0.0))
    values = to_lift_drag(body, alpha)
    jac = jax.vmap(jax.jacfwd(to_lift_drag), in_axes=(0, 0))(body, alpha)
    cov = jnp.einsum("wij,wjk,wlk->wil", jac, body_cov, jac)
    return values, jnp.sqrt(jnp.clip(jnp.diagonal(cov, axis1=1, axis2=2), 0.0))


def estimate_oem(
    log: FlightLog,
    *,
    window: float = 0.5,
    node_interval: float = 2.0,
    shooting: str = "multiple",
    decimate: int = 5,
    start: str = "lse",
    axes: str = "body",
    parameters: str = "hybrid",
    min_qbar: float = 2000.0,
    rtol: float = 1e-5,
    max_iter: int | None = None,
    geometry: Geometry | None = None,
) -> Estimates:
    """Output-error estimates of the six derivatives per window.

    **Arguments:**

    - `log`: a validated flight log.
    - `window`: parameter window, s (0.5). `node_interval`: shooting nodes, s (2).
    - `shooting`: `multiple` (all windows and nodes in one structured
      Levenberg-Marquardt, continuity enforced) or `single` (the thesis's sequential
      windows: each window starts from the previous window's simulated end state,
      only the first from the measurements).
    - `decimate`: fit every n-th sample (default 5: 200 Hz from a 1 kHz log), each
      measurement and each known input the mean of the n samples around it.
    - `start`: starting values, `lse`, `database` or `truth10`.
    - `axes`: estimate body-axis (`body`, the thesis's choice) or lift/drag (`wind`)
      derivatives; results are reported in lift/drag form either way.
    - `parameters` (multiple shooting; default `hybrid`, the one whose standard
      errors cover over the Monte Carlo campaign): `linear` (derivatives continuous and
      linear in time between window boundaries; a window's estimate is their mean
      over the window), `window` (per window the six derivatives and how the alpha
      derivatives change inside it, with time and with alpha, see [`thesis_model`][];
      the reported values are at the window's mean time and alpha: no structural
      bias from secant derivatives, twice the unknowns), `hybrid` (those terms
      for the force derivatives in alpha only, CXa and CZa per window with them;
      the elevator and moment derivatives linear as in `linear`) or `constant` per
      window (the thesis's model).
    - `min_qbar` (multiple shooting): windows whose mean measured dynamic pressure is
      below this (Pa) are not fitted and get no estimate (high in the climb the
      aerodynamic forces vanish into the noise and nothing can be identified).
    - `rtol`: the relative change of det(R) that ends a fit; `max_iter`: an
      iteration bound (default `None`: each fit runs to convergence, within the
      engine's adaptive budget, and says so if it does not).
    - `geometry`: the vehicle's reference area and length (a `Geometry`; default
      the Pegasus vehicle's, 13.5 m^2 and 2.48 m). The log's metadata is not read
      for them.

    **Returns:** [`Estimates`][] in lift/drag form (1/rad) with standard errors
    (multiple shooting: Cramér-Rao corrected for coloured residuals; single:
    Cramér-Rao); flags `converged`, `iterations`, `max_defect`, `se_inflation` (mean
    coloured-residual factor of the window's standard errors), `max_correlation`
    (largest |correlation| between the window's body-axis parameters),
    `terms_held` (multiple shooting: the window's alpha terms were held at zero,
    alpha being linear in time inside it to within its noise, see the module).
    """
    if parameters not in PARAMETERS:
        raise ValueError(
            f"parameters must be one of {', '.join(PARAMETERS)}, got {parameters!r}"
        )
    if shooting not in ("single", "multiple"):
        raise ValueError(f"shooting must be single or multiple, got {shooting!r}")
    layout = WindowLayout.make(len(log), log.sample_rate, window)
    setup, states = oem_setup(
        log,
        window=window,
        node_interval=node_interval,
        decimate=decimate,
        start=start,
        axes=axes,
        single=shooting == "single",
        min_qbar=min_qbar,
        parameters=parameters,
        geometry=geometry,
    )
    if shooting == "multiple":
        fit = setup.fit(rtol=rtol, max_iter=max_iter)
        values, sd, ok, flags = windowed_lift_drag(fit, setup.alpha, axes)
    else:
        body, body_sd, ok, its = _sequential_single(
            setup.model,
            setup.data,
            setup.windows,
            setup.theta0,
            jnp.asarray(states[0]),
            jnp.asarray(rtol, float),
            max_iter=iteration_bound(max_iter),
        )
        flags = {"converged": ok, "iterations": its}
        cov = jax.vmap(jnp.diag)(body_sd**2)  # the sequential fits give no correlation
        values, sd = _to_lift_drag_with_errors(body, cov, setup.alpha, axes)
        values = jnp.where(ok[:, None], values, jnp.nan)
        sd = jnp.where(ok[:, None], sd, jnp.nan)
    start_t, end_t = layout.times(float(log.t[0]))
    return Estimates(
        method="oem",
        window_start=jnp.asarray(start_t),
        window_end=jnp.asarray(end_t),
        values=values,
        stderr=sd,
        valid=ok,
        flags=flags,
        truth=window_truth(
            {k: jnp.asarray(v) for k, v in log.channels.items()}, layout
        ),
    )


@functools.partial(jax.jit, static_argnames=("model", "windows", "max_iter"))
def _sequential_single(model, data, windows, theta0, x0, rtol, max_iter):
    """The thesis's single shooting: window by window, each a one-segment fit on
    the engine from the previous window's simulated end state (held). A padded
    last window is fitted to the record's last sample repeated, as the thesis's
    sequential code did."""
    n, length = windows.n_windows, windows.window
    nx, p = len(model.states), len(model.parameters)
    inputs = _pad(data.inputs[0], n * length + 1)
    measured = _pad(
        data.measured.reshape(-1, data.measured.shape[-1])[: windows.samples],
        n * length,
    )

    def one(x_start, w):
        lay = Layout(
            inputs=inputs[None],
            t0=data.t0,
            dt=data.dt,
            n=jnp.array([n * length + 1]),
            record=jnp.zeros(1, int),
            first=(w * length)[None],
            measured=jax.lax.dynamic_slice_in_dim(measured, w * length, length)[None],
            valid=jnp.ones((1, length), bool),
            link=jnp.zeros(0, bool),
            scale=jnp.ones(nx),
            node_free=jnp.zeros((1, nx), bool),
            length=length,
            bias_channels=(),
        )
        z0 = jnp.concatenate([x_start, theta0[w]])
        sol = solve(
            model,
            lay,
            z0,
            jnp.ones(p, bool),
            nx=nx,
            p=p,
            rtol=rtol,
            max_iter=max_iter,
            coloured=False,
        )
        params = sol.z[nx:]
        sd = jnp.sqrt(jnp.clip(jnp.diag(sol.covariance)[nx:], 0.0))
        xs, _ = segment_solve(model, lay, 0, x_start, params)
        ok = (sol.result == RESULTS.successful) & jnp.all(jnp.isfinite(xs[-1]))
        x_next = jnp.where(ok, xs[-1], x_start)
        return x_next, (params, sd, ok, sol.iterations)

    _, (params, sd, ok, its) = jax.lax.scan(one, x0, jnp.arange(n))
    return params, sd, ok, its


def _pad(x, n):
    return jnp.concatenate([x, jnp.repeat(x[-1:], max(n - x.shape[0], 0), axis=0)])[:n]
