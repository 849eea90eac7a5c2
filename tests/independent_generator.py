"""An independent flight generator for the trust tests (issue 15).

It shares no code with diffpegasus: plain numpy and scipy, its own ISA-like
atmosphere (geometric altitude, four layers), its own inverse-square gravity, its own
Pegasus-like aerodynamic table (smooth in Mach by PCHIP, non-linear in alpha, an
alpha-elevator cross term), its own thrust, mass and inertia model, `solve_ivp`
(DOP853, restarted at every input discontinuity), elevator pulses that are true
steps at times that fall anywhere between samples, and noise levels lower than the
package's simulator. Logs are written in the SPEC section 5 format (CSV plus JSON
sidecar with `S_ref`, `c_ref`, `sample_rate_hz` and the noise sigmas).

Planted effects (SPEC section 6 meaning, implemented here from scratch):
`actuator_delay` (the surface follows the logged command tau s late),
`sensor_bias:az` (constant bias on the az channel), `pitch_damping` (Cmq with
q c / 2V), `moment_offset` (CM0), `thrust_misalignment` (moment = thrust x offset).

The same `seed` gives the same flight (pulse times, drop conditions) at every
sample rate; the noise depends on the seed and the rate.
"""

import json
import pathlib

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import PchipInterpolator


S_REF = 13.5  # m^2
C_REF = 2.48  # m
G0 = 9.80665
R_EARTH = 6.371e6
R_GAS = 287.05287
KAPPA = 1.4

# noise per sample (SI units), the same at every sample rate; lower than the
# package's default sensors on q and qdot (issue 15)
NOISE = {
    "ax": 0.02,
    "az": 0.02,
    "q": 2e-4,
    "qdot": 5e-3,
    "alpha": 1e-3,
    "theta": 5e-4,
    "V": 0.2,
    "h": 2.0,
    "mach": 5e-4,
    "qbar": 20.0,
    "de": 5e-5,
}

EFFECTS = (
    "actuator_delay",
    "sensor_bias:az",
    "pitch_damping",
    "moment_offset",
    "thrust_misalignment",
)

# --- atmosphere: layers (base altitude m, lapse K/m), geometric altitude ----------
_LAYERS = ((0.0, -6.5e-3), (11_000.0, 0.0), (20_000.0, 1.0e-3), (32_000.0, 2.8e-3))


def _layer_bases():
    t, p = 288.15, 101_325.0
    bases = []
    for i, (h0, lapse) in enumerate(_LAYERS):
        bases.append((h0, lapse, t, p))
        if i + 1 < len(_LAYERS):
            dh = _LAYERS[i + 1][0] - h0
            if lapse == 0.0:
                p = p * np.exp(-G0 * dh / (R_GAS * t))
            else:
                t_new = t + lapse * dh
                p = p * (t_new / t) ** (-G0 / (lapse * R_GAS))
                t = t_new
    return bases


_BASES = _layer_bases()


def atmosphere(h):
    """Temperature (K), pressure (Pa), density (kg/m^3), speed of sound (m/s)."""
    h = np.asarray(h, float)
    temp = np.empty_like(h)
    pres = np.empty_like(h)
    for i, (h0, lapse, t0, p0) in enumerate(_BASES):
        top = _BASES[i + 1][0] if i + 1 < len(_BASES) else np.inf
        sel = (h >= h0) & (h < top) if i else h < top
        dh = h[sel] - h0
        if lapse == 0.0:
            temp[sel] = t0
            pres[sel] = p0 * np.exp(-G0 * dh / (R_GAS * t0))
        else:
            temp[sel] = t0 + lapse * dh
            pres[sel] = p0 * (temp[sel] / t0) ** (-G0 / (lapse * R_GAS))
    return temp, pres, pres / (R_GAS * temp), np.sqrt(KAPPA * R_GAS * temp)


def gravity(h):
    return G0 * (R_EARTH / (R_EARTH + h)) ** 2


