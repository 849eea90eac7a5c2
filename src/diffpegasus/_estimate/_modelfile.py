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
import pathlib
import runpy
import traceback

from .._errors import LogError
from .._model import Model
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


def load_model_file(path) -> ModelSpec:
    """Run a model-definition file and collect what it defines. An error inside the
    file becomes one `LogError` line naming the file and line."""
    path = pathlib.Path(path)
    if not path.is_file():
        raise LogError(f"{path}: no such model file")
    try:
        ns = runpy.run_path(str(path), run_name="diffpegasus_model")
    except Exception as e:  # the user's code: report where it failed, in one line
        frames = [
            f for f in traceback.extract_tb(e.__traceback__) if f.filename == str(path)
        ]
        line = f" line {frames[-1].lineno}" if frames else ""
        raise LogError(f"{path}:{line}: {type(e).__name__}: {e}") from None
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
    return spec_from_namespace(ns, str(path))


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
        candidates=tuple(ns.get("candidates", ())),
        vehicle=ns.get("vehicle"),
        process_noise=_process_noise(ns.get("process_noise"), name),
    )


def _process_noise(value, name):
    """A model file's `process_noise`: `None`, a tuple of state names or a dict
    name -> start intensity."""
    if value is None:
        return None
    if isinstance(value, str):
        return (value,)
    try:
        if isinstance(value, dict):
            return {str(k): float(v) for k, v in value.items()}
        return tuple(str(v) for v in value)
    except (TypeError, ValueError):
        raise LogError(
            f"{name}: `process_noise` must be state names or a dict name -> start "
            "intensity"
        ) from None
