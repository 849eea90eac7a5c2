"""Model-definition files: a user's model in one Python file, no package code.

The file is ordinary Python. It must define `model`, a [`Model`][], or `vehicle`, a
[`FlightVehicle`][] built from the library's parts (then library effects compose
with it: `--add`, `diagnose`), and may define

- `columns`: a column map (see [`load_columns`][]) for the logs it is fitted to;
- `read(path)`: instead of `columns`, a function returning the channels of one data
  file as a dict of 1-D arrays by channel name, SI units (for channels that are
  combinations of columns, e.g. an aileron angle from the left and right surfaces);
- `x0`: the initial state of every record, or a dict from data-file name (as given,
  its base name, or its stem) to each record's initial state (default: the state
  channels at each record's first sample);
- `initial_state`: `"fixed"` (default) or `"estimated"`;
- `biases`: outputs with a per-record bias, e.g. `("ax", "az")`;
- `shooting`: a shooting strategy, e.g. `dp.MultipleShooting(interval=2.0)`;
- `candidates`: held parameters (start 0) that `diagnose` score-tests, e.g. a
  pitch-damping term the model may be missing;
- `process_noise`: the states whose equations get process noise (turbulence) in
  `fit --method fem`, and which `diagnose` then also scores as the candidate
  `process_noise`: names, or a dict name -> start intensity (state units /
  sqrt(s)). Without it, `fit --method fem` puts process noise on every state and
  `diagnose` does not test it.

The built-in vehicles other than Pegasus are such files' contents, too.
"""

import dataclasses
import inspect
import math
import pathlib
import runpy

from .._errors import LogError
from .._model import Model
from .._usercode import contained
from ._fit import MultipleShooting, SingleShooting


@dataclasses.dataclass(frozen=True)
class ModelSpec:
    """A model with what its file says about the data (see the module docstring)."""

    model: Model
    name: str
    columns: dict | None = None
    read: object = None
    x0: tuple[float, ...] | dict[str, tuple[float, ...]] | None = None
    initial_state: str = "fixed"
    biases: tuple[str, ...] = ()
    shooting: SingleShooting | MultipleShooting = SingleShooting()
    candidates: tuple[str, ...] = ()
    vehicle: object = None
    process_noise: tuple[str, ...] | dict[str, float] | None = None
    # the airflow states a coloured gust shifts (the process-noise candidate
    # offers it besides white noise), e.g. ("V", "alpha"); None: white only
    gust: tuple[str, ...] | None = None
    # the states whose rates are inertial kinematics under a gust (e.g. ("h",))
    gust_kinematic: tuple[str, ...] = ()
    # the pitch-rate state the body axes turn at under a gust on (airspeed,
    # angle of attack): the wind's transport enters the inertial rates
    gust_pitch_rate: str | None = None
    # what the entry chose from the data (JSON-ready, e.g. the baseline's
    # resolution), reported by the diagnosis
    notes: dict | None = None


def load_model_file(path) -> ModelSpec:
    """Run a model-definition file and collect what it defines. An error inside the
    file becomes one `LogError` line naming the file and line."""
    path = pathlib.Path(path)
    if not path.is_file():
        raise LogError(
            f"{path}: no such model file"
            if not path.exists()
            else f"{path}: is a folder, not a model file"
        )
    try:
        path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as e:
        raise LogError(
            f"{path}: the model file is not UTF-8 text (byte {e.start}); save it as "
            "UTF-8"
        ) from None
    except OSError as e:
        raise LogError(f"{path}: cannot read the model file ({e.strerror})") from None
    with contained(str(path), "at import"):
        ns = runpy.run_path(str(path), run_name="diffpegasus_model")
    model = ns.get("model")
    if model is None and ns.get("vehicle") is not None:
        from .._vehicle._parts import FlightVehicle, vehicle_model

        if not isinstance(ns["vehicle"], FlightVehicle):
            raise LogError(f"{path}: `vehicle` must be a diffpegasus.FlightVehicle")
        ns["model"] = model = vehicle_model(ns["vehicle"])
    if not isinstance(model, Model):
        raise LogError(
            f"{path}: a model file must define `model = diffpegasus.Model(...)` "
            f"or `vehicle = diffpegasus.FlightVehicle(...)` "
            f"(found {type(model).__name__})"
        )
    spec = spec_from_namespace(ns, str(path))
    _check_model(spec.model, str(path))
    return spec


def _reader(read, name):
    if read is not None and not callable(read):
        raise LogError(f"{name}: `read` must be a function read(path) -> dict")
    return read


def _initial_state(x0, model: Model, name: str):
    def one(v, where):
        try:
            v = tuple(float(a) for a in v)
        except (TypeError, ValueError):
            raise LogError(f"{name}: {where} must be numbers, got {v!r}") from None
        if not all(math.isfinite(a) for a in v):
            raise LogError(f"{name}: {where} must be finite numbers, got {v!r}")
        if len(v) != len(model.states):
            raise LogError(
                f"{name}: {where} has {len(v)} values, the model has "
                f"{len(model.states)} states ({', '.join(model.states)})"
            )
        return v

    if x0 is None:
        return None
    if isinstance(x0, dict):
        return {str(k): one(v, f"x0[{k!r}]") for k, v in x0.items()}
    return one(x0, "x0")


