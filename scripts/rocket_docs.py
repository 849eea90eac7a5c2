"""Write the rocket documentation pages: for each flight folder given, the same as
`diffpegasus rocket fit <folder>/rocket.toml --out docs/rockets/<name>` (figures and
summary.json), then docs/rockets/<name>.md and the table docs/rockets/validation.md.

Run: `python scripts/rocket_docs.py FOLDER [FOLDER ...]` (each FOLDER holding a
rocket.toml and its logs). `--page NAME` rewrites docs/rockets/NAME.md alone from
its summary.json (and attitude.json, where the attitude's fit wrote one), no fit.
"""

import json
import pathlib
import sys
import time


ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs" / "rockets"


def pct(v):
    return "-" if v is None else f"{v:+.2f} %"


def m(v):
    return "-" if v is None else f"{v:.0f}"


def band_m(row):
    """ " ± half-width" of the predicted apogee's 95% band ("" without one)."""
    w = row.get("apogee_predicted_half_width_m")
    return "" if w is None or w != w else f" ± {w:.0f}"


def page(name, row):
    lines = [
        f"# {row['flight']}",
        "",
        "Reproduce (the flight's folder from RocketPy's public flight data, MIT):",
        "",
        "```bash title=\"Not run here: needs the flight's rocket.toml and logs, "
        'and minutes per flight"',
        f"diffpegasus rocket fit {name}/rocket.toml --out docs/rockets/{name}",
        "```",
        "",
        f"Channels fitted: {', '.join(row['outputs'])}. Fit "
        f"{'converged' if row['converged'] else 'did NOT converge'} in "
        f"{row['fit_seconds']:.0f} s (this machine, cold: compilation included).",
        "",
        "| quantity | value |",
        "|---|---|",
        f"| apogee in the log (barometric, m AGL) | {m(row['apogee_logged_m'])} |",
        f"| apogee reconstructed (m) | {m(row['apogee_reconstructed_m'])} "
        f"({pct(row['reconstructed_error_pct'])}) |",
        f"| apogee predicted from the log to {row['prediction_uses_log_to_s']:.1f} s "
        f"(burnout + 2 s), 95% band (m) | {m(row['apogee_predicted_m'])}"
        f"{band_m(row)} ({pct(row['predicted_error_pct'])}) |",
        f"| team's pre-flight simulation (m) | {m(row['apogee_team_preflight_m'])} "
        f"({pct(row['team_preflight_error_pct'])}) |",
        f"| re-flown with the team's CD, catalogue thrust (m) | "
        f"{m(row['apogee_resimulated_team_cd_m'])} |",
        f"| altitude RMS over the ascent (m) | {row['altitude_rms_m']:.1f} "
        f"({row['altitude_rms_pct_of_apogee']:.2f} % of apogee) |",
        f"| thrust scale | {row['thrust_scale']:.3f} ± "
        f"{row['thrust_scale_stderr']:.3f} |",
    ]
    for k, (v, s) in row["estimates"].items():
        if k != "thrust_scale":
            lines.append(f"| {k.replace('_', ' ')} | {v:.4g} ± {s:.2g} |")
    spread = row.get("cd_structural")
    if spread is None:  # one sensor: nothing to compare
        band = "coloured-residual corrected"
    elif spread.get("note"):
        band = f"coloured-residual corrected; {spread['note']}"
    else:
        band = (
            "coloured-residual corrected, with the disagreement between the "
            "barometer and the accelerometer added; summary.json's stderr_noise is "
            "the noise's alone"
        )
    lines += [
        "",
        f"CD(Mach), power off (± is 1.96 standard errors, {band}):",
        "",
        "| Mach | CD identified | 95% band | team CD |",
        "|---|---|---|---|",
    ]
    for r in row["cd_table"]:
        lines.append(
            f"| {r['mach']:.2f} | {r['cd']:.3f} | ± {1.96 * r['stderr']:.3f}"
            f" | {r['team_cd']:.3f} |"
        )
    lines += [
        "",
        f"![altitude]({name}/altitude.png)",
        f"![acceleration]({name}/acceleration.png)",
        f"![drag]({name}/drag.png)",
        f"![apogee]({name}/apogee.png)",
        "",
    ]
    extra = DOCS / name / "attitude.json"
    if extra.exists():
        lines += attitude(json.loads(extra.read_text()))
    return "\n".join(lines)


