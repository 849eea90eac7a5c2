"""The HFB-320 business jet, longitudinal motion (Jategaonkar, *Flight Vehicle System
Identification*, 2nd ed., test case 4).

States `V, alpha, theta, q`; inputs elevator `de` (rad) and `thrust` (N, from the
log); outputs `V, alpha, theta, q, qdot, ax, az`. Aerodynamics, with `V0` the
reference speed:

    CD = CD0 + CDV V/V0 + CDa alpha
    CL = CL0 + CLV V/V0 + CLa alpha
    CM = CM0 + CMV V/V0 + CMa alpha + CMq q c/V0 + CMde de

Constant mass, air density and the book's constants. The vehicle is the one flight
model (`pitch_plane`) with these parts, so every library effect composes with it.
The book's flight
record `hfb320_1_10.asc` (FVSysID ASCII columns; where to get it: the documentation's
data page) loads through [`COLUMNS`][].
"""

from .._model import Model
from ._parts import (
    AbstractAerodynamics,
    ConstantAtmosphere,
    ConstantMass,
    effect_parameter as effect_parameter,
    FlightVehicle,
    Geometry,
    LoggedThrust,
    PITCH_PLANE_EFFECTS,
    vehicle_model,
)


G = 9.80665  # m/s^2
S_OVER_M = 4.028e-3  # S/m, m^2/kg
SC_OVER_IY = 8.0027e-4  # S c / Iy, m^3/(kg m^2)
THRUST_MOMENT = -7.0153e-6  # pitch acceleration per newton of thrust, 1/(N s^2)
V0 = 104.67  # m/s
MASS = 7472.0  # kg
SIGMA_T = 0.0524  # thrust inclination, rad
RHO = 0.792  # kg/m^3
CBAR = 1.215  # m

START = {
    "CD0": 5.67516e-3,
    "CDV": 7.72612e-3,
    "CDa": 0.674256,
    "CL0": -0.318267,
    "CLV": 0.260317,
    "CLa": 5.37576,
    "CM0": 4.98218e-2,
    "CMV": 1.89182e-2,
    "CMa": -0.498586,
    "CMq": -25.8439,
    "CMde": -0.990687,
}
# The book's initial state (V m/s, alpha rad, theta rad, q rad/s).
X0 = (106.023, 0.111685, 0.104887, -0.00332659)

# FVSysID ASCII columns of the record -> model channels (SI units, radians).
COLUMNS = {
    "t": {"column": "T"},
    "de": {"column": "DELV"},
    "thrust": {"column": "THRUST"},
    "V": {"column": "TASCG"},
    "alpha": {"column": "ALFCG"},
    "theta": {"column": "THE"},
    "q": {"column": "Q"},
    "qdot": {"column": "QDOT"},
    "ax": {"column": "AXCG"},
    "az": {"column": "AZCG"},
    "qbar": {"column": "PDYN"},
}


S_REF = S_OVER_M * MASS  # m^2
IYY = S_REF * CBAR / SC_OVER_IY  # kg m^2
SPEED_OF_SOUND = 320.5  # m/s, at the test altitude (only the Mach channel uses it)

CANDIDATES = PITCH_PLANE_EFFECTS  # the library effects `--add` and `diagnose` use


class HFB320Aerodynamics(AbstractAerodynamics):
    """The book's aerodynamic model: CL, CD and CM (about the CG)."""

    def start(self):
        return dict(START)

    def coefficients(self, c, p):
        v = c.airspeed
        cd = p["CD0"] + p["CDV"] * v / V0 + p["CDa"] * c.alpha
        cl = p["CL0"] + p["CLV"] * v / V0 + p["CLa"] * c.alpha
        cm = (
            p["CM0"]
            + p["CMV"] * v / V0
            + p["CMa"] * c.alpha
            + p["CMq"] * c.q * CBAR / V0
            + p["CMde"] * c.de
        )
        return cl, cd, cm


# The vehicle as a value: its parts.
HFB320 = FlightVehicle(
    aerodynamics=HFB320Aerodynamics(),
    propulsion=LoggedThrust(angle=SIGMA_T, moment_per_newton=THRUST_MOMENT * IYY),
    mass=ConstantMass(mass=MASS, iyy=IYY),
    geometry=Geometry(s_ref=S_REF, c_ref=CBAR),
    atmosphere=ConstantAtmosphere(density=RHO, speed_of_sound=SPEED_OF_SOUND, g=G),
    name="hfb320",
)


def hfb320_model(
    effects: tuple[str, ...] = (), free: tuple[str, ...] = (), **changes
) -> Model:
    """The HFB-320 longitudinal model with the book's start values
    ([`vehicle_model`][] of [`HFB320`][]).

    **Arguments:** `effects`: library effects composed with the vehicle (canonical
    names, see [`CANDIDATES`][]), each adding its parameter (`name.parameter`,
    start 0) held at zero unless named in `free`; keyword arguments change the
    model's fields (e.g. `fixed=("CMq",)`, `start={"CMq": 0.0}`).
    """
    return vehicle_model(HFB320, effects=effects, free=free, **changes)


# The output-error estimates on the real record (`diffpegasus fit ... --vehicle
# hfb320`): the truth of simulated flights.
IDENTIFIED = {
    "CD0": 0.117776,
    "CDV": -0.0517719,
    "CDa": 0.234949,
    "CL0": -0.204497,
    "CLV": 0.363406,
    "CLa": 3.21170,
    "CM0": 0.134393,
    "CMV": -0.0138949,
    "CMa": -1.00232,
    "CMq": -27.0630,
    "CMde": -1.43719,
}
# FVSysID's filter-error estimates for the record (chapter 7, mDefCase04.m, quoted
# there as ml_fem's for test_case=4): the reference of `fit --method fem`.
BOOK_FEM = {
    "CD0": 0.122688,
    "CDV": -0.0644969,
    "CDa": 0.320055,
    "CL0": -0.0929113,
    "CLV": 0.148726,
    "CLa": 4.32785,
    "CM0": 0.111905,
    "CMV": 0.00395154,
    "CMa": -0.967854,
    "CMq": -34.7098,
    "CMde": -1.52913,
}
# Sensor noise of simulated flights (1 sigma, SI units, radians).
NOISE = {
    "V": 0.1,
    "alpha": 1e-3,
    "theta": 1e-3,
    "q": 5e-4,
    "qdot": 2e-3,
    "ax": 0.02,
    "az": 0.05,
}
# Process noise of the book's filter-error case (all four state equations) with
# FVSysID's start intensities (mDefCase04.m; V m/s, alpha rad, theta rad, q rad/s,
# each per sqrt(s)): `fit --method fem` and the diagnosis's process-noise candidate.
PROCESS_NOISE = {"V": 0.02, "alpha": 0.002, "theta": 0.02, "q": 0.02}
TRIM = {"de": -0.0075, "thrust": 11633.0}  # elevator (rad), thrust (N) of the record
