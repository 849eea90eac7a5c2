"""A plausible lateral-directional database for the Pegasus first stage, its fins as
the roll and yaw controls, and the vehicle as a 6-DOF [`Aircraft`][] at one flight
condition.

**Not published data.** The thesis models the pitch plane only ("the lateral
parameters considered zero"); no lateral derivatives, fin geometry or roll/yaw
inertias of Pegasus are published that we know of. What follows is an engineering
estimate, to simulate plausible lateral motion and exercise lateral identification
on a launch-vehicle-like configuration, not to predict Pegasus.

Provenance and assumptions:

- **Geometry** as the 3-DOF vehicle (thesis Table 2.1): wing area 13.5 m^2 (the
  reference), span 6.7 m, mean chord 2.48 m, root and tip chords 3.69 and 0.338 m,
  length 15 m, diameter 1.27 m; the wing sits on top of the body (high wing).
- **Fins** (assumed): three all-moving fins at the aft skirt, two horizontal (roll
  control: aileron-like differential deflection `da = (right - left) / 2`, trailing
  edge down positive on the right fin) and one ventral, below the body (yaw control
  `dr`, positive giving positive side force); each [`FIN_AREA`][] 1.6 m^2 exposed,
  aspect ratio 1.5, centroid at station 14.2 m and 1.25 m from the body axis (a
  fin half-span outboard of the 0.635 m radius), scaled by eye from photographs
  against the published diameter.
- **Fin lift slope** [`fin_lift_slope`][] (per rad): Helmbold's low-aspect-ratio
  formula with the Prandtl-Glauert factor below Mach 0.9, Ackeret's `4 / sqrt(M^2 -
  1)` with the rectangular-wing tip loss `1 - 1 / (2 A sqrt(M^2 - 1))` above Mach
  1.2, linear in between. Each fin's force is that slope times its local incidence
  (the flow at its centroid: sideslip, and the rotation rates times the arm), times
  the dynamic pressure and its area; no fin-body interference, no downwash.
- **Wing**: roll damping by strip theory of the tapered wing with the database's lift
  slope (`Cl_p = -(CLa / 12) (1 + 3 taper) / (1 + taper)`, Etkin's form); dihedral
  effect of a high 45-degree-swept wing at small lift `Cl_beta = -0.05` (an
  assumption, of the order the DATCOM charts give); nothing else.
- **Body**: slender-body theory, side force `CY_beta = -2 A_base / S` acting so that
  the yawing moment about the CG is `Cn_beta = -2 (Vol - A_base (L - x_cg)) / (S b)`
  (the Munk moment, destabilising).
- **Inertias** (assumed; only the pitch inertia is in the thesis's mass model): the
  stack a solid cylinder of the body's radius about its axis, `Ixx = m r^2 / 2`,
  plus a 250 kg wing (of the mass model's 440 kg of wing, fins and interstage) as a
  rod of the span, `m_w b^2 / 12`, which also adds to `Izz = Iyy + m_w b^2 / 12`;
  principal axes (`Ixz = 0`).

**What it gives** (measured, `tests/test_pegasus_lateral.py`): the body's Munk
moment exceeds the single ventral fin's, so the vehicle is directionally unstable
along the climb (`Cn_beta` -0.05 at the drop, Mach 0.8; -0.07 at 20 s, Mach 2;
-0.13 at 35 s, Mach 3.5; the fins lose lift slope supersonic): trimmed level
at the default condition (20 s, Mach 2, 16 km, 8 deg angle of attack) the lateral
matrix has a divergence of 0.6 /s (doubling in about 1.2 s) beside a stable roll
and yaw oscillation (-0.88 +/- 0.63j /s). A launch vehicle flies on its autopilot;
simulate short manoeuvres (or close a loop) and identify with multiple shooting.
The numbers are estimates, not Pegasus's: they change with every assumption above
(a 2 m^2 ventral fin would make it stable subsonic, not supersonic).
"""

import math

import numpy as np

from .._atmosphere import isa
from .._sixdof import Aircraft, inertia_tensor, LateralDerivatives
from ._vehicle import Vehicle


FIN_AREA = 1.6  # m^2, exposed, each fin (assumed)
FIN_ASPECT = 1.5  # fin aspect ratio (assumed)
FIN_STATION = 14.2  # m from the nose, fin centroids (assumed)
FIN_ARM = 1.25  # m, fin centroid from the body axis (assumed)
WING_MASS = 250.0  # kg (assumed, of the mass model's 440 kg wing, fins, interstage)
WING_CL_BETA = -0.05  # per rad, high swept wing at small lift (assumed)
TAPER = 0.338 / 3.69  # tip / root chord (thesis Table 2.1)


def fin_lift_slope(mach: float) -> float:
    """Lift-curve slope of one fin, per rad of incidence, at Mach `mach` (see the
    module docstring: Helmbold below 0.9, Ackeret with tip loss above 1.2, linear
    between)."""

    def subsonic(m):
        beta2 = 1.0 - m**2
        a = FIN_ASPECT
        return 2 * math.pi * a / (2 + math.sqrt(4 + a**2 * beta2))

    def supersonic(m):
        b = math.sqrt(m**2 - 1.0)
        return 4.0 / b * (1.0 - 1.0 / (2.0 * FIN_ASPECT * b))

    mach = float(mach)
    if mach <= 0.9:
        return subsonic(mach)
    if mach >= 1.2:
        return supersonic(mach)
    w = (mach - 0.9) / 0.3
    return (1 - w) * subsonic(0.9) + w * supersonic(1.2)


