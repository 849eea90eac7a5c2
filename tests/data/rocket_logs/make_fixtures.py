"""Writes the tiny synthetic flight-computer logs the rocket-log tests read.

One closed-form flight (`flight`), written in three layouts: an AltOS CSV export
(`altos.csv`: 1 g removed, Pa, m, 20 Hz then 2 Hz after 15 s, every tenth row
of the ascent written twice as AltOS does, GNSS held between 1 Hz fixes), a CATS export split by
sensor (`cats/`: imu with the rocket's axis along -Y, baro, filtered data, gnss) and
an altimeter CSV (`altimeter.csv`: altitude in ft, acceleration in g with gravity).

    python tests/data/rocket_logs/make_fixtures.py
"""

import pathlib

import numpy as np


G0 = 9.80665
HERE = pathlib.Path(__file__).resolve().parent
# the flight: 2 s boost at 6 g net, a coast against gravity and quadratic drag
# (deceleration g + K v^2), free fall from apogee until 30 m/s under the drogue, main
# at 150 m (6 m/s), landing; liftoff at t = 0. Closed form throughout.
BURN, BOOST_G, K = 2.0, 6.0, 1e-4
V_DROGUE, H_MAIN, V_MAIN = 30.0, 150.0, 6.0
V_BURNOUT = BOOST_G * G0 * BURN
H_BURNOUT = 0.5 * BOOST_G * G0 * BURN**2
_TH0 = np.arctan(V_BURNOUT * np.sqrt(K / G0))
_W = np.sqrt(G0 * K)
T_APOGEE = BURN + _TH0 / _W
H_APOGEE = H_BURNOUT - np.log(np.cos(_TH0)) / K
_T_FALL = V_DROGUE / G0
T_DROGUE = T_APOGEE + _T_FALL
H_DROGUE = H_APOGEE - 0.5 * G0 * _T_FALL**2
T_MAIN = T_DROGUE + (H_DROGUE - H_MAIN) / V_DROGUE
T_LANDING = T_MAIN + H_MAIN / V_MAIN


def flight(t):
    """Altitude (m) and axial specific force (m/s^2, gravity included)."""
    t = np.asarray(t, float)
    h = np.zeros_like(t)
    sf = np.full_like(t, G0)  # on the pad, under a canopy, after landing
    b = (t >= 0) & (t < BURN)
    h[b] = 0.5 * BOOST_G * G0 * t[b] ** 2
    sf[b] = (BOOST_G + 1) * G0
    c = (t >= BURN) & (t < T_APOGEE)
    phase = _TH0 - _W * (t[c] - BURN)
    h[c] = H_BURNOUT + np.log(np.cos(phase) / np.cos(_TH0)) / K
    sf[c] = -G0 * np.tan(phase) ** 2  # -K v^2
    f = (t >= T_APOGEE) & (t < T_DROGUE)
    h[f] = H_APOGEE - 0.5 * G0 * (t[f] - T_APOGEE) ** 2
    sf[f] = 0.0
    d = (t >= T_DROGUE) & (t < T_MAIN)
    h[d] = H_DROGUE - V_DROGUE * (t[d] - T_DROGUE)
    m = (t >= T_MAIN) & (t < T_LANDING)
    h[m] = H_MAIN - V_MAIN * (t[m] - T_MAIN)
    return h, sf


def pressure(h):
    return 101325.0 * (1 - 2.25577e-5 * h) ** 5.25588


def main():
    rng = np.random.default_rng(27)
    # AltOS: 0.5 s on the pad, 20 Hz to 15 s, then 2 Hz to 70 s
    t = np.concatenate([np.arange(-0.5, 15, 0.05), np.arange(15, 70.01, 0.5)])
    h, sf = flight(t)
    h = h + rng.normal(0, 0.3, t.size)
    sf = sf + np.round(rng.normal(0, 0.2, t.size) / 0.5) * 0.5
    lat = 32.9395 + 1e-4 * np.floor(np.maximum(t, 0))
    gps_alt = 1390 + np.round(flight(np.floor(t))[0])
    head = (
        "#version,serial,flight,call,time,state,state_name,acceleration,pressure,"
        "altitude,height,speed,temperature,battery_voltage,nsat,latitude,longitude,"
        "altitude"
    )
    with open(HERE / "altos.csv", "w") as f:
        f.write(head + "\n")
        for k, (ti, hi, ai) in enumerate(zip(t, h, sf, strict=False)):
            row = (
                f"6, 5115, 1,N0CALL, {ti:8.2f}, 3, boost, {ai - G0:7.2f}, "
                f"{pressure(hi):9.2f}, {hi + 1320:8.2f}, {hi:8.2f}, {0.0:7.2f}, 30.0, "
                f"3.87, 9, {lat[k]:.7f},-106.9114515, {gps_alt[k]:7.1f}\n"
            )
            f.write(row)
            if k % 10 == 5 and ti < 15:
                f.write(row)
    # CATS: 0.75 s pre-trigger, 20 Hz to 70 s, one file per sensor, axis along -Y
    t = np.arange(-0.75, 70.0, 0.05)
    h, sf = flight(t)
    cats = HERE / "cats"
    cats.mkdir(exist_ok=True)
    ax = rng.normal(0, 0.1, t.size)
    ay = -sf + rng.normal(0, 0.2, t.size)
    az = rng.normal(0, 0.1, t.size)
    g = rng.normal(0, 1.0, (t.size, 3))
    with open(cats / "imu.csv", "w") as f:
        f.write("ts,id,Ax,Ay,Az,Gx,Gy,Gz\n")
        for row in zip(t, ax, ay, az, *g.T, strict=False):
            f.write(
                "{:.3f},IMU0,{:.4f},{:.4f},{:.4f},{:.3f},{:.3f},{:.3f}\n".format(*row)
            )
    p = pressure(h + rng.normal(0, 0.5, t.size))
    with open(cats / "baro.csv", "w") as f:
        f.write("ts,id,T,P\n")
        for ti, pi in zip(t, p, strict=False):
            f.write(f"{ti:.3f},BARO0,30.0,{pi:.0f}\n")
    with open(cats / "filteredDataInfo.csv", "w") as f:
        f.write("ts,filteredAltitudeAGL,filteredAcceleration\n")
        for ti, hi, ai in zip(t, h, sf, strict=False):
            a = ai - G0 if ti < T_APOGEE + 0.5 else 0.0
            f.write(f"{ti + 0.005:.3f},{hi:.4f},{a:.4f}\n")
    tg = np.arange(-0.6, 70.0, 0.2)
    with open(cats / "gnssInfo.csv", "w") as f:
        f.write("ts,latitude,longitude,satellites\n")
        for ti in tg:
            f.write(f"{ti:.3f},{39.39 + 1e-5 * max(ti, 0):.7f},-8.2895,9\n")
    # altimeter: ft and g (gravity included), 20 Hz, 0.3 s on the pad
    t = np.arange(-0.3, 70.0, 0.05)
    h, sf = flight(t)
    with open(HERE / "altimeter.csv", "w") as f:
        f.write("t(s),alt(ft),accel(g)\n")
        for ti, hi, ai in zip(
            t,
            h + rng.normal(0, 0.3, t.size),
            sf + rng.normal(0, 0.2, t.size),
            strict=False,
        ):
            f.write(f"{ti:.2f},{hi / 0.3048:.2f},{ai / G0:.3f}\n")


if __name__ == "__main__":
    main()
