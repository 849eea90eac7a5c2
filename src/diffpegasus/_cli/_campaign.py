"""`montecarlo` and `design-input`: campaigns and input design."""

import json
import pathlib
from typing import Annotated

import typer

from .._files import write_text
from ._common import (
    _fail,
    app,
    at_least_one,
    finite,
    FIT,
    OUTPUT,
    positive,
)


THESIS_PANEL = "Pegasus thesis reproduction"
RUN = "Processes and hosts"
SIM = "Simulation"


@app.command(rich_help_panel=THESIS_PANEL)
def montecarlo(
    samples: Annotated[
        int,
        typer.Option(
            help="Number of perturbed flights",
            callback=at_least_one,
            rich_help_panel=SIM,
        ),
    ] = 100,
    methods: Annotated[
        str,
        typer.Option(help="Comma-separated subset of lse,nn,oem", rich_help_panel=FIT),
    ] = "lse,nn,oem",
    seed: Annotated[
        int, typer.Option(help="Seed of the draws", rich_help_panel=SIM)
    ] = 0,
    out: Annotated[
        pathlib.Path,
        typer.Option(
            help="Results folder (a rerun resumes it)", rich_help_panel=OUTPUT
        ),
    ] = pathlib.Path("montecarlo"),
    batch: Annotated[
        int,
        typer.Option(
            help="Flights per chunk (sharded over the cores)",
            callback=at_least_one,
            rich_help_panel=RUN,
        ),
    ] = 10,
    duration: Annotated[
        float,
        typer.Option(help="Flight length, s", callback=positive, rich_help_panel=SIM),
    ] = 80.3,
    sample_rate: Annotated[
        float, typer.Option(help="Log rate, Hz", callback=positive, rich_help_panel=SIM)
    ] = 1000.0,
    nn_epochs: Annotated[
        int,
        typer.Option(
            help="Maximum training epochs of the network",
            callback=at_least_one,
            rich_help_panel=FIT,
        ),
    ] = 1000,
    max_iter: Annotated[
        int,
        typer.Option(
            help="Iteration bound of each flight's OEM fit (the fits of a chunk are "
            "batched, so one creeping fit holds its chunk; a fit that stops short "
            "counts as not converged)",
            callback=at_least_one,
            rich_help_panel=FIT,
        ),
    ] = 30,
    processes: Annotated[
        int,
        typer.Option(
            help="Run the campaign in N processes on this machine (the cores "
            "shared out among them), coordinated by jax.distributed on 127.0.0.1",
            rich_help_panel=RUN,
        ),
    ] = 1,
    coordinator: Annotated[
        str | None,
        typer.Option(
            help="Several hosts: HOST:PORT of process 0's coordination service (the "
            "same on every host), with --num-processes and --process-id; `auto` to "
            "take all three from SLURM, Open MPI, ... (jax.distributed.initialize)",
            rich_help_panel=RUN,
        ),
    ] = None,
    num_processes: Annotated[
        int | None,
        typer.Option(
            help="Several hosts: how many processes in all", rich_help_panel=RUN
        ),
    ] = None,
    process_id: Annotated[
        int | None,
        typer.Option(
            help="Several hosts: this process's index, 0..N-1", rich_help_panel=RUN
        ),
    ] = None,
):
    """Monte Carlo comparison of LSE, NN+LSE and OEM on perturbed Pegasus flights.

    The thesis's chapter 6: per-flight MSE, tables beside the thesis, box plots,
    coverage and wall times in `--out`. Interrupted runs resume without
    recomputing; damaged chunk files are reported and computed again. With
    `--processes`, or `--coordinator` on several hosts, the processes share the
    chunks out and process 0 writes the summary.
    """
    import os

    from .._campaign._distributed import launch_local, start_distributed

    if processes < 1:
        _fail(f"--processes must be at least 1, got {processes}")
    if processes > 1:
        if coordinator is not None:
            _fail("use either --processes (one machine) or --coordinator (hosts)")
        args = [
            f"--samples={samples}",
            f"--methods={methods}",
            f"--seed={seed}",
            f"--out={out}",
            f"--batch={batch}",
            f"--duration={duration!r}",
            f"--sample-rate={sample_rate!r}",
            f"--nn-epochs={nn_epochs}",
            f"--max-iter={max_iter}",
        ]
        try:
            launch_local(["montecarlo", *args], processes)
        except (ValueError, OSError) as e:
            _fail(str(e))
        summary = json.loads((out / "summary.json").read_text())
    else:
        # one CPU device per core (or per core of this process's share), before
        # JAX starts its backend
        if "xla_force_host_platform_device_count" not in os.environ.get(
            "XLA_FLAGS", ""
        ):
            flag = f"--xla_force_host_platform_device_count={os.cpu_count()}"
            os.environ["XLA_FLAGS"] = (
                f"{os.environ.get('XLA_FLAGS', '')} {flag}".strip()
            )
        try:
            start_distributed(coordinator, num_processes, process_id)
        except (ValueError, RuntimeError) as e:
            _fail(str(e))
        import jax

        from .._campaign._montecarlo import Campaign, run_campaign

        devices = len(jax.local_devices())
        if batch % devices:
            batch = -(-batch // devices) * devices
            typer.echo(
                f"--batch rounded up to {batch}, a multiple of the {devices} devices",
                err=True,
            )
        try:
            campaign = Campaign(
                samples=samples,
                methods=tuple(m.strip() for m in methods.split(",") if m.strip()),
                seed=seed,
                batch=batch,
                t_final=duration,
                sample_rate=sample_rate,
                decimate=max(1, int(round(sample_rate / 200.0))),
                nn_epochs=nn_epochs,
                max_iter=max_iter,
            )
            summary = run_campaign(campaign, out)
        except (ValueError, OSError) as e:
            _fail(str(e))
        if jax.process_index() != 0:
            return  # process 0 prints the tables
    typer.echo((out / "tables.md").read_text())
    if "oem_coverage_2sigma" in summary:
        cov = summary["oem_coverage_2sigma"]["overall"]
        typer.echo(f"OEM 2-sigma coverage: {100 * cov:.1f}% of windows")
    typer.echo(
        f"wrote mse.csv, mse_means.csv, mse_std.csv, tables.md, figures, times.json "
        f"and summary.json in {out}"
    )


@app.command("design-input", rich_help_panel=THESIS_PANEL)
def design_input(
    criterion: Annotated[
        str,
        typer.Option(
            help="D (log det) or A (trace) of the relative CRB", rich_help_panel=FIT
        ),
    ] = "D",
    max_deflection: Annotated[
        float, typer.Option(help="Peak excitation, deg", callback=positive)
    ] = 2.0,
    max_rate: Annotated[
        float, typer.Option(help="Peak rate, deg/s", callback=positive)
    ] = 40.0,
    max_alpha: Annotated[
        float,
        typer.Option(
            help="Peak alpha excursion from the unexcited flight, deg",
            callback=positive,
        ),
    ] = 2.0,
    start: Annotated[
        float, typer.Option(help="Segment start, s", callback=finite)
    ] = 20.0,
    length: Annotated[
        float, typer.Option(help="Segment length, s", callback=positive)
    ] = 5.0,
    steps: Annotated[
        int,
        typer.Option(
            help="Optimiser steps", callback=at_least_one, rich_help_panel=FIT
        ),
    ] = 150,
    out: Annotated[
        pathlib.Path,
        typer.Option(help="Folder for the results", rich_help_panel=OUTPUT),
    ] = pathlib.Path("design"),
):
    """Design the Pegasus elevator excitation that identifies the derivatives best.

    Optimises the excitation for the OEM (Cramér-Rao criterion through the
    differentiable model) and compares it with hand-picked inputs under the same
    limits: design.json, design_inputs.png, design_stderr.png.
    """
    import numpy as np

    from .._design._optimal import Limits, pegasus_design, run_design
    from .._report._plotting import plot_design
    from .._vehicle._pegasus._aerodynamics import DERIVATIVE_NAMES

    if criterion not in ("D", "A"):
        _fail(f"--criterion must be D or A, got {criterion!r}")
    if min(max_deflection, max_rate, max_alpha, length) <= 0:
        _fail("limits and --length must be positive")
    out.mkdir(parents=True, exist_ok=True)
    typer.echo("building the design model and optimising (compiles first)...", err=True)
    design = pegasus_design((start, start + length))
    limits = Limits(
        float(np.deg2rad(max_deflection)),
        float(np.deg2rad(max_rate)),
        float(np.deg2rad(max_alpha)),
    )
    result = run_design(design, limits, kind=criterion, steps=steps)
    plot_design(design, result, out)
    report = _design_report(result, criterion, limits, (start, start + length))
    write_text(out / "design.json", json.dumps(report, indent=2))
    from .._report._markdown import write_index

    write_index(out, "input design")
    typer.echo(
        f"predicted standard errors, 1/deg (criterion {criterion}, lower is better):"
    )
    typer.echo("  input       " + "".join(f"{n:>10s}" for n in DERIVATIVE_NAMES))
    for name, row in report["inputs"].items():
        typer.echo(
            f"  {name:10s}  "
            + "".join(f"{row['stderr_per_deg'][n]:10.2e}" for n in DERIVATIVE_NAMES)
        )
    typer.echo(
        f"wrote design.json, design_inputs.png, design_stderr.png, index.md in {out}"
    )


def _design_report(result, criterion, limits, segment) -> dict:
    import numpy as np

    from .._vehicle._pegasus._aerodynamics import DERIVATIVE_NAMES

    best = result["inputs"]["optimised"]
    return {
        "criterion": criterion,
        "segment_s": list(segment),
        "limits": {
            "max_deflection_deg": float(np.rad2deg(limits.max_deflection)),
            "max_rate_deg_s": float(np.rad2deg(limits.max_rate)),
            "max_alpha_excursion_deg": float(np.rad2deg(limits.max_excursion)),
        },
        "best_hand_picked": result["best_hand_picked"],
        "criterion_start": result["history"]["start"],
        "criterion_end": result["history"]["end"],
        "optimised_multisine": {
            "amplitudes_deg": (
                np.asarray(best.inner.amplitudes) * float(best.scale)
            ).tolist(),
            "frequencies_hz": np.asarray(best.inner.frequencies).tolist(),
            "phases_rad": np.asarray(best.inner.phases).tolist(),
        },
        "inputs": {
            name: {
                "criterion": row["criterion"],
                "stderr_per_deg": dict(
                    zip(
                        DERIVATIVE_NAMES,
                        (np.asarray(row["stderr"]) * np.pi / 180).tolist(),
                        strict=True,
                    )
                ),
                "peak_deflection_deg": float(np.rad2deg(row["peaks"]["deflection"])),
                "peak_rate_deg_s": float(np.rad2deg(row["peaks"]["rate"])),
                "peak_alpha_excursion_deg": float(
                    np.rad2deg(row["peaks"]["excursion"])
                ),
            }
            for name, row in result["rows"].items()
        },
    }
