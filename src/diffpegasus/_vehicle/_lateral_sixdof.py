"""The 6-DOF lateral-directional model for output error (side force, roll and yaw
equations; measured longitudinal motion as pseudo-inputs), simulated lateral logs of
the business jet, and the linear derivatives a 6-DOF aircraft implies."""

from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np

from .._model import Model
from ._effects import make_effect
from ._lateral import LATERAL_DERIVATIVES
from ._parts import effect_parameter
from ._sixdof import (
    G,
    lateral_coefficients,
    LATERAL_DERIVATIVE_NAMES,
    LateralDerivatives,
    rigid_body_rates,
)


SIXDOF_LATERAL_STATES = ("v", "p", "r", "phi")
SIXDOF_LATERAL_INPUTS = ("da", "dr", "u", "w", "q", "theta")
SIXDOF_LATERAL_OUTPUTS = ("beta", "p", "r", "phi", "ay", "pdot", "rdot")
# The library effects that compose with the 6-DOF lateral model (`effects=`): a
# sideslip (vane) offset and biases of the lateral accelerometer and rate gyros.
SIXDOF_LATERAL_EFFECTS = (
    "sensor_bias:beta",
    "sensor_bias:ay",
    "sensor_bias:p",
    "sensor_bias:r",
)


def sixdof_lateral_model(
    *,
    mass: float,
    inertia,
    s_ref: float,
    b_ref: float,
    rho: float,
    start: dict | None = None,
    fixed: Sequence[str] = (),
    effects: Sequence[str] = (),
    free: Sequence[str] = (),
) -> Model:
    """The 6-DOF side-force, rolling and yawing equations of a rigid aircraft, with
    the measured longitudinal motion as pseudo-inputs.

    **Arguments:** `mass` (kg), `inertia` the `(3, 3)` tensor (kg m^2, see
    [`inertia_tensor`][]), reference area `s_ref` (m^2) and span `b_ref` (m), air
    density `rho` (kg/m^3); `start` values of the parameters by name (default 0)
    and `fixed` names; `effects`: library sensor biases on the outputs
    (`sensor_bias:<output>`, e.g. [`SIXDOF_LATERAL_EFFECTS`][]: the sideslip offset
    and the `ay, p, r` biases), each adding its parameter (`sensor_bias:ay.bias`,
    start 0, output units) held at zero unless named (with or without `.bias`) in
    `free`: the candidates of [`diagnose_model`][] (with a derivative held at zero,
    e.g. `Cn_r` for yaw damping missing).

    **Returns:** a [`Model`][]: states `v` (m/s, body y velocity), `p, r` (rad/s),
    `phi` (rad); inputs `da, dr` (rad), body velocities `u, w` (m/s), pitch rate
    `q` (rad/s) and pitch attitude `theta` (rad); outputs `beta` (rad), `p, r`,
    `phi`, `ay` (m/s^2, body y specific force), `pdot, rdot` (rad/s^2); the
    parameters [`LATERAL_DERIVATIVE_NAMES`][] (`CY_beta` ... `Cn_dr`, per rad).
    """
    inertia = np.asarray(inertia, float)
    effects = tuple(effects)
    for e in effects:
        name, _, channel = e.partition(":")
        if name != "sensor_bias" or channel not in SIXDOF_LATERAL_OUTPUTS:
            raise ValueError(
                f"effect {e!r} does not compose with the 6-DOF lateral model; it "
                f"takes sensor_bias:<output> for an output of {SIXDOF_LATERAL_OUTPUTS}"
            )
    extra = {effect_parameter(e): 0.0 for e in effects}
    values = dict.fromkeys(LATERAL_DERIVATIVE_NAMES, 0.0) | extra
    for k, v in (start or {}).items():
        if k not in values:
            raise ValueError(f"{k!r} is not a parameter of this model")
        values[k] = float(v)
    held = tuple(k for k in extra if k not in free and k.split(".")[0] not in free)

    def evaluate(x, u, p):
        v, roll, yaw, phi = x
        da, dr, ub, wb, q, theta = u
        speed = jnp.sqrt(ub**2 + v**2 + wb**2)
        beta = jnp.arcsin(v / speed)
        derivs = LateralDerivatives(**{k: p[k] for k in LATERAL_DERIVATIVE_NAMES})
        cy, cl, cn = lateral_coefficients(derivs, beta, roll, yaw, da, dr, speed, b_ref)
        qbar = 0.5 * rho * speed**2
        fy = qbar * s_ref * cy
        moment = qbar * s_ref * b_ref * jnp.stack([cl, 0.0, cn])
        # the x and z forces and the pitching moment do not enter the v, p, r rows
        vel_dot, omega_dot, euler_dot = rigid_body_rates(
            jnp.stack([ub, v, wb]),
            jnp.stack([roll, q, yaw]),
            jnp.stack([phi, theta, 0.0]),
            jnp.stack([0.0, fy, 0.0]),
            moment,
            mass,
            jnp.asarray(inertia),
            jnp.zeros((3, 3)),
            G,
        )
        rates = jnp.stack([vel_dot[1], omega_dot[0], omega_dot[2], euler_dot[0]])
        channels = dict(
            zip(
                SIXDOF_LATERAL_OUTPUTS,
                (beta, roll, yaw, phi, fy / mass, omega_dot[0], omega_dot[2]),
                strict=True,
            )
        )
        # the library's sensor effects, through their measurement hook (a sensor
        # bias reads no flight condition)
        for e in effects:
            effect = make_effect(e, p[effect_parameter(e)])
            channels = effect.measure(channels, None)  # pyright: ignore[reportArgumentType]
        return rates, jnp.stack([channels[n] for n in SIXDOF_LATERAL_OUTPUTS])

    def rates(t, x, u, p):
        del t
        return evaluate(x, u, p)[0]

    def observe(t, x, u, p):
        del t
        return evaluate(x, u, p)[1]

    return Model(
        states=SIXDOF_LATERAL_STATES,
        inputs=SIXDOF_LATERAL_INPUTS,
        outputs=SIXDOF_LATERAL_OUTPUTS,
        parameters=values,
        rates=rates,
        observe=observe,
        fixed=tuple(dict.fromkeys(tuple(fixed) + held)),
    )


