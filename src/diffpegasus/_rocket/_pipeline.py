"""One rocket flight end to end: fit, predict, re-simulate, check, report."""

import json
import os
import pathlib
import shutil
import tempfile
import time

import numpy as np

from .._errors import LogError
from ._apogee import apogee_band
from ._checks import equation_error_drag, resimulate
from ._data import logged_apogee
from ._identify import (
    accel_covers_ascent,
    altitude_only,
    ascent_end,
    fit_rocket,
    prepare,
)


PREDICTION_HORIZON = 2.0  # s after burnout: what an air-brake controller has


def burnout_time(log, problem, result) -> float:
    """s since liftoff: the log's burnout event, else the fitted motor's end."""
    if "burnout" in log.events:
        return float(log.events["burnout"].t)
    t0 = result.estimate("motor_time")[0]
    return t0 + problem.rocket.motor.burn_time * result.estimate("burn_scale")[0]


def predict(problem, until: float):
    """The fit an air-brake controller could make at `until` (s, log time): the
    log up to then, the start curve's drag scaled by one factor with the thrust
    scale and the barometer's static-pressure error; its `apogee` is the
    prediction."""
    # a few seconds of log cannot tell the barometer's lag or the day's
    # temperature from the drag: the prediction holds them at their start values.
    # The static-pressure error follows the dynamic pressure from the first second
    # and is estimated (held at zero it went into the thrust and drag split: NDRT
    # 2020 -8.4% instead of -3.1%; the largest miss of the six real flights 8.4% ->
    # 4.0%, the mean 2.5% -> 1.7%, measured before Camoes's air brakes were
    # modelled). An accelerometer that stops after the boost
    # is calibrated against the barometer over the whole ascent; a few seconds
    # cannot tell its scale from the drag, so the prediction reads the barometer
    # alone there
    short = problem
    if "accel" in problem.outputs and not accel_covers_ascent(
        problem.record, end=ascent_end(problem)
    ):
        short = altitude_only(problem)
    # multiple shooting only: a few seconds of log leave the thrust, drag and
    # static-error split weakly determined, and single shooting from there found
    # lower det(R) on them that extrapolated far worse (Prometheus +7.1% for
    # -4.0%, Andromeda -19.7% for +1.2%)
    return fit_rocket(
        short,
        free=("static_error",),
        until=until,
        drag="scale",
        hold_temperature=True,
        single=False,
        throw=False,
    )


def run_flight(
    rocket, log, out=None, *, free=None, spread=True, descent=False, gnss=False
) -> dict:
    """Fit the ascent, predict the apogee from the log up to two seconds after
    burnout with its band ([`apogee_band`][]), re-simulate with the team's drag curve, and (with `out`) write the
    figures and `summary.json` there. `spread`: carry the disagreement between
    the log's sensors in CD's band (see [`fit_rocket`][]; `False`: the noise's
    band alone). `descent`: fit the record through the descent under parachutes
    too (see [`prepare`][]; the prediction reads the ascent as without), each
    stage's drag area in the summary's `descent` rows and, with `out`,
    `descent.png`. `gnss`: the log's GNSS position among the outputs (see
    [`prepare`][]).

    **Returns:** the summary (see [`summary`][]) with `cd_table` rows (Mach, CD,
    standard error with the sensors' spread and of the noise alone, team CD) and,
    with two sensors, `cd_structural` (the spread's Birge ratio and `tau` at the
    knots) added.
    """
    from ._identify import default_free
    from ._report import summary

    t0 = time.perf_counter()
    problem = prepare(rocket, log, descent=descent, gnss=gnss)
    if free is None:
        free = default_free(problem)
    free = tuple(free)
    result = fit_rocket(problem, free=free, throw=False, spread=spread)
    seconds = time.perf_counter() - t0
    cut = burnout_time(log, problem, result) + PREDICTION_HORIZON
    prediction = predict(prepare(rocket, log) if descent else problem, cut)
    band = apogee_band(prediction)
    team = resimulate(problem, result) if rocket.team_drag_off is not None else result
    log_apogee = logged_apogee(log)
    row = summary(problem, result, prediction, team, log_apogee, seconds, band)
    mach = np.array(problem.flight.knots.mach)
    cd, sd = result.cd(mach)
    _, noise = result.cd(mach, structural=False)
    team_cd = (
        np.interp(mach, *rocket.team_drag_off)
        if rocket.team_drag_off is not None
        else np.full(len(mach), np.nan)
    )
    row["cd_table"] = [
        {
            "mach": float(m),
            "cd": float(c),
            "stderr": float(s),
            "stderr_noise": float(n),
            "team_cd": float(tc),
        }
        for m, c, s, n, tc in zip(mach, cd, sd, noise, team_cd, strict=True)
    ]
    # the sensors' disagreement the band carries (none with one sensor)
    if result.spread is not None:
        row["cd_structural"] = {
            "birge": None if result.spread.note else result.spread.birge,
            "tau_at_knots": result.spread.tau.tolist(),
            "converged": None
            if result.spread.converged is None
            else [bool(c) for c in result.spread.converged],
            "note": result.spread.note,
        }
    model = result.fit.model
    row["estimates"] = {
        k: list(result.estimate(k))
        for k, est in zip(model.parameters, model.free, strict=True)
        if est and k not in problem.flight.knots.names and k != "cd_scale"
    }
    # the fits the fit chose from: det(R) of each one's own fit and of its
    # parameters flown from the pad (what they are compared on)
    row["tries"] = {
        label: {"det_r": own, "det_r_flown": flown, "converged": ok}
        for label, (own, flown, ok) in result.tries.items()
    }
    if descent:
        from ._descent_report import descent_table

        row["descent"] = descent_table(problem, result)
    if out is not None:
        _write_outputs(problem, result, prediction, team, row, descent, out)
    return row


# every file `rocket fit --out` writes
OUTPUTS = (
    "summary.json",
    "altitude.png",
    "acceleration.png",
    "drag.png",
    "apogee.png",
    "descent.png",
)


def _write_outputs(problem, result, prediction, team, row, descent, out) -> None:
    """The figures and summary.json in `out`, complete or not at all: written into
    a folder beside it and moved in only once every file is written (a figure that
    fails leaves `out` as it was). A fit that did not converge gets its
    summary.json alone: its curves may not be finite, and no figure shows them."""
    from ._report import figures

    out = pathlib.Path(out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        stage = pathlib.Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    except OSError as e:
        raise LogError(
            f"{out}: cannot write the results there ({e.strerror})"
        ) from None
    try:
        if row.get("converged", True):
            if descent:
                from ._descent_report import descent_figure

                descent_figure(problem, result, stage / "descent.png")
            ee = equation_error_drag(result)
            figures(problem, result, prediction, team, ee, stage)
        (stage / "summary.json").write_text(json.dumps(row, indent=1, default=float))
        out.mkdir(exist_ok=True)
        # an earlier run's figures this run does not write would sit beside its
        # summary as if they were its own
        for name in OUTPUTS:
            if not (stage / name).exists():
                (out / name).unlink(missing_ok=True)
        for f in sorted(stage.iterdir()):
            os.replace(f, out / f.name)
    except OSError as e:
        raise LogError(
            f"{out}: cannot write the results there ({e.strerror})"
        ) from None
    finally:
        shutil.rmtree(stage, ignore_errors=True)
