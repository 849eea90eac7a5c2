"""`rocket fit | compare | diagnose`: a rocket flight from its `rocket.toml` and logs."""

import json
import math
import pathlib
from typing import Annotated

import typer

from .._errors import LogError
from ._common import _fail, app, FIT_FAILED


rocket_app = typer.Typer(
    help="Rocket flights: CD(Mach), thrust and apogee from a flight computer's log.",
    no_args_is_help=True,
)
app.add_typer(rocket_app, name="rocket")

TomlArgument = Annotated[
    pathlib.Path,
    typer.Argument(help="The rocket's rocket.toml (see the rockets guide)"),
]
LogsOption = Annotated[
    list[pathlib.Path] | None,
    typer.Option(
        "--log",
        help="A log file of the flight (repeat for several; "
        "default: the files the rocket.toml's [log] tables name)",
    ),
]
MapOption = Annotated[
    pathlib.Path | None,
    typer.Option("--columns", help="Column map (.json or .toml) for the log files"),
]
OutOption = Annotated[
    pathlib.Path | None, typer.Option(help="Folder for the figures and summary.json")
]
JsonOption = Annotated[bool, typer.Option("--json", help="Print one JSON object")]
AttitudeOption = Annotated[
    bool,
    typer.Option(
        "--attitude",
        help="Let the rocket weathercock (Barrowman normal force from the file's "
        "[geometry]); slower fits",
    ),
]


SpreadOption = Annotated[
    bool,
    typer.Option(
        "--sensor-spread/--no-sensor-spread",
        help="Add the disagreement between the barometer and the accelerometer to "
        "CD's band (each sensor's own fit from the joint one; --no-sensor-spread: "
        "the noise's band alone, faster)",
    ),
]


def _load(toml, logs, columns, attitude=False):
    from .._vehicle._rocket import read_rocket

    if not toml.is_file():
        _fail(f"{toml}: no such file")
    try:
        rocket = read_rocket(toml, attitude=attitude)
        from .._log._rocketlogs import read_rocket_log

        log = read_rocket_log(list(logs) if logs else toml, columns)
    except LogError as e:
        _fail(str(e))
    return rocket, log


def _pct(v):
    return "-" if v is None else f"{v:+.2f}%"


def _m(v):
    return "-" if v is None else f"{v:.0f} m"


def _band(half_width):
    """The predicted apogee's 95% band as the terminal shows it ("" without one)."""
    if half_width is None or not math.isfinite(half_width):
        return ""
    return f"+/- {half_width:.0f} m (95%) "


DescentOption = Annotated[
    bool,
    typer.Option(
        "--descent",
        help="fit the record past apogee too: the fall under each parachute stage "
        "(the barometer alone), each stage's drag area CdS",
    ),
]


GnssOption = Annotated[
    bool,
    typer.Option(
        "--gnss",
        help="Fit the log's GNSS position too (east and north of the pad, where it "
        "has fixes), with the wind's east and north components",
    ),
]


