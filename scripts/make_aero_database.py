"""Generate `src/diffpegasus/data/pegasus_aero.csv`, the a-priori aerodynamic database.

The thesis's tables (from its reference [32], expanded with a MATLAB network) are not
public, so this database is built from textbook semi-empirical estimates for a
Pegasus-like winged body (S = 13.5 m^2, c = 2.48 m, wing aspect ratio 3.33, 45 deg
leading-edge sweep, 15 m x 1.27 m body, three aft fins). Every number below is an
engineering estimate, chosen to give the trends of such a vehicle:

- normal-force slope of the wing from the DATCOM subsonic formula, from linear
  supersonic theory `~4 / sqrt(M^2 - 1)` (x 0.8 for the low-aspect-ratio wing's tip
  losses) above Mach 1, capped in the transonic region; plus slender-body theory
  (2 per rad on the 1.27 m^2 base area) and body cross-flow lift growing with |alpha|;
- drag that grows with alpha (induced drag `CL * alpha` and a wave-drag-like hump
  near Mach 1.2), in the thesis's form CD = CDa alpha + CDde de (no CD0 term, the
  thesis's assumption for the symmetric vehicle);
- fin (elevon) effectiveness from the same theory on 2 x 2.0 m^2 of fin;
- pitching moment about the centre-of-pressure station (the normal force is placed
  at the cp by the simulator): a small stable CMa, and CMde from the fins acting
  4.1 m aft of the cp.

All derivatives are per radian. Grid: the thesis's expanded breakpoints (alpha
-1.84:2:26.16 deg, Mach 0.3:1:8.3) with one extra Mach point at 9.3 so the
burnout Mach (up to about 9.5) stays inside the table.

Run: `python scripts/make_aero_database.py`.
"""

import pathlib

import numpy as np


ASPECT_RATIO = 3.33
SWEEP_HALF_CHORD = np.deg2rad(35.0)
S_REF = 13.5
BODY_BASE_AREA = np.pi * 1.27**2 / 4
FIN_AREA = 2 * 2.0
FIN_ARM_OVER_CHORD = 4.1 / 2.48


def wing_slope(mach):
    """Wing normal-force slope (1/rad, on the wing area), subsonic to hypersonic."""
    m_sub = np.minimum(mach, 0.95)
    beta2 = 1 - m_sub**2
    a = ASPECT_RATIO
    datcom = (
        2
        * np.pi
        * a
        / (2 + np.sqrt(4 + a**2 * beta2 * (1 + np.tan(SWEEP_HALF_CHORD) ** 2 / beta2)))
    )
    supersonic = 4 / np.sqrt(np.maximum(mach**2 - 1, 1e-9))
    return np.where(mach <= 1.0, datcom, np.minimum(datcom, supersonic))


def fin_slope(mach):
    """Fin normal-force slope (1/rad, on the fin area)."""
    subsonic = 2.6
    supersonic = 4 / np.sqrt(np.maximum(mach**2 - 1, 1e-9))
    return np.where(mach <= 1.0, subsonic, np.minimum(subsonic * 1.3, supersonic))


def derivatives(alpha, mach):
    """The six database derivatives (1/rad) at alpha (rad) and Mach."""
    k_lin = wing_slope(mach) + 2 * BODY_BASE_AREA / S_REF
    crossflow = 1.7 / (1 + 0.1 * mach)
    cla = k_lin + crossflow * np.abs(alpha)
    clde = fin_slope(mach) * FIN_AREA / S_REF
    wave = 0.15 + 0.35 * np.exp(-(((mach - 1.2) / 0.9) ** 2))
    cda = wave + k_lin * alpha
    cdde = clde * (0.1 + alpha)
    cma = -0.02 * k_lin * (1 + 0.5 * alpha)
    cmde = -FIN_ARM_OVER_CHORD * clde
    return cla, clde, cda, cdde, cma, cmde


def main():
    alpha_deg = -1.84 + 2.0 * np.arange(15)
    mach = 0.3 + 1.0 * np.arange(10)
    rows = []
    for m in mach:
        for a in alpha_deg:
            rows.append([m, a, *derivatives(np.deg2rad(a), m)])
    out = pathlib.Path(__file__).parents[1] / "src/diffpegasus/data/pegasus_aero.csv"
    header = "mach,alpha_deg,CLa,CLde,CDa,CDde,CMa,CMde"
    np.savetxt(
        out, np.array(rows), delimiter=",", header=header, comments="", fmt="%.8g"
    )
    print(f"wrote {out} ({len(rows)} rows)")


if __name__ == "__main__":
    main()
