"""One simulated flight written in the export layouts of flight computers the
shipped flights do not use: what the rocket-log reader must take with the column
map a user would write (or none).

The flight is the committed RocketPy flight (tests/data/rocket_sim/clean: 50 Hz
from ignition to apogee, barometric altitude and axial specific force with their
noise); pressure and temperature follow from its altitude by the standard
troposphere (independent closed form, not the package's atmosphere), and a
flight computer's vertical speed is a Savitzky-Golay derivative of the altitude.
Each writer rounds as the layout does (integer feet, integer mG, ...) and returns
the files, the column map and what the read must give.

The layouts, with where they are described (public documentation or sample
files):

- `stratologger_pf2`: PerfectFlite StratoLogger DataCap file: 13 lines of
  "Key: value", a blank line, `Data: (Time, Altitude, Velocity, Temperature (F),
  Voltage)`, rows of ", "-separated numbers at 20 Hz, altitude in integer ft,
  speed in integer ft/s, temperature in degF (a DataCap .pf2 file published in
  github.com/lalligood/RocketryAltimeter).
- `blue_raven_lr`: Featherweight Blue Raven low-rate CSV: a wall-clock `Time`
  column beside `Flight_Time_(s)`, `Baro_Press_(atm)`, `Temperature_(F)`,
  `Baro_Altitude_AGL_(feet)`, `Velocity_Up` in ft/s with no unit (its column
  names as public analysis scripts read them).
- `openlog_arduino`: an Arduino sketch's log on a SparkFun OpenLog: a banner line,
  tab-separated, CRLF, `millis` since power-on, pressure in mbar, acceleration in
  mG, the last line cut short by the power going off.
- `excel_semicolon`: a log re-saved by a spreadsheet in a European locale:
  semicolons, decimal commas, CRLF, Windows-1252 (`Höhe [m]`, `[°C]`, `[m/s²]`).
- `units_row`: a row of units under the header (`(s),(ft),(ft/s),(mbar),(mG)`),
  as FlySight's track files write it.
- `flysight_track`: FlySight's track CSV: a units row, ISO 8601 UTC times, the
  GNSS altitude `hMSL` and `velD` (down) (the format notes of
  github.com/sco1/pyflysight).
- `easymini_altos`: Altus Metrum EasyMini (AltOS CSV, barometer only: no
  acceleration column).
- `whitespace_logger`: space-separated, a model-name line and a line of setup
  numbers before the header, time in `Milliseconds` (Eagle Tree eLogger's text
  export).
- `openrocket_export`: a simulator's CSV: `#` comment lines before the header,
  the header itself after `# `, and `# Event ... occurred` lines among the data.
- `numbered_samples`: a sample number and no time column, 20 Hz.
"""

import pathlib

import numpy as np
from scipy.signal import savgol_filter


HERE = pathlib.Path(__file__).resolve().parent
SIM = HERE / "data" / "rocket_sim" / "clean"
ELEVATION = 150.0  # m, the pad's (the flight's rocket.toml)
FT = 0.3048
G0 = 9.80665
APOGEE_T = 24.0  # s, RocketPy's last row (its apogee)


def flight() -> dict[str, np.ndarray]:
    """The truth: time (s from ignition) and SI channels."""
    a = np.loadtxt(SIM / "log.csv", delimiter=",", skiprows=1)
    t, h, acc = a.T
    z = ELEVATION + h
    return {
        "t": t,
        "altitude": h,
        "accel_axial": acc,
        "velocity": savgol_filter(h, 25, 2, deriv=1, delta=float(t[1] - t[0])),
        "pressure": 101325.0 * (1 - 2.25577e-5 * z) ** 5.25588,
        "temperature": 288.15 - 0.0065 * z,
    }


def _at(f: dict, t: np.ndarray) -> dict:
    return {k: (t if k == "t" else np.interp(t, f["t"], v)) for k, v in f.items()}


def _degf(kelvin):
    return (kelvin - 273.15) * 9 / 5 + 32