def attitude(a):
    """The section of a flight's attitude fit with its gyros (the JSON that
    experiments/rocket_attitude_hedy.py writes)."""
    cna, cp = a["cn_alpha_barrowman"], a["cp_barrowman_m"]
    lines = [
        "## The attitude, with the gyros",
        "",
        "Reproduce (minutes to hours; writes the JSON this section is made from):",
        "",
        '```bash title="Not run here: needs the flight\'s folder"',
        "nice python experiments/rocket_attitude_hedy.py hedy "
        "docs/rockets/hedy/attitude.json",
        "```",
        "",
        "The rocket file gives no `motor_center_of_mass_m`; the script takes it, and "
        "the motor's lateral inertia, from the file's own liquid-motor description "
        "(tank positions, mass flows times burn time, as point masses): "
        f"{a['motor_cg_m']:.3f} m from the tail, {a['motor_inertia_kgm2']:.2f} "
        "kg m^2. Barrowman's normal-force slope from the file's geometry (nose, "
        "free-form fins, boat tail) is "
        + ", ".join(f"{cna[m]:.2f}" for m in cna)
        + " per rad at Mach "
        + ", ".join(m for m in cna)
        + ", its centre of pressure "
        + ", ".join(f"{cp[m]:.3f}" for m in cp)
        + " m from the tail.",
        "",
    ]
    if "cn_alpha_scale" not in a:
        lines += [f"The fit did not finish: {a.get('note', 'no result')}.", ""]
        return lines
    lines += [
        f"Channels fitted: {', '.join(a['outputs'])}. Fit "
        f"{'converged' if a['converged'] else 'did NOT converge'} in "
        f"{a['seconds']:.0f} s ({a['iterations']} iterations; cold, 2 cores "
        "shared with other jobs).",
        "",
        "| quantity | value (± 1.96 standard errors) |",
        "|---|---|",
    ]
    for k in a["free"]:
        v, b = a[k]
        lines.append(f"| {k.replace('_', ' ')} | {v:.4g} ± {b:.2g} |")
    if "gyro_rms_rad_s" in a:
        lines.append(
            f"| gyro residual RMS (rad/s) | {a['gyro_rms_rad_s']:.4f} (mean "
            f"lateral rate {a['gyro_mean_abs_rad_s']:.4f}) |"
        )
    lines += [
        "",
        "What these bands mean, and what the gyros hold besides the weathercocking: "
        "[Rocket flights](index.md#what-it-does-not-do-yet).",
        "",
    ]
    return lines


# the multiple-shooting fit alone (the table before the single-shooting try):
# reconstructed apogee error %, altitude RMS m
BEFORE = {
    "andromeda": (-0.74, 21.5),
    "camoes": (-0.22, 10.4),
    "cavour": (-0.20, 8.9),
    "ndrt_2020": (0.02, 2.7),
    "prometheus_2022": (-0.67, 5.6),
    "hedy": (-0.14, 19.3),
}
# measured by benchmarks/rocket_fit_time.py (its JSON's prometheus_2022 entry)
FIT_TIME = (
    "(17 parameters, 2906 samples, 31 iterations over the tries) takes 6.9 s, "
    "cold 43.6 s, on the 2 cores at load 0.7 to 1.2 (before the single-shooting "
    "try: 3.4 s warm, 35 s cold, at load 3 to 8)"
)
# the same with `--spread` (benchmarks/results/rocket_fit_time_spread.json)
FIT_TIME_SPREAD = "9.7 s warm, 56.6 s cold, at load 1.1"


