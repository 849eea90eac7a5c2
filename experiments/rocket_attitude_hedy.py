"""Hedy's attitude fit with its gyros: the normal-force slope and pitch damping
scales (1 = Barrowman's from the rocket file's geometry, its free-form fins by
strips) with their 95% bands, on the one shipped real flight with raw 3-axis gyros.

The shipped rocket.toml gives no `motor_center_of_mass_m` (the attitude needs it):
this script derives it, and the motor's lateral inertia, from the file's own
liquid-motor description (tank positions in the motor frame from the nozzle, the
nozzle's position, the mass flows times the burn time: ethanol, LOX and the two
nitrogen tanks as point masses; the tanks' own lengths ignored) and flies a copy of
the file with them in a temporary folder. The rocket's moment of inertia without
motor (`I11_kgm2`) and its centre of mass are the file's.

Run: `nice python experiments/rocket_attitude_hedy.py FOLDER OUT.json`
(FOLDER the flight's folder with rocket.toml, motor/, drag/, logs/). Minutes to an
hour: the attitude's fit with a 34 s ascent at 100 Hz (1328 s at a load of 12 to
16 on 2 cores). `... FOLDER --gyros` prints instead what the raw gyros hold besides
the weathercocking: each lateral gyro's sample-to-sample noise and its
least-squares slope on the roll rate (a roll axis misaligned with the gyros'),
no fit. `... FOLDER OUT.json --derolled` fits with the lateral rate from the two
lateral gyros less their least-squares part proportional to the roll rate (slopes
from the log's own ascent, liftoff to apogee): what the misalignment alone costs.
"""

import json
import pathlib
import sys
import tempfile
import time
import tomllib

import numpy as np


def motor_mass_properties(doc):
    """`(centre of mass m in the rocket's coordinates, lateral inertia kg m^2 about
    it)` of Hedy's loaded liquid motor from its [motor] description."""
    mo = doc["motor"]
    burn = mo["burn_time_s"]
    tanks = mo["tank_positions_motor_frame_m"]
    mass = {
        "ethanol": mo["ethanol_mass_flow_kg_s"] * burn,
        "lox": mo["lox_mass_flow_kg_s"] * burn,
        "n2_for_ethanol": mo["nitrogen_mass_flow_kg_s"] * burn,
        "n2_for_lox": mo["nitrogen_mass_flow_kg_s"] * burn,
    }
    m = np.array([mass[k] for k in tanks])
    x = np.array([tanks[k] for k in tanks])
    cg = float(np.sum(m * x) / np.sum(m))
    inertia = float(np.sum(m * (x - cg) ** 2))
    return mo["nozzle_position_in_rocket_m"] + cg, inertia, float(np.sum(m))


def flight_copy(folder, tmp):
    """A copy of `folder`'s rocket.toml with the motor's mass properties, the data
    folders linked."""
    text = (folder / "rocket.toml").read_text()
    doc = tomllib.loads(text)
    cg, inertia, mass = motor_mass_properties(doc)
    line = f"motor_center_of_mass_m = {cg:.4f}\nmotor_inertia_kgm2 = {inertia:.4f}\n"
    text = text.replace("[geometry]\n", "[geometry]\n" + line, 1)
    for sub in ("motor", "drag", "logs", "weather"):
        if (folder / sub).exists():
            (tmp / sub).symlink_to((folder / sub).resolve())
    (tmp / "rocket.toml").write_text(text)
    return tmp / "rocket.toml", {
        "motor_cg_m": cg,
        "motor_inertia_kgm2": inertia,
        "propellant_kg": mass,
    }


