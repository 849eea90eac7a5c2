"""Lateral-directional models for output error: the textbooks' linear model and the
6-DOF side-force, rolling and yawing equations with longitudinal pseudo-inputs.

**The linear model** ([`lateral_model`][]; Jategaonkar, *Flight Vehicle System
Identification*, 2nd ed., section 4.20, test cases 1 and 34 of FVSysID's chapter 4):
states roll and yaw rate `p, r` (rad/s); inputs aileron `da`, rudder `dr` and the
measured sideslip `beta` (rad); outputs `pdot, rdot` (rad/s^2), `ay` (m/s^2),
`p, r`:

    pdot = Lp p + Lr r + Lda da + Ldr dr + Lbeta beta + bx_p
    rdot = Np p + Nr r + Nda da + Ndr dr + Nbeta beta + bx_r
    ay   = Yp p + Yr r + Yda da + Ydr dr + Ybeta beta

    measured = [pdot - bx_p, rdot - bx_r, ay, p, r] + [by_pdot, ..., by_r]

The measured accelerations carry the output biases `by_*`, not the state biases
`bx_*` (as in the book's observation equations). With both sets of biases the
initial state is zero and held: a nonzero `x0` is absorbed by the lumped biases (for
`A` invertible, `x -> x - x0` maps `bx -> bx + A x0`, `by -> by + C x0`), so records
for this model carry `x0 = 0` ([`lateral_record`][] sets it).

*Biases as model parameters, not through `fit(..., biases=...)`:* the engine's
per-record biases are output biases; the book's model has state-equation biases
too, and output biases shared by all manoeuvres. So the biases are parameters of the
model: 15 derivatives + 2 state + 5 output biases = 22 for one manoeuvre (test case
1). With `manoeuvres=n > 1` each manoeuvre gets its own state biases
`bx_p_1, bx_r_1, ...` and the output biases stay shared (test case 34); the model then
has `n` extra inputs `manoeuvre_1 ... manoeuvre_n`, 1 on the records of that
manoeuvre and 0 elsewhere, which select the state biases ([`lateral_record`][] adds
them). This is exact, not an approximation: a per-record parameter is a shared
parameter times a per-record constant input. (Per-manoeuvre output biases instead:
`output_biases=False` and `fit(..., biases=LATERAL_OUTPUTS)`.)

*Sideslip as a state* (`sideslip="state"`): output error takes inputs as exact, so
a noisy sideslip vane biases the derivatives (measured in the README: 6 standard
errors on `Ndr` with 1e-3 rad of noise). The variant makes `beta` and the bank angle
`phi` states driven by the modelled side force, linearised about a reference flight
`(V, alpha, theta)`, and outputs: same 15 derivatives, two more output biases.

**The nonlinear lateral model** ([`sixdof_lateral_model`][]): the 6-DOF side-force
and moment equations of [`rigid_body_rates`][] with the measured longitudinal
motion `u, w, q, theta` as pseudo-inputs; states `v, p, r, phi`; the 15 coefficient
derivatives of [`LateralDerivatives`][] as parameters.

**Discrepancy candidates** (held parameters for [`diagnose_model`][]): the 6-DOF
model composes the library's sensor biases (`SIXDOF_LATERAL_EFFECTS`: sideslip
offset, `ay, p, r`); the linear model, whose lumped biases absorb those, takes
aileron and rudder delays (`LATERAL_EFFECTS`); any derivative held at zero is a
candidate too (yaw damping missing: `Cn_r`, `Nr`).

**Simulated logs** ([`simulate_lateral_log`][], the command line's `simulate
--vehicle hfb320-lateral`): a 6-DOF business-jet manoeuvre with every channel and the
truth, including the linear derivatives it implies
([`implied_lateral_derivatives`][]).
"""

from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np

from .._estimate._model import Model, Record
from ._effects import make_effect
from ._parts import effect_parameter
from ._sixdof import (
    G,
    lateral_coefficients,
    LATERAL_DERIVATIVE_NAMES,
    LateralDerivatives,
    rigid_body_rates,
)


