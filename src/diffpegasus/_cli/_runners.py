"""`diffpegasus fit DATA... --model FILE` / `--vehicle NAME`: fit a model to files,
report estimates with standard errors, correlations and the cost."""

import dataclasses
import pathlib
import sys

import numpy as np

from .._diagnose._candidates import diagnosis_message, score_candidates
from .._diagnose._rule import rule_summary
from .._errors import LogError
from .._estimate._fit import Fit, output_error
from .._estimate._modelfile import ModelSpec
from .._files import save_figure
from .._registry._records import load_records as load_records


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def parse_name_value(option: str, text: str, names, what: str):
    """`NAME` or `NAME=VALUE` of a command-line `option`: `(name, float value or
    None)`; a NAME not in `names` ("'x' is not WHAT (names)") or a VALUE that is no
    number is one `LogError` naming the option and the text."""
    name, sep, value = text.partition("=")
    name = name.strip()
    if name not in names:
        raise LogError(f"{option} {text}: {name!r} is not {what} ({', '.join(names)})")
    if not sep:
        return name, None
    try:
        number = float(value)
    except ValueError:
        raise LogError(f"{option} {text}: {value!r} is not a number") from None
    if not np.isfinite(number):
        raise LogError(f"{option} {text}: {value!r} is not a finite number")
    return name, number


def parse_holds(holds: list[str], spec: ModelSpec) -> ModelSpec:
    """Apply `--fix NAME=VALUE` (hold at VALUE) and `--fix NAME` (hold at the start)."""
    if not holds:
        return spec
    model = spec.model
    start, fixed = {}, list(model.fixed)
    for text in holds:
        name, value = parse_name_value(
            "--fix", text, model.parameters, f"a parameter of {spec.name}"
        )
        if value is not None:
            start[name] = value
        if name not in fixed:
            fixed.append(name)
    model = (
        model.replace(start=start or None, fixed=tuple(fixed))
        if start
        else model.replace(fixed=tuple(fixed))
    )
    return dataclasses.replace(spec, model=model)


def num(x) -> float | None:
    """A finite number for JSON, `None` for NaN or infinity."""
    x = float(x)
    return x if np.isfinite(x) else None


def report_head(result, spec: ModelSpec, r_diagonal) -> dict:
    """What every fit report starts with (output or filter error): the model, the
    records, whether and how it converged, the cost, the held parameters, the
    diagonal of R by output; `estimates`, `stderr`, `stderr_crb` and
    `high_correlations` left for the caller to fill."""
    model = result.model
    return {
        "model": spec.name,
        "records": [r.name for r in result.records],
        "converged": result.converged,
        "message": result.message,
        "cost": num(result.cost),
        "iterations": result.iterations,
        "estimates": {},
        "stderr": {},
        "stderr_crb": {},
        "fixed": [
            p
            for p, f in zip(model.parameters, result.free, strict=True)
            if not f and p not in spec.candidates
        ],
        "high_correlations": [],
        "R": {o: num(v) for o, v in zip(model.outputs, r_diagonal, strict=True)},
    }


def fit_report(result: Fit, spec: ModelSpec) -> dict:
    """The JSON-ready summary of a fit."""
    ok = result.converged
    model = result.model
    out = report_head(result, spec, result.R)
    hidden = set(spec.candidates)
    for row in result.table():
        name = row["parameter"]
        if name in hidden:
            continue
        out["estimates"][name] = num(row["estimate"]) if ok else None
        out["stderr"][name] = (
            None if not ok or row["stderr"] is None else num(row["stderr"])
        )
        out["stderr_crb"][name] = (
            None if not ok or row["stderr_crb"] is None else num(row["stderr_crb"])
        )
    if ok:
        # (held candidates are exactly 0: their correlations are 0 too)
        out["high_correlations"] = [
            {"a": a, "b": b, "correlation": c} for a, b, c in result.high_correlations()
        ]
    if result.bias_outputs:
        out["biases"] = {
            rec.name: {
                o: {
                    "estimate": num(result.biases[i, j]) if ok else None,
                    "stderr": num(result.bias_stderr[i, j]) if ok else None,
                }
                for j, o in enumerate(result.bias_outputs)
            }
            for i, rec in enumerate(result.records)
        }
    out["initial_states"] = {
        rec.name: dict(
            zip(model.states, result.initial_states[i].tolist(), strict=True)
        )
        for i, rec in enumerate(result.records)
    }
    return out