def gyros(folder):
    """Hedy's raw gyros (imu.csv, deg/s; Y the roll axis): per phase, each lateral
    gyro's noise (`std(diff) / sqrt 2`, rad/s) and its slope on the roll rate."""
    a = np.genfromtxt(
        folder / "logs" / "imu.csv",
        delimiter=",",
        names=True,
        dtype=None,
        encoding=None,
    )
    t = a["ts"]
    g = {k: np.radians(a[k]) for k in ("Gx", "Gy", "Gz")}
    out = {}
    for lo, hi in ((-0.7, -0.1), (0.5, 8.0), (8.0, 20.0), (20.0, 33.0), (0.0, 33.0)):
        m = (t >= lo) & (t < hi)
        row = {"roll_mean_abs_rad_s": float(np.mean(np.abs(g["Gy"][m])))}
        for k in ("Gx", "Gz"):
            row[f"{k}_noise_rad_s"] = float(np.std(np.diff(g[k][m])) / np.sqrt(2))
            row[f"{k}_per_roll"] = float(np.polyfit(g["Gy"][m], g[k][m], 1)[0])
        row["lateral_mean_rad_s"] = float(np.mean(np.hypot(g["Gx"][m], g["Gz"][m])))
        out[f"{lo:g} to {hi:g} s"] = row
    print(json.dumps(out, indent=1))


def derolled(log):
    """`log` with a `gyro_lateral` channel (which the fit reads first): the lateral
    gyros less their slope on the roll (y) gyro over the ascent, in quadrature."""
    import dataclasses

    ch = log.channels
    gx, gy, gz = (ch[f"gyro_{a}"] for a in "xyz")
    m = (gx.t >= 0) & (gx.t <= log.events["apogee"].t)
    kx = np.polyfit(gy.values[m], gx.values[m], 1)[0]
    kz = np.polyfit(gy.values[m], gz.values[m], 1)[0]
    lateral = np.hypot(gx.values - kx * gy.values, gz.values - kz * gy.values)
    new = dict(ch)
    new["gyro_lateral"] = dataclasses.replace(
        gx, values=lateral, source=f"gyro_x, gyro_z less {kx:.4f}, {kz:.4f} x gyro_y"
    )
    return dataclasses.replace(log, channels=new), (float(kx), float(kz))


def main():
    if sys.argv[2:] == ["--gyros"]:
        return gyros(pathlib.Path(sys.argv[1]))
    import diffpegasus.rocket as dr
    from diffpegasus._log._rocketlogs import read_rocket_log
    from diffpegasus._rocket._identify import default_free

    folder, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
    with tempfile.TemporaryDirectory() as tmp:
        toml, result = flight_copy(folder, pathlib.Path(tmp))
        rocket = dr.read_rocket(toml, attitude=True)
        frame = rocket.airframe
        result["cn_alpha_barrowman"] = {
            str(m): float(np.sum(frame.cn_alpha(m))) for m in (0.0, 0.6, 0.8)
        }
        result["cp_barrowman_m"] = {
            str(m): frame.center_of_pressure(m) for m in (0.0, 0.6, 0.8)
        }
        log = read_rocket_log(toml)
        if "--derolled" in sys.argv[3:]:
            log, result["gyro_per_roll_removed"] = derolled(log)
        problem = dr.prepare(rocket, log)
        result["outputs"] = list(problem.outputs)
        free = default_free(problem)
        result["free"] = list(free)
        print(json.dumps(result), flush=True)
        out.write_text(json.dumps(result, indent=1))
        t0 = time.perf_counter()
        r = dr.fit_rocket(problem, free=free, throw=False)
    result["seconds"] = time.perf_counter() - t0
    result["converged"] = bool(r.fit.converged)
    result["iterations"] = int(r.fit.iterations)
    for name in free:
        v, s = r.estimate(name)
        result[name] = [v, 1.96 * s]
    if "gyro" in problem.outputs:
        has = problem.record.inputs[:, 3] > 0
        e = problem.record.measured[has, 2] - r.fit.outputs[0][has, 2]
        result["gyro_rms_rad_s"] = float(np.sqrt(np.mean(e**2)))
        result["gyro_mean_abs_rad_s"] = float(
            np.mean(np.abs(problem.record.measured[has, 2]))
        )
    out.write_text(json.dumps(result, indent=1))
    print(json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