LATERAL_DERIVATIVES = (
    "Lp", "Lr", "Lda", "Ldr", "Lbeta",
    "Np", "Nr", "Nda", "Ndr", "Nbeta",
    "Yp", "Yr", "Yda", "Ydr", "Ybeta",
)  # fmt: skip
LATERAL_OUTPUTS = ("pdot", "rdot", "ay", "p", "r")
LATERAL_INPUTS = ("da", "dr", "beta")

# The book's start values for the ATTAS case (1/s, 1/s^2, m/s^2 per rad and per rad/s);
# biases start at 0.02 as in the book.
LATERAL_START = dict(
    zip(
        LATERAL_DERIVATIVES,
        (
            -3.53744, 0.475534, -4.93279, 0.73334, -4.34076,
            -0.086939, -0.169526, -0.192049, -0.74855, 1.55155,
            0.0364, 2.130, 0.740, 2.279, -5.193,
        ),
        strict=True,
    )
)  # fmt: skip
BIAS_START = 0.02
# Terms the linear model can hold as candidates of `diagnose_model` (`effects=`):
# the aileron or rudder deflection entering the model late (a lag the lumped biases
# cannot absorb, unlike sensor biases and a sideslip offset).
LATERAL_EFFECTS = {"aileron_delay": "da", "rudder_delay": "dr"}

# FVSysID ASCII columns of a lateral record (the HFB-320 file's names) -> channels.
LATERAL_COLUMNS = {
    "t": "T",
    "da": "DAIL",
    "dr": "DRUD",
    "beta": "BETCG",
    "pdot": "PDOT",
    "rdot": "RDOT",
    "ay": "AYCG",
    "p": "P",
    "r": "R",
    "phi": "PHI",
}


def _state_bias_names(manoeuvres: int) -> tuple[str, ...]:
    if manoeuvres == 1:
        return ("bx_p", "bx_r")
    return tuple(f"bx_{s}_{k}" for k in range(1, manoeuvres + 1) for s in ("p", "r"))


def _linear_rates_and_outputs(x, u, p, setup):
    """State rates and outputs of the linear model; `setup` holds the static
    choices `(manoeuvres, state_biases, output_biases, flight)`, `flight` the
    `(speed, alpha, theta)` of the sideslip-as-state variant or None."""
    manoeuvres, state_biases, output_biases, flight = setup
    if flight is None:
        roll, yaw = x[0], x[1]
        da, dr, beta = u[0], u[1], u[2]
        n_known = 3
    else:
        beta, roll, yaw, phi = x[0], x[1], x[2], x[3]
        da, dr = u[0], u[1]
        n_known = 2

    def row(k):
        return (
            p[k + "p"] * roll
            + p[k + "r"] * yaw
            + p[k + "da"] * da
            + p[k + "dr"] * dr
            + p[k + "beta"] * beta
        )

    pdot, rdot, ay = row("L"), row("N"), row("Y")
    bx = jnp.zeros(2)
    if state_biases:
        if manoeuvres == 1:
            bx = jnp.stack([p["bx_p"], p["bx_r"]])
        else:
            which = u[n_known : n_known + manoeuvres]
            bp = jnp.stack([p[f"bx_p_{k}"] for k in range(1, manoeuvres + 1)])
            br = jnp.stack([p[f"bx_r_{k}"] for k in range(1, manoeuvres + 1)])
            bx = jnp.stack([jnp.dot(which, bp), jnp.dot(which, br)])
    y = [pdot, rdot, ay, roll, yaw]
    if flight is None:
        rates = jnp.stack([pdot, rdot]) + bx
    else:
        speed, alpha, theta = flight
        # the side-force equation linearised about wings-level flight at
        # (speed, alpha, theta): m V betadot = m ay + m g cos(theta) phi + ...
        betadot = (
            (ay + G * np.cos(theta) * phi) / speed
            + roll * np.sin(alpha)
            - yaw * np.cos(alpha)
        )
        phidot = roll + yaw * np.tan(theta)
        rates = jnp.stack([betadot, pdot + bx[0], rdot + bx[1], phidot])
        y += [beta, phi]
    y = jnp.stack(y)
    if output_biases:
        y = y + jnp.stack([p["by_" + name] for name in _outputs(flight)])
    return rates, y