# --- aerodynamics: a Pegasus-like winged body, per rad ----------------------------
_MACH = np.array([0.5, 0.7, 0.85, 0.95, 1.05, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 6.0])
_TABLE = {
    # lift slope, body cross-flow lift (times alpha|alpha|), elevator lift
    "CLa": [3.0, 3.2, 3.6, 4.0, 4.1, 3.7, 3.1, 2.5, 2.1, 1.8, 1.4, 1.0],
    "CLaa": [2.0, 2.0, 2.1, 2.2, 2.3, 2.3, 2.2, 2.0, 1.9, 1.8, 1.7, 1.6],
    "CLde": [0.60, 0.62, 0.66, 0.68, 0.62, 0.52, 0.42, 0.33, 0.27, 0.23, 0.18, 0.13],
    # drag: CD = (CDa + CDaa alpha) alpha + CDde de (the thesis form, no CD0)
    "CDa": [0.10, 0.10, 0.12, 0.20, 0.26, 0.22, 0.18, 0.15, 0.13, 0.12, 0.10, 0.08],
    "CDaa": [1.4, 1.5, 1.6, 1.9, 2.1, 1.9, 1.6, 1.3, 1.1, 1.0, 0.9, 0.8],
    "CDde": [0.05, 0.05, 0.06, 0.08, 0.09, 0.08, 0.07, 0.06, 0.05, 0.05, 0.04, 0.03],
    # moment about the reference station (logged as xcp): small, stable
    "CMa": [
        -0.12,
        -0.13,
        -0.15,
        -0.18,
        -0.20,
        -0.17,
        -0.14,
        -0.11,
        -0.09,
        -0.08,
        -0.06,
        -0.05,
    ],
    "CMaa": [
        -0.3,
        -0.3,
        -0.3,
        -0.35,
        -0.4,
        -0.35,
        -0.3,
        -0.25,
        -0.2,
        -0.2,
        -0.15,
        -0.1,
    ],
    "CMde": [
        -1.00,
        -1.03,
        -1.10,
        -1.12,
        -1.02,
        -0.86,
        -0.70,
        -0.55,
        -0.45,
        -0.38,
        -0.30,
        -0.22,
    ],
}
_FINE = np.linspace(_MACH[0], _MACH[-1], 5501)
_SMOOTH = {k: PchipInterpolator(_MACH, np.array(v))(_FINE) for k, v in _TABLE.items()}


def _tab(name, mach):
    return np.interp(mach, _FINE, _SMOOTH[name])


def coefficients(alpha, de, mach):
    """CL, CD and CM (about the reference station) of the clean vehicle."""
    cross = 1.0 - 0.5 * np.abs(alpha)  # elevator loses authority at high alpha
    cl = _tab("CLa", mach) * alpha + _tab("CLaa", mach) * alpha * np.abs(alpha)
    cl = cl + _tab("CLde", mach) * cross * de
    cd = (_tab("CDa", mach) + _tab("CDaa", mach) * alpha) * alpha
    cd = cd + _tab("CDde", mach) * de
    cm = _tab("CMa", mach) * alpha + _tab("CMaa", mach) * alpha * np.abs(alpha)
    cm = cm + _tab("CMde", mach) * cross * de
    return cl, cd, cm


def reference_station(mach):
    """Moment reference station (m from the nose, aft positive), moving aft
    supersonically as the lift moves onto the wing."""
    return 7.75 + 0.2 * np.tanh((mach - 1.1) / 0.35)


# --- motor and mass ---------------------------------------------------------------
T_IGNITION = 5.0
T_VAC = 470e3
ISP = 288.0
A_EXIT = 1.5
M_LAUNCH = 18_400.0
M_PROPELLANT = 12_300.0


def motor(t, p_ambient):
    """Net thrust (N) and mass flow (kg/s, negative): a 0.4 s cosine rise after
    ignition (the nozzle pressure loss rising with it), then regressive."""
    s = np.clip((t - T_IGNITION) / 0.4, 0.0, 1.0)
    rise = 0.5 - 0.5 * np.cos(np.pi * s)
    vac = T_VAC * (1.0 - 0.002 * np.maximum(t - T_IGNITION, 0.0))
    return rise * (vac - A_EXIT * p_ambient), -rise * vac / (ISP * G0)