def pegasus_lateral(
    mach: float,
    xcg: float,
    cl_alpha: float,
    vehicle: Vehicle | None = None,
    fin_area: float = FIN_AREA,
) -> LateralDerivatives:
    """The lateral derivatives (per rad; rates per `p b / 2V`, `r b / 2V`) of the
    Pegasus first stage at Mach `mach` with the CG at station `xcg` (m from the
    nose), the vehicle's lift slope `cl_alpha` (per rad, for the wing's roll
    damping) and each fin's exposed area `fin_area` (m^2). See the module docstring
    for what each term is and assumes."""
    v = vehicle or Vehicle()
    s, b = v.s_ref, v.span
    k = fin_lift_slope(mach) * fin_area / s  # one fin's force coefficient per rad
    arm = FIN_STATION - xcg  # m, fins aft of the CG
    z_v = FIN_ARM  # the ventral fin below the axis
    y_h = FIN_ARM  # the horizontal fins either side
    radius = v.diameter / 2
    base = math.pi * radius**2
    volume = base * v.length
    # ventral fin: local sideslip beta - r arm / V - p z_v / V; side force
    # k (dr - local sideslip); yawing moment -arm Y; rolling moment -z_v Y
    cy_fin = dict(beta=-k, p=2 * k * z_v / b, r=2 * k * arm / b, dr=k)
    return LateralDerivatives(
        CY_beta=cy_fin["beta"] - 2 * base / s,
        CY_p=cy_fin["p"],
        CY_r=cy_fin["r"],
        CY_da=0.0,
        CY_dr=cy_fin["dr"],
        Cl_beta=-z_v / b * cy_fin["beta"] + WING_CL_BETA,
        Cl_p=-z_v / b * cy_fin["p"]
        - 4 * k * y_h**2 / b**2  # the horizontal fins
        - cl_alpha / 12 * (1 + 3 * TAPER) / (1 + TAPER),  # the wing
        Cl_r=-z_v / b * cy_fin["r"],
        Cl_da=-2 * k * y_h / b,  # right fin down, left fin up
        Cl_dr=-z_v / b * cy_fin["dr"],
        Cn_beta=-arm / b * cy_fin["beta"] - 2 * (volume - base * arm) / (s * b),
        Cn_p=-arm / b * cy_fin["p"],
        Cn_r=-arm / b * cy_fin["r"],
        Cn_da=0.0,
        Cn_dr=-arm / b * cy_fin["dr"],
    )


def pegasus_aircraft(
    t: float = 20.0,
    mach: float = 2.0,
    altitude: float = 16_000.0,
    fin_area: float = FIN_AREA,
) -> Aircraft:
    """The Pegasus first stage as a 6-DOF [`Aircraft`][] at `t` s after the drop
    (mass, CG and pitch inertia of the mass model at that time), Mach `mach` and
    geometric altitude `altitude` (m; air density of the standard atmosphere); the
    default is a point of the climb where level trim needs a moderate angle of
    attack (8 deg); each fin's exposed area `fin_area` (m^2).

    Longitudinal: the database's derivatives at zero angle of attack and this Mach,
    the pitching moment moved from the cp to the CG (`Cma = CMa - CLa (x_cp - x_cg) /
    c`, the same for `Cmde`), no `CL0, CD0, Cm0` (the database has none); pitch
    damping from the two horizontal fins, `Cmq = -4 k l^2 / c^2` per `q c / 2V` (the
    same fin model as the lateral terms). Lateral: [`pegasus_lateral`][]; inertias
    as the module docstring assumes. Thrust along body x (the trim supplies it).
    """
    v = Vehicle()
    props = v.mass.at(t, v.motor)
    mass, xcg, iyy = float(props.mass), float(props.xcg), float(props.Iyy)
    d = v.aero.derivatives(0.0, mach)
    xcp = float(v.xcp(mach))
    shift = (xcp - xcg) / v.c_ref
    k = fin_lift_slope(mach) * fin_area / v.s_ref
    arm = FIN_STATION - xcg
    wing = WING_MASS * v.span**2 / 12
    ixx = mass * (v.diameter / 2) ** 2 / 2 + wing
    return Aircraft(
        mass=mass,
        inertia=inertia_tensor(ixx, iyy, iyy + wing),
        s_ref=v.s_ref,
        b_ref=v.span,
        c_ref=v.c_ref,
        rho=float(isa(altitude).density),
        CL0=0.0,
        CLa=float(d.CLa),
        CD0=0.0,
        CDa=float(d.CDa),
        Cm0=0.0,
        Cma=float(d.CMa) - float(d.CLa) * shift,
        Cmq=-4 * k * arm**2 / v.c_ref**2,
        Cmde=float(d.CMde) - float(d.CLde) * shift,
        lateral=pegasus_lateral(mach, xcg, float(d.CLa), v, fin_area),
    )


def pegasus_speed(mach: float = 2.0, altitude: float = 16_000.0) -> float:
    """Airspeed (m/s) at Mach `mach` and altitude `altitude` (m), standard
    atmosphere: the speed to [`trim`][] a [`pegasus_aircraft`][] at."""
    return float(mach * np.asarray(isa(altitude).speed_of_sound))