@rocket_app.command("fit")
def fit_command(
    toml: TomlArgument,
    log: LogsOption = None,
    columns: MapOption = None,
    out: OutOption = None,
    as_json: JsonOption = False,
    attitude: AttitudeOption = False,
    sensor_spread: SpreadOption = True,
    descent: DescentOption = False,
    gnss: GnssOption = False,
):
    """Fit CD(Mach), thrust scale and the barometer to the ascent; reconstruct and
    predict the apogee (from the log up to 2 s after burnout); re-simulate with the
    team's drag curve; write figures with --out. --descent: the descent under
    parachutes too, each stage's CdS. --gnss: the GNSS position too."""
    from .._rocket._pipeline import run_flight

    if out is not None and out.exists() and not out.is_dir():
        _fail(f"{out}: --out names a file; give a folder for the figures")
    rocket, flight_log = _load(toml, log, columns, attitude)
    try:
        extra = {"descent": True} if descent else {}  # the call as before without
        extra.update({"gnss": True} if gnss else {})
        row = run_flight(rocket, flight_log, out, spread=sensor_spread, **extra)
    except LogError as e:
        _fail(str(e))
    if as_json:
        typer.echo(json.dumps(row, default=float))
        _exit_unless_converged(toml, row)
        return
    typer.echo(
        f"{row['flight']}: fitted {', '.join(row['outputs'])} "
        f"in {row['fit_seconds']:.1f} s"
        + ("" if row["converged"] else " (NOT converged)")
    )
    if row.get("not_converged_reason"):
        typer.echo(f"  not converged:         {row['not_converged_reason']}")
    typer.echo(f"  apogee logged          {_m(row['apogee_logged_m'])}")
    typer.echo(
        f"  apogee reconstructed   {_m(row['apogee_reconstructed_m'])} "
        f"({_pct(row['reconstructed_error_pct'])})"
    )
    typer.echo(
        f"  apogee predicted       {_m(row['apogee_predicted_m'])} "
        f"{_band(row.get('apogee_predicted_half_width_m'))}"
        f"({_pct(row['predicted_error_pct'])}, log to "
        f"{row['prediction_uses_log_to_s']:.1f} s)"
    )
    typer.echo(
        f"  team pre-flight        {_m(row['apogee_team_preflight_m'])} "
        f"({_pct(row['team_preflight_error_pct'])})"
    )
    typer.echo(
        f"  altitude RMS           {row['altitude_rms_m']:.1f} m "
        f"({row['altitude_rms_pct_of_apogee']:.2f}% of apogee)"
    )
    typer.echo(
        f"  thrust scale           {row['thrust_scale']:.3f} "
        f"+/- {row['thrust_scale_stderr']:.3f}"
    )
    note = row.get("cd_structural", {}).get("note")
    if note:
        typer.echo(f"  CD band                {note}")
    for d in row.get("descent", []):
        file = d["cds_rocket_file_m2"]
        typer.echo(
            f"  {d['stage']:<6} CdS            {d['cds_m2']:.3f} "
            f"+/- {d['cds_stderr_m2']:.3f} m^2"
            + ("" if file is None else f" (rocket file {file:.3f})")
            + f", falling {d['fall_rate_log_m_s']:.1f} m/s "
            f"(model {d['fall_rate_model_m_s']:.1f}), full "
            + (
                f"{d['open_s']:.2f} +/- {d['open_stderr_s']:.2f} s"
                if d["open_stderr_s"] > 0
                else f"{d['open_s']:.2f} s (held)"
            )
            + " after its event"
        )
    if out is not None:
        typer.echo(
            f"  figures and summary.json in {out}"
            if row["converged"]
            else f"  summary.json in {out} (no figures: the fit did not converge)"
        )
    _exit_unless_converged(toml, row)


def _exit_unless_converged(toml, row):
    """Exit 3 (the input was fine, the fit failed) after the report of a fit that did
    not converge: its numbers are printed and written, but a script must not take
    them for a result."""
    if not row["converged"]:
        why = row.get("not_converged_reason") or "see the report"
        typer.echo(f"error: {toml}: the fit did not converge: {why}", err=True)
        raise typer.Exit(code=FIT_FAILED)


