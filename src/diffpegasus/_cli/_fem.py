"""`fit/compare --method fem` (filter error) of a vehicle or model file, and the
process-noise candidate of `diagnose --vehicle/--model`."""

import sys

import numpy as np

from .._errors import LogError
from .._estimate._filter_error import filter_error, FilterErrorFit
from .._estimate._fit import SingleShooting
from .._estimate._modelfile import ModelSpec
from ._runners import (
    channel_report,
    load_records,
    num,
    parse_holds,
    parse_name_value,
    report_head,
)


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def check_method(method: str) -> str:
    """`method` if the estimator registry has it, else a `LogError` listing the
    names."""
    from .._estimate._methods import ESTIMATORS

    if method not in ESTIMATORS:
        names = ", ".join(ESTIMATORS)
        raise LogError(f"--method must be one of {names}, got {method!r}")
    return method


def parse_process_noise(texts, spec: ModelSpec):
    """`--process-noise STATE` / `STATE=F0` (repeatable) or, without any, the
    states of the spec's `process_noise` (a model file's, or the vehicle's: the
    HFB-320's four state equations), else every state. Without `=F0` the start
    intensities are scaled to an output-error fit's residuals (a spec's book start
    values can be far too large for a record the model already fits)."""
    model = spec.model
    if not texts:
        if spec.process_noise is not None:
            return tuple(spec.process_noise)
        return tuple(model.states)
    starts, names = {}, []
    for text in texts:
        name, value = parse_name_value(
            "--process-noise", text, model.states, f"a state of {spec.name}"
        )
        if value is not None:
            starts[name] = value
            if not starts[name] > 0:
                raise LogError(f"--process-noise {text}: the start must be positive")
        names.append(name)
    if starts and len(starts) != len(names):
        raise LogError(
            "--process-noise: give every state a start intensity (STATE=F0) or none"
        )
    return starts if starts else tuple(names)


def fem_report(result: FilterErrorFit, spec: ModelSpec) -> dict:
    """The JSON-ready summary of a filter-error fit: the output-error report's keys
    (`stderr` and `stderr_crb` are both the Cramér-Rao bound of the innovations'
    likelihood) plus `method`, `process_noise` and `process_noise_stderr` (state ->
    intensity, state units / sqrt(s)), `constraint_active` and `kc` (record ->
    state -> the diagonal of K C)."""
    ok = result.converged
    model = result.model

    hidden = set(spec.candidates)
    out = {
        **report_head(result, spec, np.diag(result.R)),
        "method": "fem",
        "process_noise": {
            s: num(f) if ok else None
            for s, f in zip(result.process_noise, result.F, strict=True)
        },
        "process_noise_stderr": {
            s: num(f) if ok else None
            for s, f in zip(result.process_noise, result.F_stderr, strict=True)
        },
        "constraint_active": bool(result.constraint_active),
        "kc": {
            rec.name: dict(zip(model.states, map(num, result.kc[i]), strict=True))
            for i, rec in enumerate(result.records)
        },
    }
    for i, name in enumerate(model.parameters):
        if name in hidden:
            continue
        est = num(result.params[i]) if ok else None
        sd = num(result.stderr[i]) if ok and result.free[i] else None
        out["estimates"][name] = est
        out["stderr"][name] = sd
        out["stderr_crb"][name] = sd
    if ok:
        names = model.parameters
        for i in range(len(names)):
            for j in range(i + 1, len(names)):
                c = float(result.correlation[i, j])
                if result.free[i] and result.free[j] and abs(c) > 0.9:
                    out["high_correlations"].append(
                        {"a": names[i], "b": names[j], "correlation": c}
                    )
    out["initial_states"] = {
        rec.name: dict(
            zip(
                model.states,
                np.asarray(
                    rec.x0 if rec.x0 is not None else rec.measured_states(model, [0])[0]
                ).tolist(),
                strict=True,
            )
        )
        for rec in result.records
    }
    return out


def format_fem_table(report: dict) -> str:
    """The estimate table of a filter-error fit with the intensities, cost and
    whether the gain constraint binds."""
    lines = [f"{'parameter':>12s} {'estimate':>14s} {'std. error':>12s} {'rel. %':>8s}"]
    rows = list(report["estimates"].items()) + [
        (f"F[{s}]", f) for s, f in report["process_noise"].items()
    ]
    sds = dict(report["stderr"])
    sds.update({f"F[{s}]": v for s, v in report["process_noise_stderr"].items()})
    for name, est in rows:
        sd = sds[name]
        if est is None:
            lines.append(f"{name:>12s} {'-':>14s}")
        elif name in report["fixed"]:
            lines.append(f"{name:>12s} {est:14.6g} {'(held)':>12s}")
        else:
            rel = 100 * sd / abs(est) if est else float("nan")
            lines.append(f"{name:>12s} {est:14.6g} {sd:12.4g} {rel:8.2f}")
    cost = "-" if report["cost"] is None else f"{report['cost']:.6e}"
    lines.append(
        f"filter error: det(R) = {cost}   iterations: "
        f"{report['iterations']}   diag(KC) <= 1 constraint "
        f"{'active' if report['constraint_active'] else 'inactive'}"
    )
    for c in report["high_correlations"]:
        lines.append(f"correlation {c['a']} / {c['b']}: {c['correlation']:+.3f}")
    return "\n".join(lines)


