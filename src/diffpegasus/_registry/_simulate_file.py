"""A simulated flight of a user's vehicle or model file: the file's model flown
from its initial state with a 3-2-1-1 on its first input."""

import runpy

import numpy as np

from .._errors import LogError
from .._log._format import FlightLog


def simulate_model_file(
    spec,
    *,
    seed: int = 0,
    hidden=(),
    duration: float | None = None,
    sample_rate: float | None = None,
    noise: bool = True,
    input: str = "pulse",
) -> FlightLog:
    """Fly `spec`'s model (a [`ModelSpec`][] of a file, with the effects of
    `hidden` composed) from its `x0` for `duration` s (default 30) at
    `sample_rate` Hz (default 50): the file's `trim` (a dict input name -> value,
    default 0) on every input, plus a 3-2-1-1 of `amplitude` (the file's
    `excitation`, default 0.01 in the first input's units) with a 1 s unit from
    2 s on the first input; RK4 at a tenth of the log step; white noise of the
    file's `noise` (a dict output name -> sigma, default none) drawn from `seed`.
    """
    from .._estimate._fit import simulate_outputs
    from .._vehicle._effects import parse_assignment
    from .._vehicle._parts import effect_parameter

    model = spec.model
    if input not in ("pulse", "3211"):
        raise LogError(f"--input {input}: a vehicle file flies a 3-2-1-1")
    if spec.x0 is None or isinstance(spec.x0, dict):
        raise LogError(
            f"{spec.name}: simulate needs the initial state: define x0 = (...) with "
            f"one value per state ({', '.join(model.states)})"
        )
    ns = runpy.run_path(spec.name, run_name="diffpegasus_model")
    trim = dict(ns.get("trim", {}))
    sigma = dict(ns.get("noise", {})) if noise else {}
    amplitude = float(ns.get("excitation", 0.01))
    params = dict(zip(model.parameters, model.start, strict=True))
    for text in hidden:
        try:
            effect = parse_assignment(text)
        except ValueError as e:
            raise LogError(f"--hidden {text}: {e}") from None
        name = effect_parameter(text.partition("=")[0].strip())
        if name not in params:
            raise LogError(f"--hidden {text}: not an effect of {spec.name}")
        params[name] = float(effect.value())
    rate = 50.0 if sample_rate is None else float(sample_rate)
    t = np.arange(0.0, (30.0 if duration is None else duration) + 0.5 / rate, 1 / rate)
    inputs = np.column_stack(
        [np.full_like(t, float(trim.get(n, 0.0))) for n in model.inputs]
    )
    # 3-2-1-1: levels +a, -a, +a, -a held 3, 2, 1 and 1 s from 2 s
    edges = 2.0 + np.cumsum([0.0, 3.0, 2.0, 1.0, 1.0])
    level = np.searchsorted(edges, t, side="right") - 1
    sign = np.array([1.0, -1.0, 1.0, -1.0])
    inside = (level >= 0) & (level < 4)
    inputs[:, 0] += np.where(inside, amplitude * sign[np.clip(level, 0, 3)], 0.0)
    theta = np.array([params[k] for k in model.parameters])
    y = simulate_outputs(model, t, inputs, theta, spec.x0, oversample=10)
    rng = np.random.default_rng(seed)
    channels = {"t": t, **{n: inputs[:, j] for j, n in enumerate(model.inputs)}}
    for j, name in enumerate(model.outputs):
        channels[name] = y[:, j] + rng.normal(size=len(t)) * float(sigma.get(name, 0))
    if not np.all(np.isfinite(y)):
        raise LogError(f"{spec.name}: the simulation diverged (non-finite outputs)")
    metadata = {
        "vehicle": spec.name,
        "sample_rate_hz": rate,
        "seed": seed,
        "noise_sigmas": sigma,
        "hidden_effects": {h.partition("=")[0]: h.partition("=")[2] for h in hidden},
    }
    if spec.vehicle is not None:
        metadata["S_ref"] = float(spec.vehicle.geometry.s_ref)
        metadata["c_ref"] = float(spec.vehicle.geometry.c_ref)
    return FlightLog(channels=channels, metadata=metadata)
