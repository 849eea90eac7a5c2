"""Figures and the summary table of one rocket flight's identification."""

import pathlib

import numpy as np


def summary(problem, result, prediction, team, log_apogee, seconds, band=None) -> dict:
    """The flight's numbers: apogees (m AGL, barometric), errors (%), the predicted
    apogee's standard error and 95% half-width (m; with `band`, an
    [`ApogeeBand`][]: total, of the fit's estimates alone, each held parameter's
    term), altitude RMS (m and % of apogee), thrust scale, fit time (s)."""
    rocket = problem.rocket

    def pct(v):
        return None if v is None else 100.0 * (v - log_apogee) / log_apogee

    thrust, thrust_sd = result.estimate("thrust_scale")
    return {
        "flight": rocket.name,
        "outputs": list(result.outputs),
        "apogee_logged_m": log_apogee,
        "apogee_recorded_m": rocket.recorded_apogee,
        "apogee_reconstructed_m": result.apogee,
        "reconstructed_error_pct": pct(result.apogee),
        "apogee_predicted_m": prediction.apogee,
        "prediction_outputs": list(prediction.outputs),
        "predicted_error_pct": pct(prediction.apogee),
        "prediction_uses_log_to_s": float(
            prediction.record.t[np.flatnonzero(prediction.record.inputs[:, 1])[-1]]
        ),
        "apogee_predicted_stderr_m": None if band is None else band.stderr,
        "apogee_predicted_half_width_m": None if band is None else band.half_width,
        "apogee_predicted_stderr_fit_m": None if band is None else band.stderr_fit,
        "apogee_predicted_held": None
        if band is None
        else {k: {"sigma": s, "stderr_m": c} for k, (s, c) in band.held.items()},
        "logged_inside_predicted_95": None
        if band is None or not np.isfinite(band.stderr)
        else bool(abs(prediction.apogee - log_apogee) <= band.half_width),
        "apogee_team_preflight_m": rocket.preflight_apogee,
        "team_preflight_error_pct": pct(rocket.preflight_apogee),
        "apogee_resimulated_team_cd_m": team.apogee,
        "altitude_rms_m": result.rms(),
        "altitude_rms_pct_of_apogee": 100.0 * result.rms() / log_apogee,
        "thrust_scale": thrust,
        "thrust_scale_stderr": thrust_sd,
        "converged": bool(result.fit.converged),
        "not_converged_reason": None
        if result.fit.converged
        else str(getattr(result.fit, "reason", "")),
        "fit_seconds": seconds,
    }


def team_curve(table, grid, top: float) -> tuple[np.ndarray, np.ndarray]:
    """The team's `(mach, cd)` table as drawn beside the fit: its rows and the
    figure's Mach grid within the table's range, Mach 0.05 to `top`, the CD
    interpolated between rows (a table of two rows, Mach 0 and 1, has none within
    a flight's Mach range yet a curve across it)."""
    tm, tc = table
    x = np.union1d(tm, grid)
    x = x[(x >= max(tm[0], 0.05)) & (x <= min(tm[-1], top))]
    return x, np.interp(x, tm, tc)


