"""Real flights the project had not fitted, run as a user would: RocketPy's Halcyon
(Aerospace Team Graz, EuRoC 2023), Juno III (Projeto Jupiter, Spaceport America Cup
2023), Lince (UC3M, EuRoC 2023) and Bella Lui (EPFL, 2020), each a folder built
from RocketPy's public flight data (MIT) and notebook: `rocket.toml` (each value
with its notebook cell), `logs/` (byte copies), `motor/`, `drag/`.

Run (this repository's src on PYTHONPATH):

    python experiments/rocket_other_teams_cli.py FOLDER ... --out DIR [--reuse] [--before DIR]

For each FOLDER it calls `python -m diffpegasus rocket fit FOLDER/rocket.toml --out
DIR/NAME` and `python -m diffpegasus rocket diagnose FOLDER/rocket.toml --json`,
timing each (`--reuse` keeps a run whose output exists), reads the log again, and
writes experiments/results/rocket_other_teams_cli.json: the events; the
apogee logged (the barometer's highest before its first fall faster than free fall,
as `summary.json`'s) and the flight card's; the apogees reconstructed and predicted
(from the log to 2 s after burnout) against both, in %; the altitude RMS over the
ascent in % of the logged apogee; how many of the team's CD points at the fit's
knots lie inside the 95% band (CD +/- 1.96 standard errors); diagnose's findings.
"""

import argparse
import json
import pathlib
import subprocess
import sys
import time

import numpy as np


HERE = pathlib.Path(__file__).resolve().parent
RESULT = HERE / "results" / "rocket_other_teams_cli.json"


def _run(args, log_path):
    t0 = time.perf_counter()
    p = subprocess.run(
        [sys.executable, "-m", "diffpegasus", "rocket", *args],
        capture_output=True,
        text=True,
    )
    seconds = time.perf_counter() - t0
    log_path.write_text(p.stdout + p.stderr)
    return p.returncode, p.stdout, p.stderr, seconds


def _pct(v, ref):
    return None if v is None or ref is None else 100.0 * (v - ref) / ref


def flight(folder: pathlib.Path, out: pathlib.Path, reuse: bool) -> dict:
    import diffpegasus as dp
    from diffpegasus._rocket._data import logged_apogee

    toml = folder / "rocket.toml"
    name = folder.name
    row: dict = {"flight": name}
    try:
        log = dp.read_rocket_log(toml)
    except Exception as e:  # the reader's one line is the result
        row["read"] = f"refused: {e}"
        return row
    row["read"] = "ok"
    row["channels"] = sorted(log.channels)
    row["messages"] = [m.replace(f"{folder.parent}/", "") for m in log.messages]
    row["events"] = {
        k: {"t_s": e.t, "value": None if e.value != e.value else e.value}
        for k, e in log.events.items()
    }
    logged = logged_apogee(log)
    row["apogee_logged_m"] = logged
    fit_dir = out / name
    if not (reuse and (fit_dir / "summary.json").exists()):
        rc, so, se, s = _run(
            ["fit", str(toml), "--out", str(fit_dir)], out / f"{name}_fit.txt"
        )
        row["fit_wall_s"] = s
        if rc:
            last = (se or so).strip().splitlines()[-1]
            row["fit"] = f"failed: {last.replace(f'{folder.parent}/', '')}"
            return row
    else:  # reused: the wall time a timed run wrote at the end of its log
        text = (out / f"{name}_fit.txt").read_text().split()
        row["fit_wall_s"] = float(text[-2]) if "WALL" in text else None
    summary = json.loads((fit_dir / "summary.json").read_text())
    card = summary.get("apogee_recorded_m")
    rec, pred = summary["apogee_reconstructed_m"], summary["apogee_predicted_m"]
    cds = summary.get("cd_table", [])
    inside = [
        abs(k["cd"] - k["team_cd"]) <= 1.96 * k["stderr"]
        for k in cds
        if k.get("team_cd") is not None and np.isfinite(k.get("stderr", np.nan))
    ]
    row.update(
        {
            "converged": summary["converged"],
            "fit_seconds": summary["fit_seconds"],
            "apogee_card_m": card,
            "apogee_reconstructed_m": rec,
            "reconstructed_vs_logged_pct": _pct(rec, logged),
            "reconstructed_vs_card_pct": _pct(rec, card),
            "altitude_rms_m": summary["altitude_rms_m"],
            "altitude_rms_pct_of_logged_apogee": 100.0
            * summary["altitude_rms_m"]
            / logged,
            "apogee_predicted_m": pred,
            "predicted_half_width_m": summary.get("apogee_predicted_half_width_m"),
            "prediction_uses_log_to_s": summary["prediction_uses_log_to_s"],
            "predicted_vs_logged_pct": _pct(pred, logged),
            "predicted_vs_card_pct": _pct(pred, card),
            "apogee_resimulated_team_cd_m": summary.get("apogee_resimulated_team_cd_m"),
            "thrust_scale": summary.get("thrust_scale"),
            "cd_knots": [k["mach"] for k in cds],
            "team_cd_inside_band": f"{sum(inside)} of {len(inside)}",
        }
    )
    diag = out / f"{name}_diagnose.json"
    if not (reuse and diag.exists()):
        rc, so, se, s = _run(
            ["diagnose", str(toml), "--json"], out / f"{name}_diag.txt"
        )
        row["diagnose_wall_s"] = s
        if rc:
            row["diagnose"] = f"failed: {(se or so).strip().splitlines()[-1]}"
            return row
        diag.write_text(so)
    row["diagnose"] = json.loads(diag.read_text())
    return row


def before(root: pathlib.Path, folder: pathlib.Path) -> dict | None:
    """An earlier version's run of the flight: its summary's apogees (the logged
    one as that version took it), RMS and prediction, or its last line."""
    name = folder.name
    summary = root / name / "summary.json"
    if summary.exists():
        s = json.loads(summary.read_text())
        keys = (
            "apogee_logged_m",
            "apogee_reconstructed_m",
            "reconstructed_error_pct",
            "altitude_rms_m",
            "altitude_rms_pct_of_apogee",
            "apogee_predicted_m",
            "predicted_error_pct",
            "converged",
        )
        return {k: s.get(k) for k in keys}
    log = root / f"{name}_fit.txt"
    if not log.exists():
        return None
    first = log.read_text().strip().splitlines()[0]
    return {"fit": first.replace(f"{folder.parent}/", "")}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("folders", nargs="+", type=pathlib.Path)
    ap.add_argument("--out", type=pathlib.Path, required=True)
    ap.add_argument("--reuse", action="store_true")
    ap.add_argument(
        "--before",
        type=pathlib.Path,
        help="DIR/NAME of the same runs with an earlier version: kept beside",
    )
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    old = json.loads(RESULT.read_text()) if RESULT.exists() else {}
    for folder in a.folders:
        row = flight(folder, a.out, a.reuse)
        if a.before is not None:
            row["before"] = before(a.before, folder)
        for k in ("fit_wall_s", "diagnose_wall_s"):  # a reused run keeps its time
            if row.get(k) is None and old.get(row["flight"], {}).get(k) is not None:
                row[k] = old[row["flight"]][k]
        old[row["flight"]] = row
        RESULT.write_text(json.dumps(old, indent=1, default=float) + "\n")
        keys = (
            "read",
            "converged",
            "reconstructed_vs_logged_pct",
            "reconstructed_vs_card_pct",
            "altitude_rms_pct_of_logged_apogee",
            "predicted_vs_logged_pct",
            "team_cd_inside_band",
        )
        print(row["flight"], {k: row.get(k) for k in keys})


if __name__ == "__main__":
    main()