def inertia(m):
    """Iyy (kg m^2) and the CG station (m) of the vehicle of mass `m`."""
    burnt = (M_LAUNCH - m) / M_PROPELLANT
    return 1.15e5 + 13.0 * (m - 6_100.0), 7.05 + 0.45 * burnt


# --- the flight -------------------------------------------------------------------
def elevator_schedule(seed: int, duration: float):
    """Step times and levels (rad) of the logged elevator command: a nominal
    nose-up deflection with steps to a pull-up trim after ignition, and 0.2-0.35 s
    pulses of +/- 1.5-2.5 deg at jittered times (not on any sample grid)."""
    rng = np.random.default_rng(10_000 + seed)
    times = [0.0]
    levels = [np.deg2rad(-3.0)]
    t_trim = 6.0 + rng.uniform(0.0, 0.2)
    nominal = lambda t: np.deg2rad(-3.0 if t < t_trim else -11.0)  # noqa: E731
    t = 1.0 + rng.uniform(0.0, 0.3)
    sign = 1.0
    while t < duration - 0.6:
        width = rng.uniform(0.2, 0.35)
        amp = np.deg2rad(rng.uniform(1.5, 2.5)) * sign
        times += [t, t + width]
        levels += [nominal(t) + amp, nominal(t + width)]
        sign = -sign
        t += width + rng.uniform(0.45, 0.85)
    # the trim step of the pull-up, between two pulses
    order = np.argsort(times, kind="stable")
    times, levels = np.array(times)[order], np.array(levels)[order]
    trim = np.searchsorted(times, t_trim)
    times = np.insert(times, trim, t_trim)
    levels = np.insert(levels, trim, levels[trim - 1] + np.deg2rad(-8.0))
    return times, levels


def _step_value(t, times, levels):
    return levels[np.searchsorted(times, t, side="right") - 1]


class _Flight:
    def __init__(self, times, levels, effects):
        self.times = times
        self.levels = levels
        self.tau = effects.get("actuator_delay", 0.0)
        self.cmq = effects.get("pitch_damping", 0.0)
        self.cm0 = effects.get("moment_offset", 0.0)
        self.offset = effects.get("thrust_misalignment", 0.0)

    def surface(self, t):
        # the surface follows the command tau late
        return _step_value(t - self.tau, self.times, self.levels)

    def evaluate(self, t, x, de):
        """Rates and every measured quantity; works on scalars and arrays."""
        u, w, q, theta, _, h, m = x
        _, p, rho, a = atmosphere(np.atleast_1d(h))
        p, rho, a = (
            p.reshape(np.shape(h)),
            rho.reshape(np.shape(h)),
            a.reshape(np.shape(h)),
        )
        v = np.sqrt(u**2 + w**2)
        alpha = np.arctan2(w, u)
        mach = v / a
        qbar = 0.5 * rho * v**2
        thrust, mdot = motor(t, p)
        iyy, xcg = inertia(m)
        iyy_dot = 13.0 * mdot
        cl, cd, cm = coefficients(alpha, de, mach)
        cm = cm + self.cm0 + self.cmq * q * C_REF / (2.0 * v)
        lift, drag = qbar * S_REF * cl, qbar * S_REF * cd
        ca, sa = np.cos(alpha), np.sin(alpha)
        fx = -drag * ca + lift * sa + thrust
        fz = -drag * sa - lift * ca
        xref = reference_station(mach)
        moment = qbar * S_REF * C_REF * cm + (xref - xcg) * fz + self.offset * thrust
        g = gravity(h)
        udot = fx / m - g * np.sin(theta) - q * w
        wdot = fz / m + g * np.cos(theta) + q * u
        qdot = (moment - iyy_dot * q) / iyy
        xdot = u * np.cos(theta) + w * np.sin(theta)
        hdot = u * np.sin(theta) - w * np.cos(theta)
        rates = np.array([udot, wdot, qdot, q, xdot, hdot, mdot])
        out = {
            "ax": fx / m,
            "az": fz / m,
            "q": q,
            "qdot": qdot,
            "alpha": alpha,
            "V": v,
            "theta": theta,
            "h": h,
            "mach": mach,
            "qbar": qbar,
            "thrust": thrust,
            "mass": m,
            "Iyy": iyy,
            "Iyy_dot": iyy_dot,
            "xcg": xcg,
            "xcp": xref,
        }
        return rates, out

    def rhs(self, t, x, de):
        return self.evaluate(t, x, de)[0]


