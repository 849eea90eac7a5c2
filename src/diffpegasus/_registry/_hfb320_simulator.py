"""The HFB-320's simulator: a flight of the vehicle's model with a 3-2-1-1 elevator
input, optional library effects and Dryden turbulence, and sensor noise: what
`diffpegasus simulate --vehicle hfb320` writes."""

import jax.numpy as jnp
import numpy as np

from .._estimate._fit import simulate_outputs
from .._inputs import three_two_one_one
from .._model import Record
from .._vehicle._effects import make_effect, Turbulence
from .._vehicle._hfb320 import (
    CBAR,
    HFB320,
    hfb320_model,
    IDENTIFIED,
    NOISE,
    S_REF,
    TRIM,
    V0,
    X0,
)
from .._vehicle._parts import effect_parameter


def simulate_log(
    duration: float = 30.0,
    rate: float = 10.0,
    seed: int = 0,
    noise: bool = True,
    hidden: dict[str, float] | None = None,
    turbulence: float = 0.0,
) -> tuple[dict[str, np.ndarray], dict]:
    """A simulated HFB-320 flight: a 3-2-1-1 elevator input (0.01 rad, 1 s unit,
    from 2 s) about the record's trim, constant thrust, the identified aerodynamics
    ([`IDENTIFIED`][]) plus any library effects `hidden` (name -> value, SI), RK4 at
    1/10 of the log step, white noise ([`NOISE`][]). `turbulence` (m/s, vertical
    intensity) flies it through Dryden gusts ([`Turbulence`][], 1750 ft length
    scale, frozen field at the reference speed `V0`) whose realisation is drawn
    from `seed`, as the sensor noise is, starting at `X0` relative to the air
    (the air data at t = 0 are the book's initial state). Returns the log's channels and its
    sidecar metadata."""
    hidden = dict(hidden or {})
    names = tuple(hidden)
    model = hfb320_model(effects=names)
    if turbulence:
        gust = Turbulence(sigma=float(turbulence), seed=int(seed), airspeed=V0)

        def effects(p):
            return tuple(make_effect(n, p[effect_parameter(n)]) for n in names) + (
                gust,
            )

        def rates(t, x, u, p):
            return HFB320.evaluate(t, x, u, p, effects(p))[0]

        def observe(t, x, u, p):
            ch = HFB320.evaluate(t, x, u, p, effects(p))[1].channels
            return jnp.stack([ch[n] for n in model.outputs])

        model = model.replace(rates=rates, observe=observe)
        # start in trim relative to the air: the simulator's V, alpha are inertial,
        # so add the gust at t = 0 (else the air data at t = 0 differ from X0 by
        # the gust, and a fit holding X0 sees an initial-state error)
        wu, ww = (float(v) for v in gust.wind(0.0, X0[2]))
        ui = X0[0] * np.cos(X0[1]) + wu
        wi = X0[0] * np.sin(X0[1]) + ww
        x0 = (float(np.hypot(ui, wi)), float(np.arctan2(wi, ui)), X0[2], X0[3])
    else:
        x0 = X0
    params = dict(IDENTIFIED)
    params.update({effect_parameter(n): v for n, v in hidden.items()})
    theta = np.array([params[k] for k in model.parameters])
    t = np.arange(0.0, duration + 0.5 / rate, 1.0 / rate)
    pulse = three_two_one_one(float(np.rad2deg(0.01)), 1.0, start=2.0)  # deg
    de = TRIM["de"] + np.array([float(pulse(x)) for x in t])
    inputs = np.column_stack([de, np.full_like(t, TRIM["thrust"])])
    y = simulate_outputs(model, t, inputs, theta, x0, oversample=10)
    rng = np.random.default_rng(seed)
    channels = {"t": t, "de": de, "thrust": inputs[:, 1]}
    for j, name in enumerate(model.outputs):
        channels[name] = y[:, j] + (
            rng.normal(size=len(t)) * NOISE[name] if noise else 0
        )
    metadata = {
        "vehicle": "hfb320",
        "S_ref": S_REF,
        "c_ref": CBAR,
        "sample_rate_hz": rate,
        "seed": seed,
        "noise_sigmas": NOISE if noise else {},
        "truth": params,
        "hidden_effects": {
            **hidden,
            **({"turbulence": turbulence} if turbulence else {}),
        },
    }
    if turbulence:
        metadata["turbulence"] = {
            "sigma": float(turbulence),
            "seed": int(seed),
            "length_scale": gust.length_scale,
            "airspeed": V0,
        }
    return channels, metadata


def simulated_record(channels: dict[str, np.ndarray], name: str = ""):
    """A [`simulate_log`][] flight as a `Record` of [`hfb320_model`][]: its inputs
    and outputs in the model's order, the book's initial state `X0` held."""
    model = hfb320_model()
    return Record(
        channels["t"],
        np.column_stack([channels[n] for n in model.inputs]),
        np.column_stack([channels[n] for n in model.outputs]),
        x0=X0,
        name=name,
    )