@rocket_app.command("compare")
def compare_command(
    toml: TomlArgument,
    log: LogsOption = None,
    columns: MapOption = None,
    as_json: JsonOption = False,
    attitude: AttitudeOption = False,
):
    """CD(Mach) identified (95% band) beside the team's curve, and the apogee flown
    with each."""
    from .._rocket._pipeline import run_flight

    rocket, flight_log = _load(toml, log, columns, attitude)
    row = run_flight(rocket, flight_log, None)
    if as_json:
        typer.echo(
            json.dumps(
                {
                    k: row[k]
                    for k in (
                        "flight",
                        "cd_table",
                        "apogee_logged_m",
                        "apogee_reconstructed_m",
                        "apogee_resimulated_team_cd_m",
                    )
                },
                default=float,
            )
        )
        return
    typer.echo(f"{row['flight']}: CD(Mach), power off")
    typer.echo("  Mach   CD      95% band          team")
    for r in row["cd_table"]:
        lo, hi = r["cd"] - 1.96 * r["stderr"], r["cd"] + 1.96 * r["stderr"]
        typer.echo(
            f"  {r['mach']:.2f}   {r['cd']:.3f}   [{lo:6.3f}, {hi:6.3f}]   "
            f"{r['team_cd']:.3f}"
        )
    typer.echo(
        f"  apogee: logged {_m(row['apogee_logged_m'])}, identified CD "
        f"{_m(row['apogee_reconstructed_m'])}, team CD and catalogue thrust "
        f"{_m(row['apogee_resimulated_team_cd_m'])}"
    )


@rocket_app.command("diagnose")
def diagnose_command(
    toml: TomlArgument,
    log: LogsOption = None,
    columns: MapOption = None,
    as_json: JsonOption = False,
    attitude: AttitudeOption = False,
    descent: DescentOption = False,
    gnss: GnssOption = False,
):
    """Name the effects the flight shows beyond drag and thrust (wind, rail
    friction, barometer lag, static-pressure errors, mass error, air brakes, ...).
    --descent: with the descent under parachutes in the fit. --gnss: with the GNSS
    position in the fit (the wind's east and north components the candidates
    instead of the one along the rail). A finding's
    statistic passes the log's own threshold; an effect one sensor alone shows (the
    barometer's lag and pressure errors, the accelerometer's scale; every effect
    without an accelerometer) must also explain half or more of the fit's misfit
    (the predicted fall of det(R))."""
    from .._rocket._diagnose import diagnose, SHARE
    from .._rocket._identify import prepare

    rocket, flight_log = _load(toml, log, columns, attitude)
    try:
        problem = prepare(rocket, flight_log, descent=descent, gnss=gnss)
    except LogError as e:
        _fail(str(e))
    try:
        named, rows, _ = diagnose(problem)
    except LogError as e:
        _fail(str(e))
    if as_json:
        typer.echo(
            json.dumps(
                {"flight": rocket.name, "named": named, "tests": rows}, default=float
            )
        )
        return
    typer.echo(f"{rocket.name}: " + (", ".join(named) if named else "nothing named"))
    if rows:
        typer.echo(
            f"   burn's length held at {rows[0]['burn_scale_held']:.4f} of the "
            f"catalogue's ({rows[0]['burn_scale_from']})"
        )
    for r in rows:
        mark = "*" if r["significant"] else " "
        if r.get("uninformed"):
            typer.echo(
                f" {mark} round {r['round']}: {r['candidate']:<34} not scored: "
                "this log holds no information on it"
            )
            continue
        line = (
            f" {mark} round {r['round']}: {r['candidate']:<34} "
            f"score {r['statistic']:9.1f} (threshold {r['threshold']:.1f})"
        )
        if r["significant"] and not r.get("explains_enough", True):
            line += (
                f"  explains {max(1 - r['cost_ratio'], 0.0):.1%} of the misfit; what "
                f"one sensor alone shows is named from {SHARE:.0%}"
            )
        elif r.get("not_judged"):
            line += "  passes, not judged: the round's strongest was too small to name"
        elif not r["significant"] and r.get("cannot_be_told_from"):
            line += f"  cannot be told from {', '.join(r['cannot_be_told_from'])}"
        elif not r["significant"] and math.isfinite(r.get("smallest_named", math.nan)):
            ((name, value),) = r["estimates"].items()
            line += (
                f"  {name} {value:+.3g}; this log names only "
                f"|{name}| > {r['smallest_named']:.3g}"
            )
        typer.echo(line)