def drop_state(seed: int) -> np.ndarray:
    """`[u, w, q, theta, x, h, mass]` at drop: 12.2-12.8 km, Mach 0.78-0.82."""
    rng = np.random.default_rng(20_000 + seed)
    h = rng.uniform(12_200.0, 12_800.0)
    mach = rng.uniform(0.78, 0.82)
    alpha = np.deg2rad(rng.uniform(1.5, 2.5))
    v = mach * atmosphere(np.array([h]))[3][0]
    return np.array(
        [v * np.cos(alpha), v * np.sin(alpha), 0.0, alpha, 0.0, h, M_LAUNCH]
    )


def generate(
    seed: int = 0,
    sample_rate: float = 1000.0,
    duration: float = 30.0,
    effects: dict[str, float] | None = None,
    noise: bool = True,
) -> tuple[dict[str, np.ndarray], dict]:
    """One flight from drop: `(channels, metadata)` in the SPEC section 5 format.

    **Arguments:** `seed` (flight and noise); `sample_rate` (Hz); `duration` (s);
    `effects` (name in [`EFFECTS`][] to value, SI units); `noise`.
    """
    effects = dict(effects or {})
    unknown = set(effects) - set(EFFECTS)
    if unknown:
        raise ValueError(f"unknown effects {sorted(unknown)}; known {EFFECTS}")
    times, levels = elevator_schedule(seed, duration)
    channels = _fly(
        _Flight(times, levels, effects), seed, sample_rate, duration, 1e-10, 1e-9
    )
    channels["az"] = channels["az"] + effects.get("sensor_bias:az", 0.0)
    _add_noise(channels, seed, sample_rate, noise)
    return channels, _metadata(seed, sample_rate, noise, hidden_effects=effects)


def _fly(flight, seed, sample_rate, duration, rtol, atol) -> dict[str, np.ndarray]:
    """The noiseless channels of `flight` from the seed's drop state: integrated
    piece by piece between the surface's steps (a true step: the solver never
    straddles it), sampled at `sample_rate` (Hz) for `duration` (s)."""
    times, levels = flight.times, flight.levels
    n = int(round(duration * sample_rate)) + 1
    t = np.arange(n) / sample_rate
    edges = np.unique(np.clip(times + flight.tau, 0.0, duration))
    edges = np.concatenate([[0.0], edges[(edges > 0) & (edges < duration)], [duration]])
    x = drop_state(seed)
    states = np.empty((n, 7))
    de_surface = np.empty(n)
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        de = _step_value(0.5 * (a + b) - flight.tau, times, levels)
        sel = (t >= a) & ((t < b) | ((b == duration) & (t <= b)))
        sol = solve_ivp(
            flight.rhs,
            (a, b),
            x,
            method="DOP853",
            rtol=rtol,
            atol=atol,
            args=(de,),
            dense_output=True,
        )
        if not sol.success:
            raise RuntimeError(f"integration failed at t = {a}: {sol.message}")
        if sel.any():
            states[sel] = sol.sol(t[sel]).T
            de_surface[sel] = de
        x = sol.y[:, -1]
    _, out = flight.evaluate(t, states.T, de_surface)
    channels = {"t": t, "de": _step_value(t, times, levels)}
    channels.update({k: np.asarray(v, float) * np.ones(n) for k, v in out.items()})
    return channels


def _add_noise(channels, seed, sample_rate, noise):
    """White measurement noise of [`NOISE`][]'s sigmas, in place (a seed and rate's
    own draws)."""
    if noise:
        n = channels["t"].shape[0]
        rng = np.random.default_rng([seed, int(round(sample_rate))])
        for name, sigma in NOISE.items():
            channels[name] = channels[name] + sigma * rng.normal(size=n)


