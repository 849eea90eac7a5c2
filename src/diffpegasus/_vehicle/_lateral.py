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
a noisy sideslip vane biases the derivatives (measured: 6 standard
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

import dataclasses
from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np

from .._model import Model, Record
from ._sixdof import (
    G,
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


@dataclasses.dataclass(frozen=True)
class _Linear:
    """The linear model's rates (`part=0`) or outputs (`part=1`), `(t, x, u, p)`.
    A value, not a closure: two models built with the same settings are equal,
    so their fits share one compiled program (the model is static to it)."""

    setup: tuple
    part: int

    def __call__(self, t, x, u, p):
        del t
        return _linear_rates_and_outputs(x, u, p, self.setup)[self.part]


@dataclasses.dataclass(frozen=True)
class _Delays:
    """Each input's delay (s), the sum of the effects' `tau` acting on it."""

    effects: tuple[str, ...]
    inputs: tuple[str, ...]

    def __call__(self, p):
        return jnp.stack(
            [
                sum(
                    (p[f"{e}.tau"] for e in self.effects if LATERAL_EFFECTS[e] == name),
                    jnp.zeros(()),
                )
                for name in self.inputs
            ]
        )


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
    rates, observe = _Linear(setup, 0), _Linear(setup, 1)
    delays = _Delays(effects, inputs) if effects else None

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
        delays=delays,
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


# --- the 6-DOF lateral equations as a model --------------------------------------