def channel_report(result: Fit) -> dict:
    """Per output: RMS of the residual, RMS over the measured range (`nrms`),
    Theil's inequality coefficient, R^2, and the Ljung-Box p-value of residual
    whiteness (small: coloured residuals, a missing term or turbulence), over all
    records."""
    from .._diagnose._metrics import ljung_box

    measured = np.concatenate([r.measured for r in result.records])
    model = np.concatenate(result.outputs)
    out = {}
    for j, name in enumerate(result.model.outputs):
        z, y = measured[:, j], model[:, j]
        e = z - y
        rms = float(np.sqrt(np.mean(e**2)))
        spread = float(np.ptp(z))
        sst = float(np.sum((z - z.mean()) ** 2))
        denom = float(np.sqrt(np.mean(z**2)) + np.sqrt(np.mean(y**2)))
        out[name] = {
            "rms": rms,
            "nrms": rms / spread if spread > 0 else None,
            "tic": rms / denom if denom > 0 else None,
            "r2": 1.0 - float(np.sum(e**2)) / sst if sst > 0 else None,
            "ljung_box_p": ljung_box(e)[1],
        }
    return out


def format_channels(channels: dict) -> str:
    lines = [
        f"{'output':>8s} {'rms':>11s} {'nrms':>7s} {'TIC':>7s} {'R^2':>7s} {'white p':>8s}"
    ]
    for name, m in channels.items():
        lines.append(
            f"{name:>8s} {m['rms']:11.4g} {m['nrms'] or float('nan'):7.3f} "
            f"{m['tic'] or float('nan'):7.3f} {m['r2'] or float('nan'):7.3f} "
            f"{m['ljung_box_p']:8.2g}"
        )
    return "\n".join(lines)


def format_table(report: dict) -> str:
    lines = [f"{'parameter':>12s} {'estimate':>14s} {'std. error':>12s} {'rel. %':>8s}"]
    for name, est in report["estimates"].items():
        sd = report["stderr"][name]
        if est is None:
            lines.append(f"{name:>12s} {'-':>14s}")
        elif name in report["fixed"]:
            lines.append(f"{name:>12s} {est:14.6g} {'(held)':>12s}")
        else:
            rel = 100 * sd / abs(est) if est else float("nan")
            lines.append(f"{name:>12s} {est:14.6g} {sd:12.4g} {rel:8.2f}")
    lines.append(f"det(R) = {report['cost']:.6e}   iterations: {report['iterations']}")
    for c in report["high_correlations"]:
        lines.append(f"correlation {c['a']} / {c['b']}: {c['correlation']:+.3f}")
    return "\n".join(lines)


def plot_fit(result: Fit, out: pathlib.Path, columns=None) -> list[pathlib.Path]:
    """One PNG per record: each output measured and modelled against time, in the
    units of the column map `columns` where it gives them ([`channel_units`][])."""
    import matplotlib

    from .._report._units import channel_units

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    names = result.model.outputs
    units = channel_units(names, columns)
    for i, rec in enumerate(result.records):
        fig, axes = plt.subplots(
            len(names), 1, figsize=(9, 1.6 * len(names) + 1), sharex=True, squeeze=False
        )
        for j, (ax, name) in enumerate(zip(axes[:, 0], names, strict=True)):
            unit, k = units[name]
            ax.plot(rec.t, rec.measured[:, j] * k, "k-", lw=1, label="measured")
            ax.plot(rec.t, result.outputs[i][:, j] * k, "r--", lw=1, label="model")
            ax.set_ylabel(f"{name}, {unit}")
            ax.grid(alpha=0.3)
        axes[0, 0].legend(loc="upper right")
        axes[-1, 0].set_xlabel("time, s")
        fig.suptitle(f"{rec.name}: output-error fit, det(R) = {result.cost:.4e}")
        fig.tight_layout()
        path = out / f"fit_{i + 1}_{pathlib.Path(rec.name).stem}.png"
        save_figure(fig, path, dpi=100)
        plt.close(fig)
        paths.append(path)
    return paths


def excitation_note(model, records) -> str | None:
    """Words for a fit whose inputs never move: the likely reason it failed."""
    if not model.inputs:
        return None
    if all(np.all(r.inputs == r.inputs[0]) for r in records):
        return (
            f"the input(s) {', '.join(model.inputs)} are constant in every record: "
            "nothing excites the vehicle, so the derivatives of the inputs (and often "
            "the others) cannot be identified; fit records with control inputs "
            "(a doublet, a 3-2-1-1) rather than more iterations"
        )
    return None