def _outputs(flight):
    return LATERAL_OUTPUTS if flight is None else LATERAL_OUTPUTS + ("beta", "phi")


def lateral_model(
    *,
    manoeuvres: int = 1,
    state_biases: bool = True,
    output_biases: bool = True,
    sideslip: str = "input",
    flight: tuple[float, float, float] | None = None,
    start: dict | None = None,
    fixed: Sequence[str] = (),
    effects: Sequence[str] = (),
    free: Sequence[str] = (),
) -> Model:
    """The linear lateral-directional model (see the module docstring).

    **Arguments:**

    - `manoeuvres`: how many records are fitted together; above 1 each gets its own
      state biases, selected by the inputs `manoeuvre_k`.
    - `state_biases`: estimate `bx_p, bx_r` (per manoeuvre); with them records must
      start from `x0 = 0` (with `sideslip="state"`, from the initial sideslip and
      bank angle and zero rates: [`lateral_record`][] does both), held: estimating
      the initial states as well is not identifiable (a common offset of them moves
      into the biases); `state_biases=False` with `fit(...,
      initial_state="estimated")` estimates them instead.
    - `output_biases`: estimate `by_pdot, by_rdot, by_ay, by_p, by_r` (and `by_beta,
      by_phi` with `sideslip="state"`), shared by all manoeuvres.
    - `sideslip`: `"input"` (measured sideslip drives the model, as in the book) or
      `"state"`: sideslip and bank angle become states, driven by the modelled side
      force, `betadot = (ay + g cos(theta) phi) / V + p sin(alpha) - r cos(alpha)`,
      `phidot = p + r tan(theta)`; use it when the sideslip measurement is noisy
      (output error takes inputs as exact).
    - `flight`: `(V m/s, alpha rad, theta rad)` of the reference flight, required
      with `sideslip="state"`.
    - `start`: start values by name (default the book's; biases 0.02).
    - `fixed`: names of parameters held at their start values.
    - `effects`: candidate terms of [`LATERAL_EFFECTS`][] (`aileron_delay`,
      `rudder_delay`: the deflection enters `tau` s late), each adding its parameter
      (`aileron_delay.tau`, s, start 0) held at zero unless named in `free`.

    **Returns:** a [`Model`][] with states `p, r`, inputs `da, dr, beta` and outputs
    `pdot, rdot, ay, p, r`; with `sideslip="state"`, states `beta, p, r, phi`, inputs
    `da, dr` and outputs `pdot, rdot, ay, p, r, beta, phi`; then the selector inputs
    `manoeuvre_1..n` if `manoeuvres > 1` with state biases.
    """
    if manoeuvres < 1:
        raise ValueError(f"manoeuvres must be at least 1, got {manoeuvres}")
    if sideslip not in ("input", "state"):
        raise ValueError(f"sideslip must be 'input' or 'state', got {sideslip!r}")
    if sideslip == "state":
        if flight is None:
            raise ValueError(
                "sideslip='state' needs flight=(V m/s, alpha rad, theta rad) of the "
                "reference flight"
            )
        flight = tuple(float(f) for f in flight)
    else:
        flight = None
    effects = tuple(effects)
    unknown = [e for e in effects if e not in LATERAL_EFFECTS]
    if unknown:
        raise ValueError(
            f"effects {unknown} do not compose with the linear lateral model; it "
            f"takes {', '.join(LATERAL_EFFECTS)}"
        )
    names = list(LATERAL_DERIVATIVES)
    if state_biases:
        names += _state_bias_names(manoeuvres)
    if output_biases:
        names += ["by_" + name for name in _outputs(flight)]
    values = {n: LATERAL_START.get(n, BIAS_START) for n in names}
    extra = {f"{e}.tau": 0.0 for e in effects}
    values |= extra
    held = tuple(k for k in extra if k not in free and k.split(".")[0] not in free)
    for k, v in (start or {}).items():
        if k not in values:
            raise ValueError(f"{k!r} is not a parameter of this model: {list(values)}")
        values[k] = float(v)
    inputs = LATERAL_INPUTS if flight is None else LATERAL_INPUTS[:2]
    if manoeuvres > 1 and state_biases:
        # (without state biases nothing is per manoeuvre: no selectors)
        inputs = inputs + tuple(f"manoeuvre_{k}" for k in range(1, manoeuvres + 1))
    setup = (manoeuvres, state_biases, output_biases, flight)

    def delays(p):
        return jnp.stack(
            [
                sum(
                    (p[f"{e}.tau"] for e in effects if LATERAL_EFFECTS[e] == name),
                    jnp.zeros(()),
                )
                for name in inputs
            ]
        )

    def rates(t, x, u, p):
        del t
        return _linear_rates_and_outputs(x, u, p, setup)[0]

    def observe(t, x, u, p):
        del t
        return _linear_rates_and_outputs(x, u, p, setup)[1]

    # typical magnitudes of a lateral manoeuvre (rad/s, rad), so that multiple
    # shooting does not take the scale of the zero initial state
    states, scale = ("p", "r"), (0.05, 0.05)
    if flight is not None:
        states, scale = ("beta", "p", "r", "phi"), (0.02, 0.05, 0.05, 0.05)
    return Model(
        states=states,
        inputs=inputs,
        outputs=_outputs(flight),
        parameters=values,
        rates=rates,
        observe=observe,
        fixed=tuple(dict.fromkeys(tuple(fixed) + held)),
        delays=delays if effects else None,
        state_scale=scale,
    )