def run_model_fem(
    spec: ModelSpec,
    files,
    *,
    columns=None,
    holds=(),
    process_noise=(),
    channels: bool = True,
    records=None,
    max_iter: int | None = None,
) -> dict:
    """Fit `spec`'s model to `files` by the filter-error method (process noise on
    `--process-noise` states, else the spec's), as the library's
    `estimate(model, records, FilterError(process_noise=..., start=the spec's
    output-error fit), max_iter=max_iter, throw=False)` with the gain chosen from
    the record (one steady-state gain about one flight condition, else a gain
    scheduled along the trajectory, see `choose_gain`); the JSON-ready report,
    with per-channel metrics of the innovations when `channels`. The spec's
    shooting and initial state shape the output-error fit the filter starts
    from (a launch vehicle's multiple shooting: one simulation from drop does not
    follow the flight)."""
    spec = parse_holds(list(holds), spec)
    noise = parse_process_noise(process_noise, spec)
    if spec.biases:
        raise LogError(
            f"{spec.name}: the filter-error method has no output biases; this model "
            "file asks for them (use --method oem)"
        )
    if records is None:
        records = load_records(spec, files, columns)
    _say(
        f"fitting {spec.name} ({sum(spec.model.free)} free parameters, process noise "
        f"on {', '.join(noise)}) to {len(records)} record(s) by filter error"
    )
    options = dict(
        process_noise=noise,
        full_R=False,
        rtol=1e-6,
        max_iter=max_iter,
        throw=False,
        progress=sys.stderr.isatty(),
        gain=None,
        start_fit=start_fit(spec),
    )
    try:
        result = filter_error(spec.model, records, **options)
        if not result.converged and not isinstance(noise, dict):
            # as the diagnosis does: the output-error estimates can be far off in
            # turbulence; the model's start values are the second start
            _say(
                f"filter error from the output-error estimates: {result.message}; "
                "trying the model's start values"
            )
            second = filter_error(
                spec.model, records, start=spec.model.start, **options
            )
            if second.converged or not np.isfinite(result.cost):
                result = second
    except ValueError as e:
        raise LogError(str(e)) from None
    report = fem_report(result, spec)
    if channels and result.converged:
        report["channels"] = channel_report(result)
    return report


def start_fit(spec: ModelSpec) -> dict:
    """The output-error fit a filter-error fit of `spec` starts from: the spec's
    shooting and initial state."""
    return {
        "shooting": spec.shooting or SingleShooting(),
        "initial_state": spec.initial_state or "fixed",
    }


def diagnosis_states(texts, spec: ModelSpec):
    """The states `diagnose` scores process noise on: `--process-noise STATE`
    (repeatable; `none` skips the test), else the spec's `process_noise` (the
    HFB-320's four state equations; a model file's), else none."""
    texts = list(texts or ())
    if texts == ["none"]:
        return None
    if texts:
        return tuple(parse_process_noise(texts, spec))
    return None if spec.process_noise is None else tuple(spec.process_noise)


def process_noise_diagnosis(spec: ModelSpec, result, ranking, report: dict, names):
    """Add the process-noise candidate on the states `names` to a `diagnose
    --vehicle/--model` report (in place): the new ranking, the verdict when
    process noise decides it, and the filter-error fit's summary. The filter-error
    fit starts from the output-error estimates with intensities from the data
    (a tenth of each state's spread per sqrt(s)), not from the book's values."""
    from .._diagnose._process_noise import process_noise_candidate

    names = tuple(names)
    _say(f"scoring process noise on {', '.join(names)} (filter-error fit)")
    from .._estimate._gust import Gust

    gust = (
        None
        if spec.gust is None
        else Gust(
            tuple(spec.gust),
            # a model without the altitude state has no climb rate to keep inertial
            kinematic=tuple(s for s in spec.gust_kinematic if s in spec.model.states),
            pitch_rate=spec.gust_pitch_rate,
        )
    )
    fem, new, message = process_noise_candidate(
        result, ranking, names, gain=None, gust=gust
    )
    for row in new:
        row["hard_to_tell_from"] = [n.split(".")[0] for n in row["hard_to_tell_from"]]
    report["ranking"] = new
    report["significant"] = [r["effect"] for r in new if r["significant"]]
    if message is not None:
        report["message"] = message
    report["filter_error"] = fem_report(fem, spec)
