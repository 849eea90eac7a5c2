"""A coloured gust state for the filter-error method.

White process noise (`x' = f(x) + F w`) kicks a state's rate; turbulence is not
white: a vertical gust of the atmosphere keeps its sign for about `L / V` seconds
(length scale over airspeed) and moves the airflow the vehicle sees, so the
aerodynamic forces and the air data (alpha vane, accelerometers) respond to it at
once, not through an integrated rate. A filter whose noise is white leaves the
innovations of such a flight coloured. [`Gust`][] adds, per airflow state `s`
it names (e.g. `alpha`, `V`), a first-order Gauss-Markov state `g_s`

    g_s' = -g_s / tau + F_s w          (w unit white noise)

and the model's rates and outputs are evaluated at the state the air sees,
`x + E g` (`E` puts `g_s` on state `s`): the vehicle's own parts see the gust
through the same airflow angle and airspeed they already use, with no change to
them. The correlation time `tau` (s) is one model parameter, estimated by the
filter-error fit as `ln tau` (so it stays positive); the intensities `F_s`
(state units / sqrt(s)) are process-noise intensities like the white ones.
`x` is the inertial state: the rates of the states a gust names `kinematic`
(the altitude's climb rate) are evaluated at `x` itself. The model's rates at
the air's state are those of the air-relative velocity; the inertial velocity's
differ by the transport of the wind through the pitching body axes: with
`pitch_rate` named (the gust's states then airspeed and angle of attack, in that
order) the body accelerations at the air's state get `-omega x W` (`W` the wind,
inertial minus air-relative velocity, in body axes) and are converted into
airspeed and angle-of-attack rates at the inertial velocity. Without it the
rates are the air's: the airspeed rate is off by about `(q - alpha') W_w`
(m/s^2), first order in the gust and the flight path's turn rate.
"""

import functools

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._model import Model


# the correlation-time parameter of the augmented model: ln(tau / 1 s)
LOG_TAU = "gust_ln_tau"
# with the airspeed named, the length-scale parameter instead: ln(L / 1 m)
LOG_LENGTH = "gust_ln_length"


class Gust(eqx.Module):
    """A first-order gust state on the airflow `states` (names of model states,
    e.g. `("V", "alpha")`), sharing one correlation time whose start is `tau`
    (s, positive). `kinematic`: states whose rates are inertial kinematics (e.g.
    the altitude, `h' = V sin(theta - alpha)` of the inertial velocity): their
    rates are evaluated at the inertial state `x`, not at the air's.
    `pitch_rate`: the pitch-rate state (rad/s); when named, `states` are the
    airspeed (m/s) and the angle of attack (rad), in that order, and the
    airspeed and angle-of-attack rates are the inertial velocity's (the wind's
    transport through the pitching body axes added). `airspeed`: the airspeed
    state (m/s); when named, the vehicle flies through a frozen field of length
    scale `L` (m, estimated as `ln L`, start `length`) and the correlation time
    is `L / V` at the air's airspeed, which follows a vehicle that accelerates
    (Taylor's hypothesis, as Dryden's and von Karman's models take it); the
    intensities stay constant. A strategy of [`FilterError`][] and of the
    diagnosis's process-noise candidate."""

    states: tuple[str, ...] = eqx.field(static=True)
    tau: float = eqx.field(static=True, default=1.0)
    kinematic: tuple[str, ...] = eqx.field(static=True, default=())
    pitch_rate: str | None = eqx.field(static=True, default=None)
    airspeed: str | None = eqx.field(static=True, default=None)
    length: float = eqx.field(static=True, default=250.0)

    def __check_init__(self):
        if not self.states:
            raise ValueError("a gust needs at least one airflow state")
        if len(set(self.states)) != len(self.states):
            raise ValueError(f"a gust names a state twice: {self.states}")
        if not self.tau > 0:
            raise ValueError(
                f"the gust's correlation time must be positive: {self.tau}"
            )
        if not self.length > 0:
            raise ValueError(f"the gust's length scale must be positive: {self.length}")
        if self.pitch_rate is not None and len(self.states) != 2:
            raise ValueError(
                "a gust with a pitch rate shifts two states, the airspeed and the "
                f"angle of attack (in that order): {self.states}"
            )

    @property
    def names(self) -> tuple[str, ...]:
        """The gust states' names, `gust[state]`."""
        return tuple(f"gust[{s}]" for s in self.states)