# the drag bands' paragraph, measured by the runs that wrote the pages (their
# summary.json) and by experiments/rocket_spread_real.py before the joint-fit rule
BAND = (
    "The drag bands on the flight pages carry, besides the noise (the knots' "
    "coloured-residual standard errors), the disagreement between a log's "
    "barometer and accelerometer, the command's default ([Simulated "
    "flights](simulated.md); `--no-sensor-spread` gives the noise's alone): each "
    "sensor's own converged fit from the joint one, estimating only what it "
    "determines on its own. The drag figures draw both, and summary.json gives "
    "both standard errors (`stderr`, `stderr_noise`) and the structural term at the "
    "knots (`cd_structural`). Andromeda and Cavour log an altitude alone: nothing "
    "to compare, the noise's band. Where the two sensors agree the band is the "
    "noise's, and it widens where they do not. On Hedy, with the burn's length "
    "estimated, they agree (Birge ratio 0.01): the band is the noise's at every "
    "knot, ±0.07 to ±0.21 from Mach 0.48 to 1.05 (with the catalogue's burn it had "
    "widened at the top of the flight, where the barometer jumps transonically: "
    "±0.71 for the noise's ±0.39 at Mach 0.96, ±1.26 for ±0.34 at Mach 1.05; Birge "
    "ratio 35). On Prometheus it is the noise's from Mach 0.2 to 0.61 (±1.6 to "
    "±0.05), ±0.05 for ±0.04 at 0.71, ±0.07 for ±0.05 at 0.81, ±0.09 for ±0.05 at "
    "0.92 and ±7.2 for ±6.9 at 0.1 (Birge ratio 6.1; 22.7 with the catalogue's "
    "burn). On NDRT 2020, whose accelerometer spans only the boost (0 to 4.5 s, "
    "its offset and scale estimated, 3.9 ± 1.2 m/s^2 and 0.91 ± 0.02), the "
    "sensors disagree at every knot but the top one: 2.2 to 3.4 times the noise's "
    "(±0.17 to ±1.01 for ±0.07 to ±0.44; Birge ratio 19.7), and the team's "
    "constant 0.44 lies outside both bands from Mach 0.28 to 0.46, where the "
    "fitted curve runs from 0.08 to 0.68. On Camoes, with the burn's length "
    "estimated, both sensors' own fits converge and they disagree 2 to 3 times "
    "the noise's at Mach 0.4 to 0.8 (±1.6 for ±0.65 at Mach 0.8; Birge "
    "ratio 16); with the catalogue's burn it was ±109 and ±618 at Mach 0.8 and "
    "0.9 for the noise's ±1.1 and ±4.0 (Birge ratio 773; the accelerometer's own "
    "fit did not converge). The one linearised "
    "Gauss-Newton step that came before had added ±3.4 to ±4.6 in CD on Hedy at "
    "Mach 0.77 to 0.96 and ±0.3 to ±0.86 on Prometheus at Mach 0.4 to 0.7. The "
    "band does not enter the fit: the reconstructed apogees, altitude RMS and "
    "predictions are those of the fit without it. Each sensor's own fit adds "
    "minutes on a busy machine (the fits with it: NDRT 98 s, Prometheus 127 s, "
    "Hedy 123 s, Camoes 339 s, cold at a load of 2 to 8; not a controlled "
    "timing)."
)