def stratologger_pf2(folder: pathlib.Path, f: dict):
    g = _at(f, np.round(np.arange(0.0, APOGEE_T + 1e-9, 0.05), 2))
    top = float(np.max(g["altitude"])) / FT
    lines = [
        "PerfectFlite SL100",
        "Firmware: 1.0",
        "Software: 1.1",
        "Serial Number: 1254",
        f"Apogee: {top:.0f}' AGL",
        f"Ground Elevation: {ELEVATION / FT:.0f}' MSL",
        f"NumSamps: {len(g['t'])}",
        "Flight Number: 3",
        "Main Setting: 500' AGL",
        "Apogee Delay: 0 Seconds",
        f"Drogue At: {APOGEE_T:.2f} Seconds",
        "Main At: 0.00 Seconds",
        "Comments: ",
        "",
        "Data: (Time, Altitude, Velocity, Temperature (F), Voltage)",
    ]
    lines += [
        f"{t:.2f}, {h / FT:.0f}, {v / FT:.0f}, {_degf(k):.2f}, 9.20"
        for t, h, v, k in zip(
            g["t"], g["altitude"], g["velocity"], g["temperature"], strict=True
        )
    ]
    path = folder / "flight.pf2"
    path.write_text("\n".join(lines) + "\n")
    # nothing needed: the names are in the Data line, the units in the data
    tol = {"altitude": 0.5 * FT, "velocity": 0.5 * FT, "temperature": 0.006}
    return [path], None, tol, 0.0


def blue_raven_lr(folder, f):
    header = (
        "Year,Month,Day,Time,Flight_Time_(s),Sync,Temperature_(F),Baro_Press_(atm),"
        "Baro_Altitude_ASL_(feet),Baro_Altitude_AGL_(feet),Batt_Volts,Velocity_Up,"
        "Inertial_Altitude,Tilt_Angle_(deg),Future_Angle_(deg),Roll_Angle_(deg)"
    )
    rows = []
    for k, t in enumerate(f["t"]):
        clock = 12 * 3600 + 7 * 60 + 53.0 + t
        hh, rest = divmod(clock, 3600)
        mm, ss = divmod(rest, 60)
        h = f["altitude"][k] / FT
        rows.append(
            f"2025,6,11,{hh:02.0f}:{mm:02.0f}:{ss:05.2f},{t:.3f},{k % 256},"
            f"{_degf(f['temperature'][k]):.1f},{f['pressure'][k] / 101325:.6f},"
            f"{h + ELEVATION / FT:.1f},{h:.1f},8.12,{f['velocity'][k] / FT:.1f},"
            f"{h:.1f},2.1,2.3,15.0"
        )
    path = folder / "BlRv_SN0867 LR.csv"
    path.write_text("\n".join([header, *rows]) + "\n")
    cmap = {
        "time": "Flight_Time_(s)",
        "altitude": "Baro_Altitude_AGL_(feet)",
        "pressure": "Baro_Press_(atm)",
        "temperature": "Temperature_(F)",
        "velocity": {"column": "Velocity_Up", "unit": "ft/s", "filtered": True},
    }
    tol = {
        "altitude": 0.05 * FT,
        "velocity": 0.05 * FT,
        "pressure": 0.6e-6 * 101325,
        "temperature": 0.03,
    }
    return [path], cmap, tol, 0.0


POWER_ON = 5.123  # s between power-on and ignition, in the millis column


def openlog_arduino(folder, f):
    lines = ["LIS3DH + BMP388 logger v2", "millis\tpressure_mbar\ttemp_C\taccel_z_mg"]
    lines += [
        f"{round((t + POWER_ON) * 1000)}\t{p / 100:.2f}\t{k - 273.15:.1f}\t"
        f"{a / G0 * 1000:.0f}"
        for t, p, k, a in zip(
            f["t"], f["pressure"], f["temperature"], f["accel_axial"], strict=True
        )
    ]
    lines.append(f"{round((APOGEE_T + 0.02 + POWER_ON) * 1000)}\t1002.")  # cut short
    path = folder / "LOG00042.TXT"
    path.write_bytes(("\r\n".join(lines)).encode())
    cmap = {
        "time": {"column": "millis", "unit": "ms"},
        "pressure": "pressure_mbar",
        "temperature": {"column": "temp_C", "unit": "degC"},
        "accel_axial": {"column": "accel_z_mg", "unit": "mG", "gravity": "included"},
    }
    tol = {"pressure": 0.5, "temperature": 0.05, "accel_axial": 0.5e-3 * G0}
    return [path], cmap, tol, POWER_ON