def _metadata(seed, sample_rate, noise, **extra) -> dict:
    return {
        "S_ref": S_REF,
        "c_ref": C_REF,
        "vehicle": "pegasus-like (independent generator)",
        "sample_rate_hz": float(sample_rate),
        "seed": seed,
        "noise_sigmas": dict(NOISE) if noise else {},
        **extra,
        "simulator": "tests/independent_generator.py",
    }


def write(path, channels: dict[str, np.ndarray], metadata: dict) -> pathlib.Path:
    """Write CSV plus JSON sidecar (same stem); returns the CSV path."""
    path = pathlib.Path(path)
    names = list(channels)
    data = np.column_stack([channels[c] for c in names])
    with path.open("w") as f:
        f.write(",".join(names) + "\n")
        np.savetxt(f, data, delimiter=",", fmt="%.17g")
    path.with_suffix(".json").write_text(json.dumps(metadata, indent=2))
    return path


def make_log(path, seed=0, sample_rate=1000.0, duration=30.0, effects=None, noise=True):
    """Generate and write one flight; returns the CSV path."""
    return write(path, *generate(seed, sample_rate, duration, effects, noise))


# --- a second vehicle: the HFB-320 business jet (for the engine's diagnosis) -------
# The book's longitudinal model (Jategaonkar, test case 4) written out here, with
# the aerodynamics identified on the real record, its constants, and its initial
# state; what differs from the package's simulation (`simulate --vehicle hfb320`):
# a 3-2-1-1 of true steps starting between samples, integration by DOP853
# restarted at each step, other noise levels.
HFB = {
    "g": 9.80665,
    "s_over_m": 4.028e-3,
    "sc_over_iy": 8.0027e-4,
    "thrust_moment": -7.0153e-6,
    "v0": 104.67,
    "mass": 7472.0,
    "sigma_t": 0.0524,
    "rho": 0.792,
    "cbar": 1.215,
    "x0": (106.023, 0.111685, 0.104887, -0.00332659),
    "de_trim": -0.0075,
    "thrust": 11633.0,
}
HFB_AERO = {
    "CD0": 0.117776,
    "CDV": -0.0517719,
    "CDa": 0.234949,
    "CL0": -0.204497,
    "CLV": 0.363406,
    "CLa": 3.21170,
    "CM0": 0.134393,
    "CMV": -0.0138949,
    "CMa": -1.00232,
    "CMq": -27.0630,
    "CMde": -1.43719,
}
HFB_NOISE = {
    "V": 0.15,
    "alpha": 7e-4,
    "theta": 7e-4,
    "q": 3e-4,
    "qdot": 3e-3,
    "ax": 0.03,
    "az": 0.03,
}


def _hfb_evaluate(x, de, thrust, cla2=0.0):
    c = HFB
    p = HFB_AERO
    v, alpha, theta, q = x
    qbar = 0.5 * c["rho"] * v**2
    cd = p["CD0"] + p["CDV"] * v / c["v0"] + p["CDa"] * alpha
    # with alpha^2 lift, CL0 moves so that the initial state stays trimmed
    alpha0 = c["x0"][1]
    cl = (
        p["CL0"]
        + p["CLV"] * v / c["v0"]
        + p["CLa"] * alpha
        + cla2 * (alpha**2 - alpha0**2)
    )
    cm = (
        p["CM0"]
        + p["CMV"] * v / c["v0"]
        + p["CMa"] * alpha
        + p["CMq"] * q * c["cbar"] / c["v0"]
        + p["CMde"] * de
    )
    f_m = thrust / c["mass"]
    vdot = (
        -c["s_over_m"] * qbar * cd
        + f_m * np.cos(alpha + c["sigma_t"])
        + c["g"] * np.sin(alpha - theta)
    )
    alphadot = (
        -c["s_over_m"] * qbar / v * cl
        - f_m / v * np.sin(alpha + c["sigma_t"])
        + q
        + c["g"] / v * np.cos(alpha - theta)
    )
    qdot = c["sc_over_iy"] * qbar * cm + c["thrust_moment"] * thrust
    cx = cl * np.sin(alpha) - cd * np.cos(alpha)
    cz = -cl * np.cos(alpha) - cd * np.sin(alpha)
    out = {
        "V": v,
        "alpha": alpha,
        "theta": theta,
        "q": q,
        "qdot": qdot,
        "ax": c["s_over_m"] * qbar * cx + f_m * np.cos(c["sigma_t"]),
        "az": c["s_over_m"] * qbar * cz - f_m * np.sin(c["sigma_t"]),
    }
    return np.array([vdot, alphadot, q, qdot]), out