# Camoes's air brakes, measured by the fits of the flight before and after the
# brakes' model (summary.json's numbers, the fits' correlation matrices and the
# fit with the day's atmosphere held, run once each)
BRAKES = (
    "Camoes flew active air brakes. The fit used to read their schedule by "
    "straight lines between rows (the file's first row `0, 0` and the next `3.8, "
    "1` opened the brakes over the boost) and held their CD at zero, so the drag "
    "knots took the brakes up as a function of Mach, which their schedule is not: "
    "the joint fit stopped unconverged at its 500-iteration budget (det(R) still "
    "falling by 6e-7 of itself per iteration; pad temperature 339 ± 39 K, lapse "
    "-25.6 ± 10.5 K/km, wind along the rail 4 ± 1480 m/s). Now the schedule is "
    "held from row to row, shaped by the team's air-brake table, and the brakes' "
    "CD is estimated. What that left was the boost. The motor's thrust file is a "
    "staircase (steps at 1.5, 2.1 and 3.0 s) burning 3.72 s; the flight "
    "computer's filtered specific force is above gravity's share along the rail by "
    "5 m/s^2 for 4.42 s, an impulse 0.96 of the file's (mass times specific force "
    "plus drag). With a thrust scale and a start time alone the fit converged at "
    "det(R) 12661 with the thrust scale at 0.89 ± 0.07, the brakes' CD at 0.18 ± "
    "0.65, and the day's temperature and lapse taking up the boost's misfit (353 ± "
    "41 K and -50 ± 23 K/km; the accelerometer's residuals 14 to 40 m/s^2 RMS over "
    "the boost against 2 to 5 on the coast). With the burn scale estimated (the "
    "burn's length over the file's; it starts where the accelerometer puts it, "
    "1.24) the fit converges at det(R) 2450 with a burn of 1.252 ± 0.001 times the "
    "file's (4.66 s), a thrust scale of 0.934 ± 0.030, the brakes' CD 0.29 ± 0.26 "
    "fully out (the team's table: 0.225) and the day at 336 ± 20 K and -38 ± 9 "
    "K/km (still no real day: the file's staircase against the smooth filtered "
    "force is left); it reconstructs the apogee to -0.16% (-0.15%) with an "
    "altitude RMS of 9.2 m (9.2 m), and its CD bands narrow where the sensors "
    "disagreed (±1.6 and ±2.3 at Mach 0.8 and 0.9 for ±109 and ±618; both "
    "sensors' own fits now converge), while the wind along the rail is left "
    "undetermined (4 ± 221 m/s; -2.8 ± 16). Started at 1 instead, the fit stopped "
    "at 1.04 (det(R) 10560). Re-flown with the team's curve, catalogue thrust and "
    "burn, the rocket reaches 2976 m (3065 m; the team's simulation with its "
    "brakes, 3003 m). The prediction to burnout + 2 s is -10.62% (-9.87% with "
    "the burn's length held; -0.74% before the brakes were modelled): it finds "
    "the burn too (1.240 ± 0.002) and a thrust scale of 0.934 ± 0.034, but 6.65 s "
    "of this log leave the drag's scale at its start (1.00 ± 0.33), and the "
    "team's curve at scale 1 with a motor delivering 0.93 of the file's impulse "
    "flies low; the same fit without the brakes' drag (2994 m, before the burn "
    "was modelled) had the missing brakes make up for the low thrust."
)
CD_SCALE_SD = (
    "0.09 on NDRT 2020, 0.17 on Prometheus, 0.26 on Cavour, 0.29 on Hedy, 0.33 on "
    "Camoes and 0.66 on Andromeda (on Prometheus, Hedy and Cavour the scale stays "
    "at its start, 1; on Hedy every estimate of the prediction stays at its start, "
    "the burn scale at the 1.04 its accelerometer gives, which moved its prediction "
    "from -0.28% with the catalogue's burn to +0.68%)"
)
BAND_WIDTHS = (
    "The half-widths, in % of the logged apogee (the prediction's miss): NDRT 2020 "
    "±3.5 (-3.1), Prometheus ±10.9 (-3.9), Cavour ±16 (-0.7), Camoes ±15.7 "
    "(-10.6), Hedy ±26.5 (+0.7), Andromeda ±43 (+1.2); almost all of it the drag "
    "scale's (the estimates' term 94 to 100% of the variance)."
)
SIMULATED = (
    "where the rocket file states RocketPy's own temperature and lapse, the "
    "logged apogee lies inside the band on 9 of 15 flights (half-widths 2.1 to "
    "2.5%, mostly the temperature's term; the estimates' term alone contains 4); "
    "the six outside are the flights planted with a barometer lag of 0.15 s (five, "
    "-3.1 to -4.7%, the prediction's drag scale 3 to 9% high) or a 7 m/s wind "
    "(one, +3.2%), which the prediction holds at zero and the band does not "
    "carry (2.7 to 3.8 standard errors off). Linearised with the fit following, "
    "Prometheus's prediction moves by 25 m per K of pad temperature and 5.4 m per "
    "K/km of lapse: the day's -8.7 K/km instead of the -6.5 held would lower it by "
    "12 m, so the lapse does not explain its -3.9%, and the temperature held (300 "
    "K) is the notebook's for another date."
)

# the predicted apogee's band, measured by experiments/rocket_apogee_band.py on the
# six flights and on RocketPy's flights (its JSON in experiments/results)
APOGEE_BAND = (
    "The predicted apogee's 95% band (the table's ±; `summary.json`'s "
    "`apogee_predicted_half_width_m`) is the prediction fit's covariance (its "
    "coloured-residual standard errors and correlations, as the drag band's) "
    "carried to the apogee through the gradient of the apogee flown from the pad "
    "(JAX, forward mode; central differences agree to 3e-8), plus the pad "
    "temperature and lapse rate the prediction holds, at 2 K (stated in the rocket "
    "file; 10 K from the standard atmosphere) and 2 K/km, each with the fit's "
    "thrust and drag following it (a consider parameter's term; refitted with the "
    "temperature moved, 15.8 m/K against the linearised 15.4 on a simulated "
    "flight). Every logged apogee lies inside its band, and it says what the "
    "seconds of log before the cut hold: the drag scale's standard error from them "
    f"is {CD_SCALE_SD}. {BAND_WIDTHS} Five of the six predictions are within 4.1% "
    "because the team's curve is held in shape and the scale starts at 1 (Camoes's "
    "-10.6% is that curve at scale 1 against a motor delivering 0.93 of its file's "
    "impulse, above); the log to burnout + "
    "2 s cannot confirm that, and the band does not pretend it does. The held "
    "atmosphere's terms: Prometheus 52 m (temperature) and 10 m (lapse), the rest "
    "3 to 33 m. On RocketPy's flights (`python experiments/rocket_apogee_band.py "
    f"FOLDER ...`), {SIMULATED}"
)