def excel_semicolon(folder, f, encoding="cp1252"):
    lines = ["Zeit [s];Höhe [m];Druck [hPa];Beschleunigung [m/s²];Temperatur [°C]"]
    lines += [
        f"{t:.2f};{h:.2f};{p / 100:.3f};{a:.3f};{k - 273.15:.2f}".replace(".", ",")
        for t, h, p, a, k in zip(
            f["t"],
            f["altitude"],
            f["pressure"],
            f["accel_axial"],
            f["temperature"],
            strict=True,
        )
    ]
    path = folder / "flug.csv"
    path.write_bytes("\r\n".join(lines).encode(encoding) + b"\r\n")
    cmap = {
        "time": "Zeit [s]",
        "altitude": "Höhe [m]",
        "pressure": "Druck [hPa]",
        "accel_axial": {"column": "Beschleunigung [m/s²]", "gravity": "included"},
        "temperature": "Temperatur [°C]",
    }
    tol = {
        "altitude": 0.005,
        "pressure": 0.05,
        "accel_axial": 0.0005,
        "temperature": 0.005,
    }
    return [path], cmap, tol, 0.0


def units_row(folder, f):
    lines = [
        "time,altitude,velocity,pressure,acceleration",
        "(s),(ft),(ft/s),(mbar),(mG)",
    ]
    lines += [
        f"{t:.2f},{h / FT:.1f},{v / FT:.1f},{p / 100:.2f},{a / G0 * 1000:.0f}"
        for t, h, v, p, a in zip(
            f["t"],
            f["altitude"],
            f["velocity"],
            f["pressure"],
            f["accel_axial"],
            strict=True,
        )
    ]
    path = folder / "track.csv"
    path.write_text("\n".join(lines) + "\n")
    tol = {
        "altitude": 0.05 * FT,
        "velocity": 0.05 * FT,
        "pressure": 0.5,
        "accel_axial": 0.5e-3 * G0,
    }
    return [path], None, tol, 0.0


FLYSIGHT_START = 1618892453.0  # 2021-04-20T04:20:53Z, s since 1970


def _clock(s):
    """`s` seconds past 04:20 as a time of day, `04:21:05.250`, to the millisecond."""
    ms = round(s * 1000)
    return f"04:{20 + ms // 60000:02d}:{ms % 60000 / 1000:06.3f}"


def flysight_track(folder, f):
    lines = [
        "time,lat,lon,hMSL,velN,velE,velD,hAcc,vAcc,sAcc,gpsFix,numSV",
        ",(deg),(deg),(m),(m/s),(m/s),(m/s),(m),(m),(m/s),,",
    ]
    lines += [
        f"2021-04-20T{_clock(53.0 + t)}Z,33.6568828,-117.7466357,"
        f"{ELEVATION + h:.3f},0.10,0.20,{-v:.2f},2.1,3.4,0.25,3,11"
        for t, h, v in zip(f["t"], f["altitude"], f["velocity"], strict=True)
    ]
    path = folder / "TRACK.CSV"
    path.write_text("\n".join(lines) + "\n")
    cmap = {
        "time": "time",
        "altitude": "hMSL",
        "velocity": {"column": "velD", "scale": -1},
        "gnss_lat": "lat",
        "gnss_lon": "lon",
    }
    # the time's resolution is 1 ms; s since 1970 in float64 keep it
    # the altitude above sea level: the pad's 150 m is its datum; times since 1970
    # in float64 are 1e-7 s off, a speed changing 50 m/s^2 moves 5e-6 m/s in it
    tol = {"altitude": 0.0005, "velocity": 0.00501, "_datum": ELEVATION}
    return [path], cmap, tol, FLYSIGHT_START


