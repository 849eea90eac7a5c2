"""`fit`: output error on one or several records, single or multiple shooting."""

import math
from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._cache import kept_call
from .._model import Model, Record
from ._engine import explain, iteration_bound, Layout, Linearisation, RESULTS, solve
from ._estimator import AbstractFit


class SingleShooting(eqx.Module):
    """Each record is integrated from its initial state to its end."""


class MultipleShooting(eqx.Module):
    """A shooting node every `interval` seconds; node states are unknowns and
    continuity is enforced by defects weighted to `continuity_tol` times the state
    scale (a quadratic penalty that keeps the defects at that level or below).

    A penalty leaves its optimum off the constrained one: the defects it allows
    let the trajectory bend towards the data, and on a record whose residuals are
    small against the state scale that moves the estimates by several standard
    errors (3.2 on the unstable-aircraft record at `1e-4`). So once the fit
    converges it is solved again from there with the tolerance ten times tighter,
    until the estimates move less than `settle` of their (coloured-residual)
    standard errors: the optimum is then single shooting's, reached from starts
    single shooting cannot integrate from. Each tightening reuses the compiled
    program. A tightening that does not converge is discarded (the fit reports the
    tolerance it reached). `settle=None` keeps the penalty's optimum."""

    interval: float = eqx.field(static=True, default=2.0)
    continuity_tol: float = eqx.field(static=True, default=1e-4)
    settle: float | None = eqx.field(static=True, default=0.1)

    def __check_init__(self):
        if not self.interval > 0:
            raise ValueError(f"shooting interval must be positive, got {self.interval}")
        if self.settle is not None and not self.settle > 0:
            raise ValueError(f"settle must be positive or None, got {self.settle}")