def figures(problem, result, prediction, team, ee, out) -> list[pathlib.Path]:
    """Write `altitude.png`, `acceleration.png`, `drag.png` and `apogee.png` to
    `out`; return their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rec = result.record
    name = problem.rocket.name
    paths = []
    y = result.fit.outputs[0]

    has = rec.inputs[:, 1] > 0
    fig, ax = plt.subplots(
        2, 1, figsize=(8, 6.5), sharex=True, gridspec_kw={"height_ratios": [3, 1.3]}
    )
    ax[0].plot(
        rec.t[has],
        rec.measured[has, 0],
        ".",
        ms=2,
        color="0.5",
        label="log (barometric)",
    )
    ax[0].plot(result.t, result.baro, "C0", label="fit: barometer model")
    ax[0].plot(
        result.t, result.states[:, 2], "C2--", lw=1, label="fit: geometric height"
    )
    ax[0].set_ylabel("altitude above pad (m)")
    ax[0].set_title(f"{name}: ascent, log and fit")
    ax[0].legend()
    ax[1].plot(rec.t[has], rec.measured[has, 0] - y[has, 0], ".", ms=2)
    ax[1].set_ylabel("residual (m)")
    ax[1].set_xlabel("time since liftoff (s)")
    fig.tight_layout()
    paths.append(out / "altitude.png")
    fig.savefig(paths[-1], dpi=90)
    plt.close(fig)

    fig, ax = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    speed = np.linalg.norm(result.states[:, 3:], axis=1)
    ax[0].plot(result.t, speed, "C0", label="speed")
    ax[0].plot(result.t, result.states[:, 5], "C1--", label="vertical velocity")
    ax[0].set_ylabel("fitted velocity (m/s)")
    ax[0].legend()
    ax[0].set_title(f"{name}: fitted velocity and axial acceleration")
    if "accel" in result.outputs:
        h2 = rec.inputs[:, 2] > 0
        ax[1].plot(
            rec.t[h2],
            rec.measured[h2, 1],
            ".",
            ms=2,
            color="0.5",
            label="log (accelerometer)",
        )
    ax[1].plot(result.t, result.accel, "C0", label="fit: axial specific force")
    ax[1].set_ylabel("specific force (m/s²)")
    ax[1].set_xlabel("time since liftoff (s)")
    ax[1].legend()
    fig.tight_layout()
    paths.append(out / "acceleration.png")
    fig.savefig(paths[-1], dpi=90)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(8, 5))
    top = float(np.max(result.mach))
    m = np.linspace(0.05, top, 200)
    cd, sd = result.cd(m)
    _, noise = result.cd(m, structural=False)
    if result.spread is not None and result.spread.note is None:
        ax.fill_between(
            m,
            cd - 1.96 * sd,
            cd + 1.96 * sd,
            color="C0",
            alpha=0.15,
            label="95% band with the sensors' disagreement",
        )
    ax.fill_between(
        m,
        cd - 1.96 * noise,
        cd + 1.96 * noise,
        color="C0",
        alpha=0.3,
        label="95% band of the noise",
    )
    ax.plot(m, cd, "C0", label="identified (power off)")
    ax.plot(result.knots.mach, result.cd(np.array(result.knots.mach))[0], "C0o", ms=4)
    rocket = problem.rocket
    if rocket.team_drag_off is not None:
        x, y = team_curve(rocket.team_drag_off, m, max(top, 0.3) * 1.1)
        ax.plot(x, y, "k--", label="team, power off")
    if ee[0].size:
        ax.plot(
            ee[0],
            ee[1],
            ".",
            ms=1.5,
            color="C3",
            alpha=0.5,
            label="equation error (accelerometer)",
        )
    lo = np.nanpercentile(cd - 1.96 * sd, 5)
    hi = np.nanpercentile(cd + 1.96 * sd, 95)
    ax.set_ylim(max(0.0, min(lo, np.min(cd)) - 0.05), max(hi, np.max(cd)) + 0.1)
    ax.set_xlabel("Mach number")
    ax.set_ylabel("drag coefficient CD (-)")
    ax.set_title(f"{name}: CD(Mach) from the flight")
    ax.legend()
    fig.tight_layout()
    paths.append(out / "drag.png")
    fig.savefig(paths[-1], dpi=90)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(8, 5))
    ax.plot(rec.t[has], rec.measured[has, 0], ".", ms=2, color="0.5", label="log")
    ax.plot(result.t, result.baro, "C0", label=f"fit ({result.apogee:.0f} m)")
    cut = prediction.record.t[np.flatnonzero(prediction.record.inputs[:, 1])[-1]]
    ax.plot(
        prediction.t,
        prediction.baro,
        "C1",
        label=f"predicted from log to {cut:.1f} s ({prediction.apogee:.0f} m)",
    )
    ax.axvline(cut, color="C1", lw=0.8, ls=":")
    ax.plot(
        team.t,
        team.baro,
        "k--",
        label=f"team CD, catalogue thrust ({team.apogee:.0f} m)",
    )
    ax.set_xlabel("time since liftoff (s)")
    ax.set_ylabel("barometric altitude above pad (m)")
    ax.set_title(f"{name}: apogee reconstructed, predicted, re-simulated")
    ax.legend()
    fig.tight_layout()
    paths.append(out / "apogee.png")
    fig.savefig(paths[-1], dpi=90)
    plt.close(fig)
    return paths