def easymini_altos(folder, f):
    header = (
        "#version,serial,flight,call,time,clock,rssi,lqi,state,state_name,pressure,"
        "altitude,height,speed,temperature,battery_voltage,drogue_voltage,"
        "main_voltage"
    )
    rows = [
        f"6, 8221, 4,N0CALL, {t:8.2f}, {k}, 0, 0, 3, boost, {p:9.2f}, "
        f"{h + ELEVATION:8.2f}, {h:8.2f}, {v:7.2f}, {tk - 273.15:5.1f}, 3.87, "
        "3.90, 3.90"
        for k, (t, p, h, v, tk) in enumerate(
            zip(
                f["t"],
                f["pressure"],
                f["altitude"],
                f["velocity"],
                f["temperature"],
                strict=True,
            )
        )
    ]
    path = folder / "2025-05-04-serial-8221-flight-0004.csv"
    path.write_text("\n".join([header, *rows]) + "\n")
    tol = {"altitude": 0.005, "velocity": 0.005, "pressure": 0.005, "temperature": 0.05}
    return [path], None, tol, 0.0


def whitespace_logger(folder, f):
    lines = [
        "Rocket 1",
        "1 0 2 115200 0",
        "Milliseconds IsEvent EventError EventData Altitude Airspeed ServoCurrent*100",
    ]
    lines += [
        f"{round(t * 1000)} 0 0 0 {h / FT:.0f} {abs(v) / 0.44704:.0f} 0"
        for t, h, v in zip(f["t"], f["altitude"], f["velocity"], strict=True)
    ]
    path = folder / "Rocket 1.FDR"
    path.write_text("\n".join(lines) + "\n")
    cmap = {
        "time": {"column": "Milliseconds", "unit": "ms"},
        "altitude": {"column": "Altitude", "unit": "ft"},
    }
    return [path], cmap, {"altitude": 0.5 * FT}, 0.0


def openrocket_export(folder, f):
    lines = [
        "# Rocket 'sim-clean'",
        "# Simulation 'Simulation 1' (RK4, 0.02 s step)",
        "# Time (s),Altitude (m),Vertical velocity (m/s)",
        "# Event LAUNCH occurred at t=0 seconds",
        "# Event IGNITION occurred at t=0 seconds",
    ]
    for k, (t, h, v) in enumerate(
        zip(f["t"], f["altitude"], f["velocity"], strict=True)
    ):
        if k == 50:
            lines.append("# Event LAUNCHROD occurred at t=1.0 seconds")
        lines.append(f"{t:.3f},{h:.3f},{v:.3f}")
    lines.append(f"# Event APOGEE occurred at t={APOGEE_T} seconds")
    path = folder / "openrocket.csv"
    path.write_text("\n".join(lines) + "\n")
    return [path], None, {"altitude": 0.0005, "velocity": 0.0005}, 0.0


def numbered_samples(folder, f):
    g = _at(f, np.round(np.arange(0.0, APOGEE_T + 1e-9, 0.05), 2))
    lines = ["n,alt_ft"] + [f"{k},{h / FT:.1f}" for k, h in enumerate(g["altitude"])]
    path = folder / "numbered.csv"
    path.write_text("\n".join(lines) + "\n")
    cmap = {
        "time": {"column": "n", "scale": 0.05},
        "altitude": {"column": "alt_ft", "unit": "ft"},
    }
    return [path], cmap, {"altitude": 0.05 * FT}, 0.0


LAYOUTS = {
    fn.__name__: fn
    for fn in (
        stratologger_pf2,
        blue_raven_lr,
        openlog_arduino,
        excel_semicolon,
        units_row,
        flysight_track,
        easymini_altos,
        whitespace_logger,
        openrocket_export,
        numbered_samples,
    )
}