def _fit_spec(
    spec,
    files,
    columns,
    holds,
    initial_state,
    biases,
    shooting,
    records=None,
    max_iter=None,
):
    spec = parse_holds(list(holds), spec)
    if records is None:
        records = load_records(spec, files, columns)
    interval = getattr(shooting or spec.shooting, "interval", None)
    if interval is not None:
        for rec, f in zip(records, files, strict=True):
            if interval < 2 * rec.dt * (1 - 1e-9):
                raise LogError(
                    f"{f}: shooting interval {interval:g} s is shorter than two sample "
                    f"steps ({2 * rec.dt:g} s): each segment needs samples to fit "
                    "(--shooting-interval, or the model file's MultipleShooting)"
                )
    _say(
        f"fitting {spec.name} ({sum(spec.model.free)} free parameters) to "
        f"{len(records)} record(s) by output error"
    )
    try:
        result = output_error(
            spec.model,
            records,
            shooting=shooting or spec.shooting,
            initial_state=initial_state or spec.initial_state,
            biases=spec.biases if biases is None else biases,
            max_iter=max_iter,
            throw=False,
            progress=sys.stderr.isatty(),
        )
    except ValueError as e:
        raise LogError(str(e)) from None
    return spec, result


def run_model_diagnose(
    spec: ModelSpec,
    files,
    *,
    columns=None,
    holds=(),
    initial_state=None,
    biases=None,
    shooting=None,
    process_noise: tuple[str, ...] | None = None,
    records=None,
    max_iter: int | None = None,
    score_process_noise=None,
) -> dict:
    """Fit `spec`'s model with its candidates held, then rank the candidates by
    score test; the JSON-ready report (`ranking`, `significant`, `message`). With
    `process_noise` (states), process noise is scored too, by
    `score_process_noise(spec, result, ranking, report, states)` (the filter-error
    fit's `process_noise_diagnosis`, which the command passes in)."""
    if not spec.candidates:
        raise LogError(
            f"{spec.name} names no candidate terms to test (a model file lists held "
            "parameters in `candidates`)"
        )
    spec, result = _fit_spec(
        spec,
        files,
        columns,
        holds,
        initial_state,
        biases,
        shooting,
        records,
        max_iter,
    )
    report = {"fit": fit_report(result, spec), "ranking": [], "significant": []}
    if spec.notes and "baseline" in spec.notes:
        report["baseline"] = spec.notes["baseline"]
    if not result.converged and not (process_noise and np.isfinite(result.cost)):
        note = excitation_note(spec.model, result.records)
        report["message"] = (
            f"the output-error fit did not converge ({result.message}): no ranking"
            + (f"; {note}" if note else "")
        )
        return report
    ranking = score_candidates(result, spec.candidates)
    # the decision rule shared with the Pegasus workflow (see _diagnose/_rule.py)
    report["message"] = diagnosis_message(ranking, result)
    report["rule"] = rule_summary(ranking)
    for row in ranking:
        row["hard_to_tell_from"] = [n.split(".")[0] for n in row["hard_to_tell_from"]]
    report["ranking"] = ranking
    report["significant"] = [r["effect"] for r in ranking if r["significant"]]
    report["cost"] = result.cost
    if process_noise and result.bias_outputs:
        report["process_noise"] = (
            "not scored: the filter-error method has no output biases (the model "
            "file asks for them)"
        )
    elif process_noise:
        score_process_noise(spec, result, ranking, report, process_noise)
    if not result.converged:
        report["message"] = (
            f"the output-error fit did not converge ({result.message}); "
            + report["message"]
        )
    return report


def run_model_fit(
    spec: ModelSpec,
    files,
    *,
    columns=None,
    holds=(),
    initial_state: str | None = None,
    biases: tuple[str, ...] | None = None,
    shooting=None,
    out: pathlib.Path | None = None,
    records=None,
    max_iter: int | None = None,
) -> dict:
    """Fit `spec`'s model to `files` (one manoeuvre each, or the `records` a
    vehicle's entry built from them); the JSON-ready report."""
    spec, result = _fit_spec(
        spec,
        files,
        columns,
        holds,
        initial_state,
        biases,
        shooting,
        records,
        max_iter,
    )
    report = fit_report(result, spec)
    if not result.converged and (note := excitation_note(spec.model, result.records)):
        report["message"] = f"{report['message']}; {note}"
    if result.converged:
        report["channels"] = channel_report(result)
    if out is not None:
        from .._report._markdown import write_index

        report["figures"] = [str(p) for p in plot_fit(result, out, spec.columns)]
        write_index(out)
    return report