def _bucket(n: int) -> int:
    """Round a segment length up so that records of similar length share one
    compiled program: to a multiple of 1/16 of the next power of two."""
    if n <= 64:
        return n
    quantum = 2 ** (math.ceil(math.log2(n)) - 4)
    return -(-n // quantum) * quantum


def layout(
    model: Model,
    records: Sequence[Record],
    shooting: SingleShooting | MultipleShooting,
    initial_state: str,
    biases: tuple[str, ...],
    state_scale: np.ndarray,
) -> Layout:
    """Cut the records into shooting segments (see [`Layout`][])."""
    nx = len(model.states)
    dts = np.array([rec.dt for rec in records])
    lengths = np.array([len(rec.t) for rec in records])
    if isinstance(shooting, MultipleShooting):
        # an interval longer than every record is one segment per record, not one
        # padded to the interval's length (1e9 s would ask for memory no one has)
        length = max(
            1, min(int(round(shooting.interval / dts.min())), int(lengths.max()))
        )
        tol = shooting.continuity_tol
    else:
        length = _bucket(int(lengths.max()))
        tol = 1.0
    record, first = [], []
    for i, n in enumerate(lengths):
        for s in range(-(-int(n) // length)):
            record.append(i)
            first.append(s * length)
    record, first = np.array(record), np.array(first)
    n_seg = len(record)
    index = first[:, None] + np.arange(length)[None, :]
    valid = index < lengths[record][:, None]
    measured = np.zeros((n_seg, length, len(model.outputs)))
    for s in range(n_seg):
        rec = records[record[s]]
        idx = np.minimum(index[s], len(rec.t) - 1)
        measured[s] = np.where(valid[s][:, None], rec.measured[idx], 0.0)
    # the inputs padded to whole segments, as `measured` is: records whose lengths
    # fall in one bucket (single shooting) or fill the same number of segments
    # (multiple shooting) then share one compiled program (the padding is the last
    # row, and the engine clips its input index at each record's own length)
    n_max = -(-int(lengths.max()) // length) * length
    inputs = np.zeros((len(records), n_max, len(model.inputs)))
    for i, rec in enumerate(records):
        inputs[i, : len(rec.t)] = rec.inputs
        inputs[i, len(rec.t) :] = rec.inputs[-1]
    starts = np.r_[True, record[1:] != record[:-1]]
    node_free = np.ones((n_seg, nx), bool)
    if initial_state == "fixed":
        node_free[starts] = False
    # device_put, not jnp.asarray: in JAX 0.10 the latter compiles a small program
    # per shape (0.05-0.1 s each, a second per command in all)
    put = jax.device_put
    return Layout(
        inputs=put(inputs),
        t0=put(np.array([rec.t[0] for rec in records], float)),
        dt=put(dts),
        n=put(lengths),
        record=put(record),
        first=put(first),
        measured=put(measured),
        valid=put(valid),
        link=put(~starts[1:]),
        scale=put(np.asarray(state_scale * tol, float)),
        node_free=put(node_free),
        length=length,
        bias_channels=tuple(model.outputs.index(b) for b in biases),
    )


class Fit(AbstractFit):
    """An output-error fit of a [`Model`][] to one or several [`Record`][]s.

    **Fields:**

    - `model`, `records`: what was fitted.
    - `params` `(params,)`: estimates (held parameters at their start values).
    - `free` `(params,)`: which were estimated.
    - `stderr` `(params,)`: Cramér-Rao standard errors (0 for held ones);
      `stderr_corrected`: the same corrected for coloured residuals (Morelli-Klein),
      never below `stderr`.
    - `correlation` `(params, params)`: correlation of the estimates.
    - `biases` `(records, len(bias_outputs))` and `bias_stderr`: per-record output
      biases (channel units) for the outputs `bias_outputs`.
    - `initial_states` `(records, states)` and `initial_stderr` (0 when held).
    - `nodes` `(segments, states)`: every shooting node.
    - `cost`: det(R); `R` `(outputs,)` the diagonal residual covariance.
    - `outputs`: per record, the model outputs `(samples, outputs)`.
    - `iterations`; `result` a [`RESULTS`][] code (`converged` is the bool);
      `reason` why it stopped and what to try (`message`, "" when converged);
      `defect`: the largest continuity defect relative to the state scale.
    - `layout`: the segments the engine solved (for the score test).
    - `linearisation`: the engine's `Linearisation` at the estimates (the
      score test of held parameters reuses it), `None` when the fit ran through
      another solver.
    """

    model: Model
    records: tuple[Record, ...]
    params: np.ndarray
    free: np.ndarray
    stderr: np.ndarray
    stderr_corrected: np.ndarray
    correlation: np.ndarray
    bias_outputs: tuple[str, ...] = eqx.field(static=True)
    biases: np.ndarray
    bias_stderr: np.ndarray
    initial_states: np.ndarray
    initial_stderr: np.ndarray
    nodes: np.ndarray
    cost: float
    R: np.ndarray
    outputs: tuple[np.ndarray, ...]
    iterations: int
    result: RESULTS
    reason: str
    defect: float
    layout: Layout
    linearisation: Linearisation | None = None

    @property
    def z(self) -> np.ndarray:
        """All unknowns in the engine's order: nodes, parameters, biases."""
        return np.concatenate(
            [self.nodes.reshape(-1), self.params, self.biases.reshape(-1)]
        )

    def table(self) -> list[dict]:
        """One row per parameter: estimate, standard error (coloured-residual
        corrected) and plain Cramér-Rao bound, relative error (%), 95% interval."""
        from ._oem import parameter_table

        rows = parameter_table(
            self.model.parameters, self.params, self.stderr_corrected, self.free
        )
        for row, crb, free in zip(rows, self.stderr, self.free, strict=True):
            row["stderr_crb"] = float(crb) if free else None
            row["fixed"] = not free
        return rows


def _output_information(jacobian, record, nx, p, nb):
    """The outputs' information about the parameters and biases, node states
    held: `A^T A` of the whitened output Jacobian's parameter and bias columns,
    `(p + records nb, p + records nb)`. Whether the inputs excite a parameter is a
    question about these columns alone (the continuity defects, weighted by a
    tolerance, can dwarf them in the full information without adding any)."""
    n_seg, length, n_out, _ = jacobian.shape
    n_rec = int(record.max()) + 1
    a = np.zeros((n_seg, length * n_out, p + n_rec * nb))
    a[..., :p] = jacobian[..., nx : nx + p].reshape(n_seg, -1, p)
    for s in range(n_seg if nb else 0):
        col = p + record[s] * nb
        a[s, :, col : col + nb] = jacobian[s, ..., nx + p :].reshape(-1, nb)
    a = a.reshape(-1, a.shape[-1])
    return a.T @ a


def _initial_nodes(model, records, lay, start):
    """Node guesses: measured states where the outputs have them, else a forward
    simulation of the start model from the record's initial state."""
    nx = len(model.states)
    record = np.asarray(lay.record)
    first = np.asarray(lay.first)
    nodes = np.zeros((len(record), nx))
    for i, rec in enumerate(records):
        segs = np.flatnonzero(record == i)
        guess = rec.measured_states(model, first[segs])
        x0 = rec.x0 if rec.x0 is not None else guess[0]
        if np.any(np.isnan(x0)):
            missing = [model.states[j] for j in np.flatnonzero(np.isnan(x0))]
            raise ValueError(
                f"{rec.name}: states {missing} are not measured outputs; give the "
                "record's initial state x0"
            )
        guess[0] = x0
        if np.any(np.isnan(guess)):
            sim = simulate(model, rec, start, x0)
            guess = np.where(np.isnan(guess), sim[first[segs]], guess)
        nodes[segs] = guess
    return nodes


def _state_scale(model, nodes):
    if model.state_scale is not None:
        return np.asarray(model.state_scale, float)
    spread = np.std(nodes, axis=0)
    level = np.max(np.abs(nodes), axis=0)
    return np.maximum(spread, 1e-3 * np.maximum(level, 1.0))


def simulate(model: Model, record: Record, params=None, x0=None) -> np.ndarray:
    """The model's states at the record's samples, `(samples, states)`, integrated by
    RK4 at the sample step from `x0` (default: the record's) with `params` (default:
    the model's start values) and the record's inputs."""
    params = np.asarray(model.start if params is None else params, float)
    return np.asarray(flown_states(model, record, params, x0))


def flown_states(model: Model, record: Record, params, x0=None) -> jax.Array:
    """[`simulate`][]'s states `(samples, states)` as a JAX array: the model flown
    over the record by single shooting (RK4 at the sample step, the engine's own
    segment) from `x0` (default: the record's, else its first measured sample) with
    `params` `(params,)`; differentiable in `params` and `x0`, and callable inside
    a traced function (one compiled program per model structure and layout)."""
    from ._engine import segment_solve

    x0 = record.x0 if x0 is None else x0
    if x0 is None:
        x0 = record.measured_states(model, [0])[0]
    lay = layout(
        model, [record], SingleShooting(), "fixed", (), np.ones(len(model.states))
    )
    xs, _ = jax.jit(segment_solve, static_argnums=0)(
        model.structure(), lay, 0, jnp.asarray(x0, float), jnp.asarray(params, float)
    )
    return xs[: len(record.t)]


def simulate_outputs(
    model: Model, t, inputs, params=None, x0=None, oversample: int = 1
) -> np.ndarray:
    """Noise-free model outputs `(samples, outputs)` at the times `t` (uniform) with
    known inputs `inputs` `(samples, inputs)`, integrated by RK4 at `1/oversample` of
    the sample step (inputs linearly interpolated) from `x0` (default: zeros) with
    `params` (default: the model's start values)."""
    from ._engine import segment_outputs

    t = np.asarray(t, float)
    inputs = np.asarray(inputs, float).reshape(len(t), -1)
    fine = np.linspace(t[0], t[-1], (len(t) - 1) * oversample + 1)
    u = np.column_stack(
        [np.interp(fine, t, inputs[:, j]) for j in range(inputs.shape[1])]
    )
    params = np.asarray(model.start if params is None else params, float)
    x0 = np.zeros(len(model.states)) if x0 is None else np.asarray(x0, float)
    rec = Record(fine, u, np.zeros((len(fine), len(model.outputs))), x0=x0)
    lay = layout(model, [rec], SingleShooting(), "fixed", (), np.ones(len(x0)))
    ys, _ = jax.jit(segment_outputs, static_argnums=0)(
        model.structure(), lay, 0, jnp.asarray(x0), jnp.asarray(params), jnp.zeros(0)
    )
    return np.asarray(ys)[: len(fine)][::oversample]


def fit(
    model: Model,
    records: Record | Sequence[Record],
    *,
    shooting: SingleShooting | MultipleShooting | None = None,
    initial_state: str = "fixed",
    biases: Sequence[str] = (),
    start=None,
    rtol: float = 1e-7,
    max_iter: int | None = None,
    throw: bool = True,
    acceleration: bool = False,
) -> Fit:
    """Maximum-likelihood output-error estimate of `model`'s parameters from one or
    several records (manoeuvres) that share them. Kept for one release: prefer
    `dp.estimate(model, records, dp.OutputError(...))`, the one entry for every
    method.

    **Arguments:**

    - `model`: the [`Model`][] (its `fixed` parameters are held at `start`).
    - `records`: a [`Record`][] or a list of them, of any lengths and sample rates.
    - `shooting`: [`SingleShooting`][] (the default) or [`MultipleShooting`][].
    - `initial_state`: `"fixed"` (each record's `x0`, by default its first measured
      sample, is held) or `"estimated"`.
    - `biases`: outputs that get a constant bias per record (estimated).
    - `start`: start values `(params,)` (default `model.start`).
    - `rtol`: stop when det(R) changes by less than this, relatively.
    - `max_iter`: iteration bound (default: the adaptive budget, see
      [`estimate`][]).
    - `throw`: raise a `RuntimeError` with the reason when the fit fails; with
      `throw=False` the [`Fit`][] carries the result code and `message` instead.
    - `acceleration`: Levenberg-Marquardt with geodesic acceleration (see
      [`solve`][]): the same optimum in fewer steps where the cost's valley bends.
      Off by default.

    **Returns:** a [`Fit`][].
    """
    return output_error(
        model,
        records,
        shooting=shooting,
        initial_state=initial_state,
        biases=biases,
        start=start,
        rtol=rtol,
        max_iter=max_iter,
        throw=throw,
        acceleration=acceleration,
    )


def output_error(
    model: Model,
    records: Record | Sequence[Record],
    *,
    shooting: SingleShooting | MultipleShooting | None = None,
    initial_state: str = "fixed",
    biases: Sequence[str] = (),
    start=None,
    rtol: float = 1e-7,
    max_iter: int | None = None,
    throw: bool = True,
    progress: bool = False,
    solver=None,
    acceleration: bool = False,
) -> Fit:
    """The output-error fit behind [`OutputError`][] and [`fit`][] (arguments as
    [`fit`][]'s; `progress` prints one line per iteration; `solver` a
    [`BlockLevenbergMarquardt`][] runs the iteration through optimistix instead
    of the engine's own loop)."""
    if acceleration and solver is not None:
        raise ValueError("acceleration is the engine's own loop's (solver=None)")
    records = (records,) if isinstance(records, Record) else tuple(records)
    shooting = SingleShooting() if shooting is None else shooting
    if not records:
        raise ValueError("no records to fit")
    if initial_state not in ("fixed", "estimated"):
        raise ValueError(
            f"initial_state must be 'fixed' or 'estimated', got {initial_state!r}"
        )
    biases = tuple(biases)
    for b in biases:
        if b not in model.outputs:
            raise ValueError(
                f"bias on {b!r}: not a model output ({', '.join(model.outputs)})"
            )
        if biases.count(b) > 1:
            # two biases on one output cannot be told apart: a singular fit
            raise ValueError(f"bias on {b!r} given twice; give each output once")
    for rec in records:
        rec.check(model)
    start = np.asarray(model.start if start is None else start, float)
    nx, p, nb = len(model.states), len(model.parameters), len(biases)
    probe = layout(model, records, shooting, initial_state, biases, np.ones(nx))
    nodes0 = _initial_nodes(model, records, probe, start)
    lay = layout(
        model, records, shooting, initial_state, biases, _state_scale(model, nodes0)
    )
    z0 = np.concatenate([nodes0.reshape(-1), start, np.zeros(len(records) * nb)])
    static = {
        "model": model.structure(),
        "nx": nx,
        "p": p,
    }
    if acceleration:  # absent otherwise: the plain step's kept program unchanged
        static["acceleration"] = True
    dynamic = {
        # traced: every bound shares one compiled program
        "max_iter": np.asarray(iteration_bound(max_iter)),
        "layout": lay,
        "z0": np.asarray(z0, float),
        "free_params": np.asarray(model.free),
        "rtol": np.asarray(rtol, float),
    }

    def run(dynamic):
        if solver is None:
            # through the cache's kept programs: a later process skips tracing
            return kept_call(solve, {**static, "progress": bool(progress)}, dynamic)
        from ._solver import solve_with_optimistix

        return solve_with_optimistix(**static, **dynamic, solver=solver)

    sol = run(dynamic)
    ns = lay.n_segments * nx
    tol = getattr(shooting, "continuity_tol", 1.0)
    iterations = int(sol.iterations)
    if getattr(shooting, "settle", None) is not None:
        free = np.flatnonzero(np.asarray(model.free)) + ns
        while bool(sol.result == RESULTS.successful) and tol > 1e-12:
            tighter = eqx.tree_at(lambda lay: lay.scale, lay, lay.scale / 10.0)
            again = run({**dynamic, "layout": tighter, "z0": np.asarray(sol.z)})
            if not bool(again.result == RESULTS.successful):
                break
            se = np.sqrt(np.clip(np.diag(np.asarray(again.corrected))[free], 0, None))
            moved = np.abs(np.asarray(again.z)[free] - np.asarray(sol.z)[free])
            sol, lay, tol = again, tighter, tol / 10.0
            iterations += int(again.iterations)
            if not np.any(moved > shooting.settle * np.where(se > 0, se, np.inf)):
                break
    sol = jax.tree.map(np.asarray, sol)
    var = np.clip(np.diag(sol.covariance), 0.0, None)
    var_c = np.maximum(np.clip(np.diag(sol.corrected), 0.0, None), var)
    sd, sd_c = np.sqrt(var), np.sqrt(var_c)
    block = sol.covariance[ns : ns + p, ns : ns + p]
    d = np.sqrt(np.clip(np.diag(block), 1e-300, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        # NaN where the information is singular (the result says so)
        correlation = block / (d[:, None] * d[None, :])
    nodes = sol.z[:ns].reshape(-1, nx)
    record = np.asarray(lay.record)
    starts = np.flatnonzero(np.r_[True, record[1:] != record[:-1]])
    outputs = []
    for i, rec in enumerate(records):
        segs = np.flatnonzero(record == i)
        outputs.append(sol.outputs[segs].reshape(-1, len(model.outputs))[: len(rec.t)])
    multiple = isinstance(shooting, MultipleShooting)
    names = list(model.parameters)
    names += [f"bias {b} ({rec.name})" for rec in records for b in biases]
    result, reason = explain(
        sol.result,
        information=_output_information(sol.jacobian, record, nx, p, nb),
        free=np.r_[np.asarray(model.free), np.ones(len(records) * nb, bool)],
        names=names,
        iterations=iterations,
        change=float(sol.change),
        defect=float(sol.defect) if multiple else None,
    )
    out = Fit(
        model=model,
        records=records,
        params=sol.z[ns : ns + p],
        free=np.asarray(model.free),
        stderr=sd[ns : ns + p],
        stderr_corrected=sd_c[ns : ns + p],
        correlation=correlation,
        bias_outputs=biases,
        biases=sol.z[ns + p :].reshape(len(records), nb),
        bias_stderr=sd_c[ns + p :].reshape(len(records), nb),
        initial_states=nodes[starts],
        initial_stderr=sd[:ns].reshape(-1, nx)[starts],
        nodes=nodes,
        cost=float(sol.cost),
        R=sol.R,
        outputs=tuple(outputs),
        iterations=iterations,
        result=result,
        reason=reason,
        defect=float(sol.defect) * tol,
        layout=lay,
        linearisation=sol.linearisation,
    )
    if throw and not out.converged:
        raise RuntimeError(f"output-error fit failed: {out.message}")
    return out


# the public name of `simulate` (the package's top level keeps `simulate` for one
# release as the Pegasus simulator's, see `diffpegasus.pegasus`)
simulate_model = simulate
