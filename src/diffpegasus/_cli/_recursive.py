"""`replay`: recursive estimation over a log, as it would run in flight."""

import json
import pathlib
from typing import Annotated

import typer

from .._log._format import LogError
from ._common import _check_out, _fail, app, JsonOption, OutOption


def _band(text: str) -> tuple[float, float]:
    try:
        low, high = (float(v) for v in text.split(","))
    except ValueError:
        _fail(f"--band must be LOW,HIGH in Hz, e.g. 0.1,1.5; got {text!r}")
    if not high > low > 0:
        _fail(f"--band {text}: need 0 < LOW < HIGH (0 Hz carries the biases)")
    return low, high


@app.command("replay")
def replay_command(
    log: Annotated[pathlib.Path, typer.Argument(help="Log or data file")],
    model: Annotated[
        pathlib.Path | None,
        typer.Option(
            help="Model-definition file (linear in its parameters); "
            "without it the log is a launch-vehicle log and CL, CD, CM are tracked on "
            "[1, alpha, de]"
        ),
    ] = None,
    method: Annotated[str, typer.Option(help="rls or rft")] = "rft",
    memory: Annotated[
        float,
        typer.Option(help="Forgetting time constant, s (inf: all data)"),
    ] = float("inf"),
    band: Annotated[
        str,
        typer.Option(
            help="the manoeuvre's band LOW,HIGH Hz: rft's frequencies; rls "
            "low-passes its differenced state equations at HIGH"
        ),
    ] = "0.1,1.5",
    step: Annotated[float, typer.Option(help="rft frequency spacing, Hz")] = 0.04,
    out: OutOption = None,
    as_json: JsonOption = False,
):
    """Replay a log through a recursive estimator, one update per sample.

    As in flight: every estimate is plotted with its 95% band against time.
    """
    import numpy as np

    _check_out(out, "folder")
    if method not in ("rls", "rft"):
        _fail(f"--method must be rls or rft, got {method!r}")
    from .._estimate import _recursive as rec_

    truth = None
    try:
        if model is not None:
            from .._estimate._modelfile import load_model_file
            from .._log._columns import load_record

            spec = load_model_file(model)
            record = load_record(
                spec.model, log, spec.columns, x0=spec.x0, reader=spec.read
            )
            reg = rec_.model_regression(spec.model, record)
            t0, dt = float(record.t[0]), record.dt
            start = np.asarray(spec.model.start)[list(reg.index)]
        else:
            from .._log._format import read_log

            flight = read_log(log)
            reg = rec_.coefficient_regression(
                flight.channels, flight.s_ref, flight.c_ref
            )
            t0, dt = float(flight.t[0]), 1.0 / flight.sample_rate
            start = np.zeros(9)
            if flight.has_truth:
                truth = {
                    n: np.asarray(flight.channels[f"true_{n}"])
                    for n in ("CLa", "CLde", "CDa", "CDde", "CMa", "CMde")
                }
    except (LogError, ValueError) as e:
        _fail(str(e))
    try:
        lam = rec_.forgetting_for(memory, dt)
        low, high = _band(band)
        if method == "rls":
            est = rec_.RecursiveLeastSquares(
                forgetting=lam, derivative=reg.derivative, dt=dt, bandwidth=high
            )
        else:
            freqs = tuple(float(f) for f in np.arange(low, high + 1e-9, step))
            est = rec_.RecursiveFourier(
                frequencies=freqs, forgetting=lam, derivative=reg.derivative, dt=dt
            )
    except ValueError as e:
        _fail(str(e))
    hist = rec_.replay(est, reg.h, reg.y, reg.o, np.asarray(start, float), t0)
    theta = np.asarray(hist.theta)
    sd = np.asarray(hist.stderr_corrected)
    half = np.asarray(hist.halfwidth)
    final = {n: float(v) for n, v in zip(reg.parameters, theta[-1], strict=True)}
    final_sd = {n: float(v) for n, v in zip(reg.parameters, sd[-1], strict=True)}
    summary = {
        "method": method,
        "forgetting": lam,
        "memory_s": memory,
        "equations": list(reg.equations),
        "final": final,
        "final_stderr_corrected": final_sd,
        "final_band_halfwidth": {
            n: float(v) for n, v in zip(reg.parameters, half[-1], strict=True)
        },
    }
    if truth is not None:
        cover = {}
        for k, n in enumerate(reg.parameters):
            if n in truth:
                inside = np.abs(theta[:, k] - truth[n]) <= half[:, k]
                skip = len(inside) // 10  # after the first tenth (start-up)
                cover[n] = float(np.mean(inside[skip:]))
        summary["band_coverage_of_truth"] = cover
    if out is not None:
        from .._report._bode import plot_history

        out.mkdir(parents=True, exist_ok=True)
        tr = None
        if truth is not None:
            tr = np.column_stack(
                [truth.get(n, np.full(len(theta), np.nan)) for n in reg.parameters]
            )
        plot_history(
            hist.t,
            theta,
            half,
            reg.parameters,
            out / "estimates.png",
            truth=tr,
            title=f"{method}: {log.name}, memory {memory:g} s",
        )
        header = "t," + ",".join(
            [*reg.parameters, *(f"stderr_{n}" for n in reg.parameters)]
        )
        np.savetxt(
            out / "estimates.csv",
            np.column_stack([np.asarray(hist.t), theta, sd]),
            delimiter=",",
            header=header,
            comments="",
        )
        (out / "summary.json").write_text(json.dumps(summary, indent=2))
    if as_json:
        typer.echo(json.dumps(summary))
        return
    typer.echo(f"{method}: {len(theta)} samples, memory {memory:g} s")
    for n in reg.parameters:
        typer.echo(f"  {n:>8s} {final[n]: .6g} +- {final_sd[n]:.3g}")
    if "band_coverage_of_truth" in summary:
        typer.echo(
            "95% band covers the truth (after the first tenth): "
            + ", ".join(
                f"{k} {v:.0%}" for k, v in summary["band_coverage_of_truth"].items()
            )
        )