HFB_EFFECTS = ("actuator_delay", "lift_alpha_squared") + tuple(
    f"sensor_bias:{name}" for name in HFB_NOISE
)


def _hfb_gusty_rates(t, y, de, gusts, cla2):
    """Inertial body-axis velocity `(u, w)`, `theta`, `q` through the wind
    `gusts(t) -> (u_g, w_g)` (earth axes, w_g down): the forces from the
    air-relative velocity, the kinematics from the inertial one. With no wind
    this is the book's (V, alpha) model rewritten in body axes."""
    u, w, theta, q = y
    ug, wg = gusts(t)
    ua = u - (ug * np.cos(theta) - wg * np.sin(theta))
    wa = w - (ug * np.sin(theta) + wg * np.cos(theta))
    air = np.array([np.hypot(ua, wa), np.arctan2(wa, ua), theta, q])
    rates, out = _hfb_evaluate(air, de, HFB["thrust"], cla2)
    g = HFB["g"]
    return np.array(
        [
            out["ax"] - q * w - g * np.sin(theta),
            out["az"] + q * u + g * np.cos(theta),
            q,
            rates[3],
        ]
    ), air


def _uniform_spline(spline):
    """`spline` (a CubicSpline on a uniform grid) evaluated at one time by its
    piecewise polynomial directly: a tenth of the call's cost, which the
    integrator pays ~1e5 times a flight."""
    c, x = spline.c, spline.x
    step, last = x[1] - x[0], len(x) - 2

    def at(t):
        i = min(max(int((t - x[0]) / step), 0), last)
        d = t - x[i]
        return ((c[0, i] * d + c[1, i]) * d + c[2, i]) * d + c[3, i]

    return at


