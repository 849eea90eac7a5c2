"""Real flights the project had not seen (RocketPy's Astra, Erebus 11 and Genesis),
each built as a user would from the documentation alone: a folder with `logs/`,
`motor/`, `drag/` and a `rocket.toml`. Per flight: the read (its messages), the
fit (converged or not), the apogee reconstructed and predicted from the log up to
2 s after burnout against the log's highest altitude, the altitude RMS over the
ascent, the team's CD at the knots inside the 95 % band, what `diagnose` names,
and the wall time.

`python experiments/rocket_other_teams.py FOLDER [FLIGHT ...] [--out FILE]`:
FOLDER holds one folder per flight (default flights: astra, erebus11, genesis);
the JSON goes to `--out` (default
experiments/results/rocket_other_teams.json). Minutes per flight.
`rocket_other_teams_before.json` is the same run on the code before
the readers' and the knots' fixes (Erebus 11's log was refused there).
"""

import json
import pathlib
import sys
import time


FLIGHTS = ("astra", "erebus11", "genesis")
OUT = pathlib.Path(__file__).resolve().parent / "results" / "rocket_other_teams.json"


def one(folder: pathlib.Path) -> dict:
    """The measures of one flight's folder."""
    import numpy as np

    import diffpegasus as dp
    import diffpegasus.rocket as dr
    from diffpegasus._errors import LogError

    toml = folder / "rocket.toml"
    row: dict = {"flight": folder.name}
    t0 = time.perf_counter()
    try:
        log = dp.read_rocket_log(toml)
    except LogError as err:
        return {**row, "read": False, "read_error": str(err)}
    row["read"] = True
    row["read_messages"] = list(log.messages)
    row["channels"] = sorted(log.channels) if hasattr(log, "channels") else []
    row["events"] = {k: [float(e.t), float(e.value)] for k, e in log.events.items()}
    rocket = dr.read_rocket(toml)
    s = dr.run_flight(rocket, log, out=None)
    row["fit_wall_s"] = time.perf_counter() - t0
    keep = (
        "apogee_logged_m",
        "apogee_recorded_m",
        "apogee_reconstructed_m",
        "reconstructed_error_pct",
        "apogee_predicted_m",
        "apogee_predicted_half_width_m",
        "predicted_error_pct",
        "logged_inside_predicted_95",
        "prediction_uses_log_to_s",
        "altitude_rms_m",
        "altitude_rms_pct_of_apogee",
        "apogee_resimulated_team_cd_m",
        "converged",
        "not_converged_reason",
        "outputs",
        "estimates",
        "tries",
    )
    row.update({k: s[k] for k in keep if k in s})
    cd = s["cd_table"]
    inside = [
        abs(r["cd"] - r["team_cd"]) <= 1.96 * r["stderr"]
        for r in cd
        if np.isfinite(r["team_cd"])
    ]
    row["cd_table"] = cd
    row["team_cd_at_knots_inside_band"] = f"{sum(inside)} of {len(inside)}"
    t1 = time.perf_counter()
    named, tests, _ = dr.diagnose(dr.prepare(rocket, log))
    row["diagnose_named"] = [str(n) for n in named]
    row["diagnose_wall_s"] = time.perf_counter() - t1
    row["diagnose_significant"] = [
        r["candidate"] for r in tests if r.get("significant")
    ]
    return row


def main():
    args = sys.argv[1:]
    out = OUT
    if "--out" in args:
        i = args.index("--out")
        out = pathlib.Path(args[i + 1])
        del args[i : i + 2]
    root = pathlib.Path(args[0])
    flights = args[1:] or FLIGHTS
    rows = json.loads(out.read_text()) if out.exists() else {}
    for name in flights:
        row = one(root / name)
        rows[name] = row
        out.write_text(json.dumps(rows, indent=1, default=float) + "\n")
        if not row["read"]:
            print(f"{name}: read refused: {row['read_error']}", flush=True)
            continue
        print(
            f"{name}: converged {row['converged']}; apogee logged "
            f"{row['apogee_logged_m']:.1f} m, reconstructed "
            f"{row['reconstructed_error_pct']:+.2f} %, predicted "
            f"{row['predicted_error_pct']:+.2f} % (95 % half-width "
            f"{row['apogee_predicted_half_width_m']:.0f} m); altitude RMS "
            f"{row['altitude_rms_pct_of_apogee']:.2f} % of apogee; team CD inside "
            f"the band at {row['team_cd_at_knots_inside_band']} knots; diagnose "
            f"names {row['diagnose_named'] or 'nothing'}; fit "
            f"{row['fit_wall_s']:.0f} s, diagnose {row['diagnose_wall_s']:.0f} s",
            flush=True,
        )


if __name__ == "__main__":
    main()