@functools.lru_cache(maxsize=32)
def with_gust(model: Model, gust: Gust) -> Model:
    """`model` with the gust states appended to its states and `gust_ln_tau` to
    its parameters (start `ln gust.tau`; `gust_ln_length`, start `ln gust.length`,
    when the gust names the airspeed); its rates and outputs at the air's
    state `x + E g`. Cached: one augmented model (and one compilation) per model
    and gust."""
    named = (
        *gust.states,
        *gust.kinematic,
        *filter(None, [gust.pitch_rate, gust.airspeed]),
    )
    unknown = [s for s in named if s not in model.states]
    if unknown:
        raise ValueError(
            f"gust on {unknown}: not model states ({', '.join(model.states)})"
        )
    scale_name = LOG_TAU if gust.airspeed is None else LOG_LENGTH
    if scale_name in model.parameters:
        raise ValueError(f"the model already has a parameter {scale_name!r}")
    n = len(model.states)
    idx = np.array([model.states.index(s) for s in gust.states])
    own = model.parameters

    def air(x):
        return x[:n].at[idx].add(x[n:])

    def mine(p):
        return {k: p[k] for k in own}

    kin = np.array([model.states.index(s) for s in gust.kinematic], int)
    iq = None if gust.pitch_rate is None else model.states.index(gust.pitch_rate)
    iv = None if gust.airspeed is None else model.states.index(gust.airspeed)

    def decay(xa, p):
        """`1 / tau` (1/s) at the air's state `xa`."""
        if iv is None:
            return jnp.exp(-p[LOG_TAU])
        return jnp.abs(xa[iv]) * jnp.exp(-p[LOG_LENGTH])

    def rates(t, x, u, p):
        xa = air(x)
        base = jnp.asarray(model.rates(t, xa, u, mine(p)), float).reshape(-1)
        if gust.pitch_rate is not None:
            base = base.at[idx].set(_inertial(base[idx], x[idx], xa[idx], x[iq]))
        if len(kin):
            inertial = jnp.asarray(model.rates(t, x[:n], u, mine(p)), float)
            base = base.at[kin].set(inertial.reshape(-1)[kin])
        return jnp.concatenate([base, -x[n:] * decay(xa, p)])

    def observe(t, x, u, p):
        return model.observe(t, air(x), u, mine(p))

    delays = None if model.delays is None else (lambda p: model.delays(mine(p)))
    scale = (
        None
        if model.state_scale is None
        else (*model.state_scale, *(model.state_scale[i] for i in idx))
    )
    return Model(
        (*model.states, *gust.names),
        model.inputs,
        model.outputs,
        (*model.parameters, scale_name),
        rates,
        observe,
        start=(
            *model.start,
            float(np.log(gust.tau if iv is None else gust.length)),
        ),
        fixed=model.fixed,
        delays=delays,
        state_scale=scale,
    )


def _inertial(rates_air, inertial, air, q):
    """The airspeed and angle-of-attack rates `(V', alpha')` of the inertial
    velocity `inertial = (V, alpha)` from the model's rates `rates_air` at the
    air-relative velocity `air = (V_a, alpha_a)`, the body pitching at `q`
    (rad/s) through a wind fixed in the earth frame: body axes x forward, z
    down, `u' = X/m - q w - g sin(theta)`, `w' = Z/m + q u + g cos(theta)`, so
    the inertial velocity's body rates are the air's plus `(-q W_w, q W_u)`."""
    va, aa = air
    dva, daa = rates_air
    ua, wa = va * jnp.cos(aa), va * jnp.sin(aa)
    dua = dva * jnp.cos(aa) - va * jnp.sin(aa) * daa
    dwa = dva * jnp.sin(aa) + va * jnp.cos(aa) * daa
    v, a = inertial
    uu, ww = v * jnp.cos(a), v * jnp.sin(a)
    du = dua - q * (ww - wa)
    dw = dwa + q * (uu - ua)
    return jnp.stack([(uu * du + ww * dw) / v, (uu * dw - ww * du) / v**2])