def generate_hfb320(
    seed: int = 0,
    sample_rate: float = 10.0,
    duration: float = 30.0,
    effects: dict[str, float] | None = None,
    noise: bool = True,
    actuator: float | None = None,
    gust_sigma: float = 0.0,
) -> tuple[dict[str, np.ndarray], dict]:
    """One HFB-320 flight: `(channels, metadata)`, channels `t, de, thrust, V,
    alpha, theta, q, qdot, ax, az` (SI, rad). A 3-2-1-1 of +/- 0.01 rad steps
    (1 s unit) from 2 s plus a random fraction of a sample: true steps of the
    logged surface, or with `actuator` (time constant, s) commanded steps that the
    surface (logged) follows as a first-order lag. Effects (`HFB_EFFECTS`):
    `actuator_delay` (s: the surface moves that much after the logged one),
    `lift_alpha_squared` (CL += value alpha^2, CL0 -= value alpha0^2: the
    initial state stays trimmed), `sensor_bias:<output>` (channel
    units). `gust_sigma` (m/s): the flight through `gust_field`'s gusts (both
    components, 533 m scale) instead of still air; V and alpha are air-relative."""
    effects = dict(effects or {})
    unknown = set(effects) - set(HFB_EFFECTS)
    if unknown:
        raise ValueError(f"unknown effects {sorted(unknown)} for the HFB-320")
    delay = effects.get("actuator_delay", 0.0)
    if delay and actuator is not None:
        raise ValueError("actuator_delay with an actuator lag is not modelled")
    cla2 = effects.get("lift_alpha_squared", 0.0)
    rng = np.random.default_rng(30_000 + seed)
    start = 2.0 + rng.uniform(0.0, 1.0) / sample_rate
    times = start + np.array([0.0, 3.0, 5.0, 6.0, 7.0])
    levels = HFB["de_trim"] + 0.01 * np.array([1.0, -1.0, 1.0, -1.0, 0.0])
    times = np.concatenate([[0.0], times])
    levels = np.concatenate([[HFB["de_trim"]], levels])
    n = int(round(duration * sample_rate)) + 1
    t = np.arange(n) / sample_rate
    acting = times + np.where(times > 0.0, delay, 0.0)
    edges = np.concatenate([acting, [duration]])
    gusts = None
    x = np.array([*HFB["x0"], HFB["de_trim"]], float)
    if gust_sigma > 0.0:
        gusts = _uniform_spline(gust_field(seed, duration, gust_sigma, HFB["x0"][0]))
        ug, wg = gusts(0.0)
        v, alpha, theta = HFB["x0"][:3]
        # the aircraft starts trimmed in the moving air mass
        x[0] = v * np.cos(alpha) + ug * np.cos(theta) - wg * np.sin(theta)
        x[1] = v * np.sin(alpha) + ug * np.sin(theta) + wg * np.cos(theta)
    states = np.empty((n, 5))
    for a, b, de in zip(edges[:-1], edges[1:], levels, strict=True):
        sel = (t >= a) & ((t < b) | ((b == duration) & (t <= b)))

        def rhs(tt, y, de=de):
            surface = de if actuator is None else y[4]
            if gusts is None:
                rates = _hfb_evaluate(y[:4], surface, HFB["thrust"], cla2)[0]
            else:
                rates = _hfb_gusty_rates(tt, y[:4], surface, gusts, cla2)[0]
            lag = 0.0 if actuator is None else (de - y[4]) / actuator
            return np.append(rates, lag)

        if actuator is None:
            x[4] = de
        sol = solve_ivp(
            rhs,
            (a, b),
            x,
            method="DOP853",
            # the gust spline is only C2 at its 10 ms knots: a tighter tolerance
            # there costs minutes and no accuracy the noise could show
            rtol=1e-11 if gusts is None else 1e-9,
            atol=1e-12 if gusts is None else 1e-10,
            dense_output=True,
        )
        if sel.any():
            states[sel] = sol.sol(t[sel]).T
        x = sol.y[:, -1]
    surface = states[:, 4]
    if gusts is None:
        air = states[:, :4].T
    else:
        air = np.stack(
            [
                _hfb_gusty_rates(tk, yk, 0.0, gusts, cla2)[1]
                for tk, yk in zip(t, states[:, :4], strict=True)
            ],
            axis=1,
        )
    _, out = _hfb_evaluate(air, surface, HFB["thrust"], cla2)
    out["q"] = states[:, 3]
    if gusts is not None:
        # qdot from the inertial q's equation at the surface actually acting
        out["qdot"] = np.array(
            [
                _hfb_gusty_rates(tk, yk, dk, gusts, cla2)[0][3]
                for tk, yk, dk in zip(t, states[:, :4], surface, strict=True)
            ]
        )
    logged = surface
    if delay:
        logged = levels[np.searchsorted(times, t, side="right") - 1]
    channels = {"t": t, "de": logged, "thrust": np.full(n, HFB["thrust"])}
    channels.update({k: np.asarray(v, float) for k, v in out.items()})
    for name, value in effects.items():
        if name.startswith("sensor_bias:"):
            channels[name.split(":", 1)[1]] = channels[name.split(":", 1)[1]] + value
    if noise:
        rng = np.random.default_rng([seed, int(round(sample_rate)), 320])
        for name, sigma in HFB_NOISE.items():
            channels[name] = channels[name] + sigma * rng.normal(size=n)
    metadata = {
        "vehicle": "hfb320 (independent generator)",
        "S_ref": HFB["s_over_m"] * HFB["mass"],
        "c_ref": HFB["cbar"],
        "sample_rate_hz": float(sample_rate),
        "seed": seed,
        "noise_sigmas": dict(HFB_NOISE) if noise else {},
        "truth": dict(HFB_AERO),
        "actuator_time_constant_s": actuator,
        "hidden_effects": effects,
        "simulator": "tests/independent_generator.py",
    }
    if gusts is not None:
        metadata["turbulence"] = {
            "sigma": gust_sigma,
            "length_m": GUST_LENGTH,
            "model": "Gauss-Markov",
        }
    return channels, metadata