def _check_parameters(model: Model, name: str) -> None:
    """A model with nothing to estimate, or a start value no fit can start from."""
    if not model.parameters:
        raise LogError(
            f"{name}: the model has no parameters (parameters={{}}); a fit estimates "
            "at least one, e.g. parameters={'Mq': -1.0}"
        )
    for p, v in zip(model.parameters, model.start, strict=True):
        if not math.isfinite(v):
            raise LogError(
                f"{name}: parameter {p!r} starts at {v!r}; start values must be "
                "finite numbers"
            )


def _candidates(value, model: Model, name: str) -> tuple[str, ...]:
    """`candidates`: parameters of the model that `diagnose` tests, held at their
    start values (usually 0)."""
    value = (value,) if isinstance(value, str) else tuple(value)
    for c in value:
        if c not in model.parameters:
            raise LogError(
                f"{name}: candidates names {c!r}, not a parameter of the model "
                f"({', '.join(model.parameters)})"
            )
    return value


def _def_line(fn) -> str:
    try:
        return f" line {inspect.getsourcelines(fn)[1]}"
    except (OSError, TypeError):
        return ""


def _check_model(model: Model, name: str) -> None:
    """Trace `rates` and `observe` once on zeros (`jax.eval_shape`: nothing runs or
    compiles) so that an output of the wrong length is named with the file and the
    function's line before any data is read."""
    import jax
    import numpy as np

    dtype = jax.dtypes.canonicalize_dtype(np.float64)
    scalar = jax.ShapeDtypeStruct((), dtype, weak_type=True)
    p = {k: scalar for k in model.parameters}
    x = np.zeros(len(model.states))
    u = np.zeros(len(model.inputs))
    for what, fn, names in (
        ("rates", model.rates, model.states),
        ("observe", model.observe, model.outputs),
    ):
        try:
            out = jax.eval_shape(fn, 0.0, x, u, p)
        except Exception:  # noqa: BLE001 (reported with the record, see Record.check)
            continue
        n = sum(int(np.prod(getattr(a, "shape", ()))) for a in jax.tree.leaves(out))
        if n != len(names):
            raise LogError(
                f"{name}:{_def_line(fn)}: {what}(t, x, u, p) returns {n} value(s); "
                f"the model has {len(names)} "
                f"{'states' if what == 'rates' else 'outputs'} ({', '.join(names)})"
            )


def _biases(biases, model: Model, name: str) -> tuple[str, ...]:
    biases = (biases,) if isinstance(biases, str) else tuple(biases)
    unknown = [b for b in biases if b not in model.outputs]
    if unknown:
        raise LogError(
            f"{name}: biases {unknown} are not model outputs "
            f"({', '.join(model.outputs)})"
        )
    return biases


def spec_from_namespace(ns: dict, name: str) -> ModelSpec:
    x0 = ns.get("x0")
    shooting = ns.get("shooting", SingleShooting())
    if not isinstance(shooting, SingleShooting | MultipleShooting):
        raise LogError(
            f"{name}: `shooting` must be dp.SingleShooting() or dp.MultipleShooting(...)"
        )
    model = ns["model"]
    _check_parameters(model, name)
    candidates = _candidates(ns.get("candidates", ()), model, name)
    # a candidate is a held term (as `diagnose_model` holds them): held here too, so
    # that `fit` and `diagnose` of the file agree on what is estimated
    held = tuple(c for c in candidates if c not in model.fixed)
    if held:
        model = ns["model"] = model.replace(fixed=(*model.fixed, *held))
    initial_state = ns.get("initial_state", "fixed")
    if initial_state not in ("fixed", "estimated"):
        raise LogError(f"{name}: initial_state must be 'fixed' or 'estimated'")
    return ModelSpec(
        model=ns["model"],
        name=name,
        columns=ns.get("columns"),
        read=_reader(ns.get("read"), name),
        x0=_initial_state(x0, ns["model"], name),
        initial_state=initial_state,
        biases=_biases(ns.get("biases", ()), ns["model"], name),
        shooting=shooting,
        candidates=candidates,
        vehicle=ns.get("vehicle"),
        process_noise=_process_noise(ns.get("process_noise"), name, model),
    )


def _process_noise(value, name, model):
    """A model file's `process_noise`: `None`, a tuple of state names or a dict
    name -> start intensity."""
    if value is None:
        return None
    if isinstance(value, str):
        value = (value,)
    try:
        if isinstance(value, dict):
            out = {str(k): float(v) for k, v in value.items()}
        else:
            out = tuple(str(v) for v in value)
    except (TypeError, ValueError):
        raise LogError(
            f"{name}: `process_noise` must be state names or a dict name -> start "
            "intensity"
        ) from None
    unknown = [k for k in out if k not in model.states]
    if unknown:
        raise LogError(
            f"{name}: process_noise names {unknown[0]!r}, not a state of the model "
            f"({', '.join(model.states)})"
        )
    if isinstance(out, dict):
        for k, v in out.items():
            if not (math.isfinite(v) and v > 0):
                raise LogError(
                    f"{name}: process_noise[{k!r}] = {v!r}: a start intensity must be "
                    "a positive finite number (state units/sqrt(s))"
                )
    return out