def moved(rows):
    """The flights whose fit single shooting moved, in words."""
    out = []
    for name, r in rows.items():
        if name not in BEFORE:
            continue
        e, rms = BEFORE[name]
        new = (round(r["reconstructed_error_pct"], 2), round(r["altitude_rms_m"], 1))
        if new == (e, rms):
            out.append(f"{r['flight']} unchanged")
        else:
            out.append(
                f"{r['flight']} {e:+.2f}% and {rms:.1f} m to "
                f"{new[0]:+.2f}% and {new[1]:.1f} m"
            )
    return "; ".join(out)


def main():
    rows = {}
    if sys.argv[1:2] == ["--page"]:
        for name in sys.argv[2:]:
            row = json.loads((DOCS / name / "summary.json").read_text())
            (DOCS / f"{name}.md").write_text(page(name, row))
        return
    if sys.argv[1:] == ["--table"]:  # the table from the pages already written
        for summary in sorted(DOCS.glob("*/summary.json")):
            rows[summary.parent.name] = json.loads(summary.read_text())
    for folder in map(pathlib.Path, [a for a in sys.argv[1:] if a != "--table"]):
        name = folder.name
        t0 = time.perf_counter()
        from diffpegasus._log._rocketlogs import read_rocket_log
        from diffpegasus.rocket import read_rocket, run_flight

        rocket = read_rocket(folder / "rocket.toml")
        log = read_rocket_log(folder / "rocket.toml")
        row = run_flight(rocket, log, DOCS / name)
        row["command_seconds"] = time.perf_counter() - t0
        (DOCS / f"{name}.md").write_text(page(name, row))
        rows[name] = row
        print(
            name,
            {
                k: row[k]
                for k in (
                    "apogee_logged_m",
                    "apogee_reconstructed_m",
                    "apogee_predicted_m",
                    "altitude_rms_m",
                    "fit_seconds",
                )
            },
            flush=True,
        )
    table = DOCS / "validation.json"
    old = json.loads(table.read_text()) if table.exists() else {}
    old.update(rows)
    table.write_text(json.dumps(old, indent=1, default=float))
    lines = [
        "# Rocket flights: apogee and altitude",
        "",
        "Reproduce: `python scripts/rocket_docs.py FOLDER ...` (one folder per flight, "
        "each the same as `diffpegasus rocket fit FOLDER/rocket.toml --out ...`; "
        "`--table` rebuilds this table from the pages' summary.json). Fit times are "
        "cold (tracing and compilation included) on a 2-core machine busy with "
        "other jobs (load 15 to 27 when Andromeda's and Cavour's fits ran, 2 to 8 "
        "for the other four; before the fit's "
        "single-shooting try, which compiles a second program per flight, they "
        "were 66 to 114 s at load 3 to 8). Warm (the programs compiled), "
        f"Prometheus's fit with the command's default effects (without each sensor's "
        f"own fit for the band) {FIT_TIME} "
        "(`python benchmarks/rocket_fit_time.py FOLDER`); with each sensor's own "
        f"fit for the band, as the command runs by default, {FIT_TIME_SPREAD} "
        "(`python benchmarks/rocket_fit_time.py --spread FOLDER`); measured again with "
        "the burn scale estimated and RK4's stages as one loop body (18 parameters, 8 "
        "iterations), 6.1 s warm and 29.0 s cold at load 0.7 to 1.3, Hedy's (21 "
        "parameters, 3430 samples, 43 iterations) 14.8 s warm and 34.1 s cold "
        "(`benchmarks/results/rocket_fit_time_recheck.json`).",
        "",
        "The fit is multiple shooting (a node every 2 s) from the start, then "
        "single shooting (one segment from the pad) from its best try: "
        "multiple shooting's penalty lets the node states absorb misfit, and a "
        "fit can stop there far above its noise. The tries are compared on "
        "det(R) of their parameters flown from the pad, the trajectory the "
        "pages show: a multiple-shooting fit's own det(R) comes from segments "
        "restarted at node states that take up misfit, and compared on it "
        "NDRT 2020 and Hedy had kept multiple shooting; compared flown, their "
        "reconstructed apogees move by less than 0.01 m and their bands by 1 to "
        "2% (the same optimum reached both ways); Camoes's fit, which did not "
        "converge then (see below), moved by less than 0.001 in CD and its bands "
        "by -14 to +3%, and no other flight's fit or prediction moved. Against the "
        "multiple-shooting fit alone (reconstructed apogee error, altitude "
        f"RMS): {moved(old)} (with the single-shooting try alone: Camoes -0.15% "
        "and 9.2 m, NDRT 2020 +0.02% and 2.7 m, Prometheus -0.34% and 1.9 m, Hedy "
        "-0.14% and 19.3 m; the burn's length, estimated since on these four, made "
        "the rest). "
        "Prometheus's lower optimum takes a barometer lag of -0.11 ± 0.01 s (a "
        "reading ahead of the height, which no barometer gives) and a pad "
        "temperature of 286 ± 5 K with a -5.9 K/km lapse (277 ± 4 K and -3.6 K/km "
        "before the burn's length was estimated): on an ascent the climb "
        "rate is a function of height, so a lag and a barometer error that "
        "depends on height are one signature, and only the model's atmosphere "
        "(one temperature, one lapse rate) tells them apart; here they trade "
        "against each other. Its CD now lies on the accelerometer's "
        "equation-error points, below the team's curve.",
        "",
        BRAKES,
        "",
        BAND,
        "",
        "The prediction is fitted by multiple shooting alone: on its few "
        "seconds of log single shooting from there found lower det(R) that "
        "extrapolated far worse (Prometheus +7.3% for -3.9%, Andromeda -19.7% "
        "for +1.2%). It holds the barometer's lag and the day's temperature and "
        "lapse rate at their start values (a few seconds of log cannot tell them "
        "from drag) and estimates the barometer's static-pressure error, which "
        "follows the dynamic pressure from the first second. Held at zero, that "
        "error went into the split between thrust and drag: the same code with "
        "it held predicts NDRT 2020 -8.44%, Prometheus -3.81%, Andromeda "
        "+1.19%, Camoes -0.62%, Cavour -0.68%, Hedy -0.28% (the largest miss "
        "8.4%, the mean 2.5%; with it estimated 4.0% and 1.7%, before Camoes's "
        "air brakes were modelled; the code before "
        "the spline and the Coriolis term: -6.61, -3.98, +1.07, -0.68, -0.74, "
        "-0.33). Where it misses by more than 2% that is what it misses: "
        "Prometheus's barometer reads about 270 m low at burnout (its "
        "static-pressure error is estimated 0.054 of the dynamic pressure from "
        "the 6.9 s, 0.069 in the full fit) on a day with a -8.7 K/km lapse, "
        "which the prediction holds at the standard -6.5 (with the prediction's fit "
        "following it, that lapse would lower the prediction by 12 m: below). NDRT's accelerometer "
        "stops after the boost and reads 0.87 g on the pad, so its prediction "
        "reads the barometer alone; 5.3 s of barometer tell thrust from drag "
        "weakly (its static error is estimated 0.003 ± 0.001 where the full fit "
        "finds 0.021), and the prediction moves with small changes of the model: "
        "the spline and the Coriolis term had moved it from -6.6% to -8.4% with "
        "the static error held.",
        "",
        APOGEE_BAND,
        "",
        "| flight | channels | apogee logged (m) | reconstructed | predicted at "
        "burnout + 2 s (95% band) | team pre-flight | altitude RMS (% of apogee) | fit (s) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, r in old.items():
        lines.append(
            f"| [{r['flight']}]({name}.md) | {', '.join(r['outputs'])} | "
            f"{m(r['apogee_logged_m'])} | {m(r['apogee_reconstructed_m'])} "
            f"({pct(r['reconstructed_error_pct'])}) | {m(r['apogee_predicted_m'])}"
            f"{band_m(r)} ({pct(r['predicted_error_pct'])}) | {m(r['apogee_team_preflight_m'])} "
            f"({pct(r['team_preflight_error_pct'])}) | {r['altitude_rms_m']:.1f} m "
            f"({r['altitude_rms_pct_of_apogee']:.2f} %) | {r['fit_seconds']:.0f} |"
        )
    lines.append("")
    (DOCS / "validation.md").write_text("\n".join(lines))


if __name__ == "__main__":
    main()