# --- turbulence for the Pegasus-like flight ---------------------------------------
# Written for the filter-error tests from the textbook gust model, not from the
# package's: each earth-axis gust component (u_g forward, w_g down) is a first-order
# Gauss-Markov process (the Dryden longitudinal form) of intensity sigma and time
# constant L / V, drawn by its exact discrete recursion on a 10 ms grid and
# interpolated by a cubic spline, so the integrator sees a smooth wind. The
# vehicle's states stay inertial; the aerodynamics, V and alpha see the air.
GUST_LENGTH = 533.0  # m (1750 ft)
GUST_STEP = 0.01  # s


def gust_field(seed: int, duration: float, sigma: float, airspeed: float):
    """`t -> (u_g, w_g)` (m/s, earth axes, w_g down) for `duration` s: the same
    realisation for a seed at every sample rate."""
    from scipy.interpolate import CubicSpline

    rng = np.random.default_rng([seed, 7_777])
    n = int(np.ceil(duration / GUST_STEP)) + 3
    a = np.exp(-GUST_STEP * airspeed / GUST_LENGTH)
    kick = sigma * np.sqrt(1.0 - a * a)
    g = np.empty((n, 2))
    g[0] = sigma * rng.normal(size=2)
    for k in range(1, n):
        g[k] = a * g[k - 1] + kick * rng.normal(size=2)
    return CubicSpline(GUST_STEP * (np.arange(n) - 1), g, axis=0)


class _GustyFlight(_Flight):
    """The flight of `_Flight` through the wind `gusts(t) -> (n, 2)`."""

    def __init__(self, times, levels, effects, gusts):
        super().__init__(times, levels, effects)
        self.gusts = gusts

    def evaluate(self, t, x, de):
        ug, wg = np.moveaxis(np.asarray(self.gusts(t)), -1, 0)
        u, w, q, theta = x[0], x[1], x[2], x[3]
        ugb = ug * np.cos(theta) - wg * np.sin(theta)
        wgb = ug * np.sin(theta) + wg * np.cos(theta)
        air = np.array(x, float, copy=True)
        air[0], air[1] = u - ugb, w - wgb
        # forces and air data from the air-relative velocity; the kinematics of
        # the inertial one: the parent's rates corrected by the wind terms
        rates, out = super().evaluate(t, air, de)
        rates = np.array(rates, float)
        rates[0] = rates[0] - q * wgb
        rates[1] = rates[1] + q * ugb
        rates[4] = rates[4] + ug
        rates[5] = rates[5] - wg
        return rates, out


def generate_turbulent(
    seed: int = 0,
    sample_rate: float = 1000.0,
    duration: float = 30.0,
    sigma: float = 1.5,
    noise: bool = True,
) -> tuple[dict[str, np.ndarray], dict]:
    """[`generate`][]'s flight (same seed: same drop, pulses and noise) flown
    through gusts of intensity `sigma` (m/s, both components)."""
    times, levels = elevator_schedule(seed, duration)
    x = drop_state(seed)
    gusts = gust_field(seed, duration, sigma, float(np.hypot(x[0], x[1])))
    flight = _GustyFlight(times, levels, {}, gusts)
    channels = _fly(flight, seed, sample_rate, duration, 1e-9, 1e-8)
    _add_noise(channels, seed, sample_rate, noise)
    turbulence = {"sigma": sigma, "length_m": GUST_LENGTH, "model": "Gauss-Markov"}
    return channels, _metadata(
        seed, sample_rate, noise, hidden_effects={}, turbulence=turbulence
    )


def make_turbulent_log(path, seed=0, sample_rate=1000.0, duration=30.0, sigma=1.5):
    """Generate and write one turbulent flight; returns the CSV path."""
    return write(path, *generate_turbulent(seed, sample_rate, duration, sigma))
