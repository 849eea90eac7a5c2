"""What a fit says about a rocket's descent under parachutes: each stage's drag area
beside the rocket file's and the fall rates logged and fitted, and the figure.
(The descent's record and start values are [`descent_record`][] and
[`start_drag_areas`][], below the fit.)"""

import pathlib

import numpy as np

from ._descent import fall_rates
from ._identify import _flown, _observed


def descent_table(problem, result) -> list[dict]:
    """One row per stage: `stage`, `deploy_s` (its event), `cds_m2` (the drag
    area's magnitude, which the model uses) and its standard error (the fit's),
    `cds_rocket_file_m2` (or `None`), `open_s` (the canopy full this long after
    the event) and its standard error (0: held), `open_rocket_file_s` (`lag_s`,
    or `None`), `open_cds_correlation` (the fit's, `None` with the opening
    held), `fall_rate_log_m_s` (the barometer's, [`fall_rates`][]) and
    `fall_rate_model_m_s` (the fitted model's over the same seconds)."""
    descent = problem.flight.descent
    t, baro = descent_trajectory(problem, result)
    rec = problem.record
    has = rec.inputs[:, 1] > 0
    log_rates = fall_rates(rec.t, rec.measured[:, 0], has, descent.deploy)
    model_rates = fall_rates(t, baro, has, descent.deploy)
    rows = []
    for k, name in enumerate(descent.names):
        value, stderr = result.estimate(name)
        given = (
            problem.rocket.parachutes[k][0]
            if k < len(problem.rocket.parachutes)
            else None
        )
        opening, open_se = result.estimate(descent.openings[k])
        lags = problem.rocket.parachute_lags
        rows.append(
            {
                "stage": name.removeprefix("cds_"),
                "deploy_s": float(descent.deploy[k]),
                "cds_m2": abs(float(value)),
                "cds_stderr_m2": float(stderr),
                "cds_rocket_file_m2": given,
                "open_s": float(opening),
                "open_stderr_s": float(open_se),
                "open_rocket_file_s": lags[k] if k < len(lags) else None,
                "open_cds_correlation": _correlation(result, name, descent, k),
                "fall_rate_log_m_s": log_rates[k],
                "fall_rate_model_m_s": model_rates[k],
            }
        )
    return rows


def _correlation(result, name, descent, k):
    """The fit's correlation of stage `k`'s opening time with its drag area
    (`None` with the opening held)."""
    names = result.fit.model.parameters
    i, j = names.index(name), names.index(descent.openings[k])
    if not result.fit.free[j]:
        return None
    return float(result.fit.correlation[i, j])


def descent_trajectory(problem, result):
    """`(t (samples,) s, barometric altitude (samples,) m)`: the fitted model
    flown from the pad over the whole record (through the descent)."""
    model, params = result.fit.model, result.fit.params
    t, x, inputs = _flown(model, params, problem.record, extra=0.0)
    ys = np.asarray(_observed(problem.flight, t, x, inputs, params, model.parameters))
    n = len(problem.record.t)
    return t[:n], ys[:n, 0]


def descent_figure(problem, result, path) -> pathlib.Path:
    """A PNG at `path`: the barometric altitude logged and fitted through the
    descent (m above the pad against s), each deployment marked, and the residual
    below."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, model = descent_trajectory(problem, result)
    rec = problem.record
    has = rec.inputs[:, 1] > 0
    fig, (ax, res) = plt.subplots(
        2, 1, figsize=(8, 6), sharex=True, gridspec_kw={"height_ratios": [3, 1]}
    )
    ax.plot(rec.t[has], rec.measured[has, 0], ".", ms=2, label="log (barometer)")
    ax.plot(t, model, "-", lw=1.2, label="model")
    for k, row in enumerate(descent_table(problem, result)):
        when, full = row["deploy_s"], row["deploy_s"] + row["open_s"]
        opening = (
            f"{row['open_s']:.2f} +/- {row['open_stderr_s']:.2g} s"
            if row["open_stderr_s"] > 0
            else f"{row['open_s']:.2f} s (held)"
        )
        label = (
            f"{row['stage']} at {when:.1f} s, full {opening} later: "
            f"CdS {row['cds_m2']:.4g} +/- {row['cds_stderr_m2']:.2g} m$^2$"
        )
        for a in (ax, res):
            a.axvline(when, color=f"C{k + 2}", ls="--", lw=0.8)
            if full != when:
                a.axvline(full, color=f"C{k + 2}", ls=":", lw=0.8)
        ax.plot([], [], color=f"C{k + 2}", ls="--", lw=0.8, label=label)
    ax.set_ylabel("altitude above the pad (m)")
    ax.legend(loc="upper right", fontsize=8)
    res.plot(rec.t[has], rec.measured[has, 0] - model[has], ".", ms=2)
    res.set_ylabel("log - model (m)")
    res.set_xlabel("time since liftoff (s)")
    fig.tight_layout()
    path = pathlib.Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
