"""What output error identifies: a state-space model and the records it is fitted to.

A [`Model`][] is the user's contract (FVSysID's "model definition"): names of states,
inputs, outputs and parameters, start values, which parameters are held, and two pure
functions

    rates(t, x, u, p)   -> dx/dt, shape (states,)
    observe(t, x, u, p) -> y,     shape (outputs,)

with `t` the time (s), `x` shape `(states,)`, `u` shape `(inputs,)` (the known inputs
at `t`, linearly interpolated between samples) and `p` a dict from parameter name to
value. A [`Record`][] is one manoeuvre: times, known inputs and measured outputs on a
uniform grid, and optionally its initial state. Several records of different lengths
are fitted together, sharing the model parameters.
"""

from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
import numpy as np


class Model(eqx.Module):
    """A state-space model for output-error (or filter-error) identification.

    **Fields:**

    - `states`, `inputs`, `outputs`: names, in the order of `x`, `u` and `y`.
    - `parameters`: names of the parameters, in the order of `start`.
    - `start`: start values, one per parameter (held parameters keep them).
    - `rates`: `rates(t, x, u, p) -> (states,)`, the state derivative.
    - `observe`: `observe(t, x, u, p) -> (outputs,)`, the model outputs.
    - `fixed`: names of parameters held at their start values.
    - `delays`: optional `delays(p) -> (inputs,)`, s: input `i` enters the model as
      recorded at `t - delays(p)[i]` (an actuator lag to estimate).
    - `state_scale`: optional typical magnitude of each state (units of the state),
      for the continuity defects of multiple shooting; default from the data.

    Every field is static: a model is a structure, fitted to data given separately.
    """

    states: tuple[str, ...] = eqx.field(static=True)
    inputs: tuple[str, ...] = eqx.field(static=True)
    outputs: tuple[str, ...] = eqx.field(static=True)
    parameters: tuple[str, ...] = eqx.field(static=True)
    start: tuple[float, ...] = eqx.field(static=True)
    rates: Callable = eqx.field(static=True)
    observe: Callable = eqx.field(static=True)
    fixed: tuple[str, ...] = eqx.field(static=True, default=())
    delays: Callable | None = eqx.field(static=True, default=None)
    state_scale: tuple[float, ...] | None = eqx.field(static=True, default=None)

    def __init__(
        self,
        states,
        inputs,
        outputs,
        parameters,
        rates,
        observe,
        *,
        start=None,
        fixed=(),
        delays=None,
        state_scale=None,
    ):
        if isinstance(parameters, dict):
            if start is not None:
                raise ValueError("give start values either in `parameters` or `start`")
            start = tuple(float(v) for v in parameters.values())
            parameters = tuple(parameters)
        self.states = tuple(states)
        self.inputs = tuple(inputs)
        self.outputs = tuple(outputs)
        self.parameters = tuple(parameters)
        self.start = (
            tuple(0.0 for _ in self.parameters)
            if start is None
            else tuple(float(v) for v in start)
        )
        self.rates = rates
        self.observe = observe
        self.fixed = tuple(fixed)
        self.delays = delays
        self.state_scale = None if state_scale is None else tuple(state_scale)

    def __check_init__(self):
        for kind in ("states", "inputs", "outputs", "parameters"):
            names = getattr(self, kind)
            if len(set(names)) != len(names):
                raise ValueError(f"model {kind} has a repeated name: {names}")
        if len(self.start) != len(self.parameters):
            raise ValueError(
                f"{len(self.start)} start values for {len(self.parameters)} parameters"
            )
        unknown = [f for f in self.fixed if f not in self.parameters]
        if unknown:
            raise ValueError(
                f"fixed parameters {unknown} are not model parameters "
                f"({', '.join(self.parameters)})"
            )
        if self.state_scale is not None and len(self.state_scale) != len(self.states):
            raise ValueError("state_scale needs one value per state")

    @property
    def free(self) -> np.ndarray:
        """Which parameters are estimated, `(params,)` bool."""
        return np.array([p not in self.fixed for p in self.parameters])

    def named(self, theta) -> dict:
        """The parameter vector `theta` `(params,)` as a dict name -> value."""
        return {name: theta[i] for i, name in enumerate(self.parameters)}

    def f(self, t, x, u, theta):
        """`rates` with the parameters as a vector."""
        return jnp.asarray(self.rates(t, x, u, self.named(theta)), float).reshape(-1)

    def g(self, t, x, u, theta):
        """`observe` with the parameters as a vector."""
        return jnp.asarray(self.observe(t, x, u, self.named(theta)), float).reshape(-1)

    def input_delays(self, theta):
        """Per-input delays (s), `(inputs,)`, or `None` when the model has none."""
        if self.delays is None:
            return None
        d = jnp.asarray(self.delays(self.named(theta)), float)
        return jnp.broadcast_to(d, (len(self.inputs),))

    def structure(self) -> "Model":
        """The model without start values or held parameters: what the compiled
        programs depend on (the engine takes those as traced arrays), so fits of one
        model with other starts or other held sets share one compilation."""
        if not self.fixed and not any(self.start):
            return self
        return self.replace(start=tuple(0.0 for _ in self.parameters), fixed=())

    def replace(self, **changes) -> "Model":
        """A copy with some fields changed, e.g. `model.replace(fixed=("CMq",))` or
        `model.replace(start=...)`; a dict `start={"CMq": 0.0}` changes those."""
        fields = {
            k: getattr(self, k)
            for k in (
                "states",
                "inputs",
                "outputs",
                "parameters",
                "rates",
                "observe",
                "start",
                "fixed",
                "delays",
                "state_scale",
            )
        }
        if isinstance(changes.get("start"), dict):
            new = dict(zip(self.parameters, self.start, strict=True))
            for k, v in changes["start"].items():
                if k not in new:
                    raise ValueError(f"{k!r} is not a model parameter")
                new[k] = float(v)
            changes["start"] = tuple(new.values())
        fields.update(changes)
        args = [fields.pop(k) for k in ("states", "inputs", "outputs", "parameters")]
        rates, observe = fields.pop("rates"), fields.pop("observe")
        return Model(*args, rates, observe, **fields)