def lateral_record(
    model: Model,
    t,
    inputs,
    measured,
    *,
    manoeuvre: int = 1,
    name: str = "record",
) -> Record:
    """A [`Record`][] for a [`lateral_model`][]: `inputs` `(samples, 3)` are `da, dr,
    beta` (rad; `da, dr` only with the sideslip a state), `measured` are the
    model's outputs `pdot, rdot, ay, p, r` (rad/s^2, m/s^2, rad/s; then `beta, phi`,
    rad). Appends the `manoeuvre_k` selector columns when the model has them
    (`manoeuvre` counts from 1). With state biases the rates start from zero (the
    biases absorb their initial values) and sideslip and bank angle from their
    first measured sample; without, every state starts from its first measurement.
    """
    inputs = np.asarray(inputs, float)
    known = [n for n in model.inputs if not n.startswith("manoeuvre_")]
    if inputs.ndim != 2 or inputs.shape[1] != len(known):
        raise ValueError(
            f"inputs must be (samples, {len(known)}): {', '.join(known)}; got "
            f"{inputs.shape}"
        )
    extra = [n for n in model.inputs if n.startswith("manoeuvre_")]
    if extra:
        if not 1 <= manoeuvre <= len(extra):
            raise ValueError(
                f"manoeuvre must be 1..{len(extra)} for this model, got {manoeuvre}"
            )
        select = np.zeros((len(inputs), len(extra)))
        select[:, manoeuvre - 1] = 1.0
        inputs = np.concatenate([inputs, select], axis=1)
    x0 = None
    if any(p.startswith("bx_") for p in model.parameters):
        measured = np.asarray(measured, float)
        x0 = np.zeros(len(model.states))
        for k, s in enumerate(model.states):
            if s in ("beta", "phi"):
                x0[k] = measured[0, model.outputs.index(s)]
    return Record(t, inputs, measured, x0=x0, name=name)


def read_lateral_asc(path, columns: dict | None = None) -> dict[str, np.ndarray]:
    """The lateral channels of an FVSysID `.asc` file (see [`LATERAL_COLUMNS`][];
    `columns` overrides names), SI units and radians as in the file."""
    from .._log._asc import read_asc

    data = read_asc(path)
    names = {**LATERAL_COLUMNS, **(columns or {})}
    return {k: data[v] for k, v in names.items() if v in data}


# --- the 6-DOF lateral equations as a model --------------------------------------


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
    from .._simulate._inputs import doublet, three_two_one_one
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