# --- simulated lateral logs ------------------------------------------------------


# Sensor noise of simulated lateral logs (1 sigma; rad, rad/s, m/s^2, rad/s^2).
LATERAL_NOISE = {
    "beta": 1e-3,
    "p": 2e-3,
    "r": 1e-3,
    "phi": 2e-3,
    "ay": 0.05,
    "pdot": 0.01,
    "rdot": 0.005,
}
LATERAL_SPEED = 104.67  # m/s, the HFB-320 record's speed


def simulate_lateral_log(
    duration: float = 25.0,
    rate: float = 25.0,
    seed: int = 0,
    noise: bool = True,
    first: str = "aileron",
    hidden: dict[str, float] | None = None,
) -> tuple[dict[str, np.ndarray], dict]:
    """A simulated lateral manoeuvre of the 6-DOF business jet ([`business_jet`][],
    trimmed level at 104.67 m/s): with `first="aileron"` an aileron 3-2-1-1 (3 deg,
    0.5 s unit, from 1 s) then a rudder doublet (3 deg, 1.2 s, from 9 s); with
    `"rudder"` a rudder 3-2-1-1 (0.6 s unit) then an aileron doublet (1 s, from 12
    s). RK4 at the log step `1 / rate` (s); white noise ([`LATERAL_NOISE`][]) on the
    measured lateral channels; `hidden`: sensor biases to plant, `{"sensor_bias:ay":
    0.1}` (channel units).

    **Returns:** `(channels, metadata)`: the channels of [`simulate_sixdof`][] (the
    linear model's `da, dr, beta, pdot, rdot, ay, p, r`, the 6-DOF lateral model's
    `v, phi, u, w, q, theta`, ...) `(samples,)` and the sidecar metadata with the
    true coefficient derivatives and the implied linear-model derivatives
    ([`implied_lateral_derivatives`][]).
    """
    from .._inputs import doublet, three_two_one_one
    from ._sixdof import business_jet, simulate_sixdof, trim

    if first not in ("aileron", "rudder"):
        raise ValueError(f"first must be 'aileron' or 'rudder', got {first!r}")
    hidden = dict(hidden or {})
    for name in hidden:
        kind, _, channel = name.partition(":")
        if kind != "sensor_bias" or channel not in LATERAL_NOISE:
            raise ValueError(
                f"{name} cannot be planted in a lateral log; it takes sensor_bias:"
                f"<channel> for {', '.join(LATERAL_NOISE)}"
            )
    # the input schedules take degrees
    if first == "aileron":
        controls = dict(
            aileron=three_two_one_one(3.0, 0.5, start=1.0, rise=0.08),
            rudder=doublet(3.0, 1.2, start=9.0, rise=0.08),
        )
    else:
        controls = dict(
            aileron=doublet(3.0, 1.0, start=12.0, rise=0.08),
            rudder=three_two_one_one(3.0, 0.6, start=1.0, rise=0.08),
        )
    aircraft = business_jet()
    start = trim(aircraft, LATERAL_SPEED)
    flight = simulate_sixdof(
        aircraft, start, t_final=duration, dt=1.0 / rate, **controls
    )
    rng = np.random.default_rng(seed)
    channels = {k: np.asarray(v, float) for k, v in flight.items()}
    for name, sigma in LATERAL_NOISE.items():
        if noise:
            channels[name] = channels[name] + sigma * rng.normal(size=len(flight["t"]))
    for name, value in hidden.items():
        channel = name.partition(":")[2]
        channels[channel] = channels[channel] + float(value)
    truth = {n: float(getattr(aircraft.lateral, n)) for n in LATERAL_DERIVATIVE_NAMES}
    metadata = {
        "vehicle": "hfb320-lateral",
        "aircraft": "business_jet (HFB-320 mass, area, chord; lateral derivatives "
        "plausible, not published)",
        "S_ref": aircraft.s_ref,
        "b_ref": aircraft.b_ref,
        "sample_rate_hz": rate,
        "seed": seed,
        "first_input": first,
        "noise_sigmas": LATERAL_NOISE if noise else {},
        "truth": truth,
        "truth_linear": implied_lateral_derivatives(aircraft, LATERAL_SPEED),
        "hidden_effects": hidden,
    }
    return channels, metadata