class Record(eqx.Module):
    """One manoeuvre: uniformly sampled known inputs and measured outputs.

    **Fields:**

    - `t`: `(samples,)` times, s, uniformly spaced.
    - `inputs`: `(samples, inputs)` known inputs, in the model's input order.
    - `measured`: `(samples, outputs)` measured outputs, in the model's output order.
    - `x0`: optional `(states,)` initial state (the value held when initial states are
      fixed, the start value when estimated); by default the measured outputs of the
      same names at the first sample.
    - `name`: what reports call the record (e.g. the file name).
    """

    t: np.ndarray
    inputs: np.ndarray
    measured: np.ndarray
    x0: np.ndarray | None = None
    name: str = eqx.field(static=True, default="record")

    def __init__(self, t, inputs, measured, x0=None, name="record"):
        self.t = np.asarray(t, float).reshape(-1)
        self.inputs = _rows(inputs, len(self.t), "inputs", name)
        self.measured = _rows(measured, len(self.t), "measured", name)
        self.x0 = None if x0 is None else np.asarray(x0, float).reshape(-1)
        self.name = str(name)

    def __check_init__(self):
        if len(self.t) < 2:
            raise ValueError(f"{self.name}: a record needs at least two samples")
        step = np.diff(self.t)
        if np.any(step <= 0):
            i = int(np.argmax(step <= 0)) + 1
            raise ValueError(
                f"{self.name}: time is not increasing at row {i + 1} "
                f"(t = {float(self.t[i]):g} s)"
            )
        # times printed with a few digits jitter by rounding: allow 1% of a step
        if np.max(np.abs(step - step.mean())) > 1e-2 * step.mean():
            raise ValueError(
                f"{self.name}: samples are not uniformly spaced "
                f"(steps from {float(step.min()):g} to {float(step.max()):g} s)"
            )
        for what in ("inputs", "measured"):
            a = getattr(self, what)
            bad = ~np.isfinite(a)
            if bad.any():
                row, col = np.argwhere(bad)[0]
                raise ValueError(
                    f"{self.name}: {what} column {int(col)} row {int(row) + 1} is "
                    f"{float(a[row, col])}"
                )

    @property
    def dt(self) -> float:
        """Sample interval, s."""
        return float((self.t[-1] - self.t[0]) / (len(self.t) - 1))

    def check(self, model: Model) -> None:
        """Raise a `ValueError` naming what does not match `model`."""
        if self.inputs.shape[1] != len(model.inputs):
            raise ValueError(
                f"{self.name}: {self.inputs.shape[1]} input columns, the model has "
                f"{len(model.inputs)} ({', '.join(model.inputs)})"
            )
        if self.measured.shape[1] != len(model.outputs):
            raise ValueError(
                f"{self.name}: {self.measured.shape[1]} output columns, the model has "
                f"{len(model.outputs)} ({', '.join(model.outputs)})"
            )
        if self.x0 is not None and len(self.x0) != len(model.states):
            raise ValueError(
                f"{self.name}: x0 has {len(self.x0)} values, the model has "
                f"{len(model.states)} states ({', '.join(model.states)})"
            )
        self._check_functions(model)

    def _check_functions(self, model: Model) -> None:
        """Trace `rates` and `observe` once, abstractly (`jax.eval_shape`: nothing is
        computed or compiled), at the first sample with the start values: a wrong
        parameter name, a wrong shape, NumPy on a traced value or any error in the
        user's code is reported here in one line rather than deep in a trace."""
        import jax

        # shapes only (numpy and ShapeDtypeStructs): `jnp.asarray` of a concrete
        # value would compile a small program per shape
        x = self.x0 if self.x0 is not None else self.measured_states(model, [0])[0]
        x = np.nan_to_num(np.asarray(x, float))
        u = np.asarray(self.inputs[0])
        dtype = jax.dtypes.canonicalize_dtype(np.float64)
        scalar = jax.ShapeDtypeStruct((), dtype, weak_type=True)
        p = {k: scalar for k in model.parameters}
        t = np.asarray(self.t[0])
        traced = (
            jax.errors.TracerArrayConversionError,
            jax.errors.ConcretizationTypeError,
            jax.errors.TracerBoolConversionError,
            jax.errors.TracerIntegerConversionError,
        )
        for what, fn, size, names in (
            ("rates", model.rates, len(model.states), model.states),
            ("observe", model.observe, len(model.outputs), model.outputs),
        ):
            try:
                out = jax.eval_shape(fn, t, x, u, p)
            except KeyError as e:
                key = e.args[0] if e.args else e
                raise ValueError(
                    f"{_where(e)}{what}(t, x, u, p): p[{key!r}] is not a model "
                    f"parameter ({', '.join(model.parameters)})"
                ) from None
            except traced as e:
                raise ValueError(
                    f"{_where(e)}{what}(t, x, u, p) converts a traced value to NumPy "
                    "or Python (np.*, float(), if on a value): write it with "
                    "jax.numpy (jnp.*, jnp.where) so it can be differentiated"
                ) from None
            except Exception as e:  # the user's code: one line, where it failed
                first = str(e).splitlines()[0] if str(e) else ""
                raise ValueError(
                    f"{_where(e)}{what}(t, x, u, p) failed: {type(e).__name__}: {first}"
                ) from None
            shapes = [getattr(a, "shape", ()) for a in jax.tree.leaves(out)]
            n = sum(int(np.prod(sh)) for sh in shapes)
            if n != size:
                kind = "states" if what == "rates" else "outputs"
                raise ValueError(
                    f"{what}(t, x, u, p) returns {n} value(s); the model has {size} "
                    f"{kind} ({', '.join(names)})"
                )

    def measured_states(self, model: Model, index) -> np.ndarray:
        """The states at sample indices `index` from outputs of the same name,
        `(len(index), states)`, NaN where a state is not measured."""
        index = np.asarray(index)
        out = np.full((len(index), len(model.states)), np.nan)
        for j, name in enumerate(model.states):
            if name in model.outputs:
                out[:, j] = self.measured[index, model.outputs.index(name)]
        return out


def _rows(a, n: int, what: str, name: str) -> np.ndarray:
    """`a` as `(n, columns)`: one row per time sample."""
    a = np.asarray(a, float)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] != n:
        raise ValueError(
            f"{name}: {what} has shape {a.shape}; it needs one row per time sample "
            f"({n} rows, one column per {'input' if what == 'inputs' else 'output'})"
        )
    return a


def _where(e: BaseException) -> str:
    """`file line N: ` of the innermost frame outside the package and JAX."""
    import traceback

    frames = traceback.extract_tb(e.__traceback__)
    for f in reversed(frames):
        if not any(
            part in f.filename
            for part in ("/jax/", "/jaxlib/", "/numpy/", "/diffpegasus/", "/equinox/")
        ):
            return f"{f.filename} line {f.lineno}: "
    return ""