def implied_lateral_derivatives(aircraft, speed: float) -> dict[str, float]:
    """The linear model's dimensional derivatives ([`LATERAL_DERIVATIVES`][]) that an
    [`Aircraft`][]'s coefficient derivatives imply at airspeed `speed` (m/s): rows of
    `I^-1 [L; N]` (roll and yaw coupled by the product of inertia; per rad, per
    rad/s) and `Y / m` (m/s^2 per rad, per rad/s)."""
    d = aircraft.lateral
    qbar = 0.5 * aircraft.rho * speed**2
    k = aircraft.b_ref / (2 * speed)
    sb = qbar * aircraft.s_ref * aircraft.b_ref
    moments = sb * np.array(
        [
            [d.Cl_p * k, d.Cl_r * k, d.Cl_da, d.Cl_dr, d.Cl_beta],
            [d.Cn_p * k, d.Cn_r * k, d.Cn_da, d.Cn_dr, d.Cn_beta],
        ]
    )
    inertia = np.asarray(aircraft.inertia)[np.ix_([0, 2], [0, 2])]
    rows = np.linalg.solve(inertia, moments)
    side = (qbar * aircraft.s_ref / aircraft.mass) * np.array(
        [d.CY_p * k, d.CY_r * k, d.CY_da, d.CY_dr, d.CY_beta]
    )
    values = [*rows[0], *rows[1], *side]
    return dict(zip(LATERAL_DERIVATIVES, map(float, values), strict=True))
