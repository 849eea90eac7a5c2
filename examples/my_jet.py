"""A user's vehicle in one short file, built from the library's parts: here the
HFB-320 (the textbook's test case 4) again, but written as a user would for their own
aircraft. The flight record `hfb320_1_10.asc` comes with the book's software FVSysID
(the documentation's data page, "The textbook's aircraft records", says where to get
it); with it in the current folder:

    diffpegasus fit hfb320_1_10.asc --vehicle examples/my_jet.py
    diffpegasus diagnose hfb320_1_10.asc \
        --vehicle examples/my_jet.py --fix CMq=0

Because it is a `FlightVehicle`, the library's effects compose with it (`--add
pitch_damping`, and the candidates of `diagnose`).
"""

import diffpegasus as dp


V0, CBAR, MASS = 104.67, 1.215, 7472.0  # m/s, m, kg
S = 4.028e-3 * MASS  # m^2
IYY = S * CBAR / 8.0027e-4  # kg m^2


class Aero(dp.AbstractAerodynamics):
    """CD, CL linear in V/V0 and alpha; CM adds pitch damping and elevator."""

    def start(self):
        return {
            "CD0": 5.7e-3,
            "CDV": 7.7e-3,
            "CDa": 0.67,
            "CL0": -0.32,
            "CLV": 0.26,
            "CLa": 5.4,
            "CM0": 0.05,
            "CMV": 0.019,
            "CMa": -0.5,
            "CMq": -26.0,
            "CMde": -1.0,
        }

    def coefficients(self, c, p):
        v = c.airspeed / V0
        cd = p["CD0"] + p["CDV"] * v + p["CDa"] * c.alpha
        cl = p["CL0"] + p["CLV"] * v + p["CLa"] * c.alpha
        cm = (
            p["CM0"]
            + p["CMV"] * v
            + p["CMa"] * c.alpha
            + p["CMq"] * c.q * CBAR / V0
            + p["CMde"] * c.de
        )
        return cl, cd, cm


vehicle = dp.FlightVehicle(
    aerodynamics=Aero(),
    propulsion=dp.LoggedThrust(angle=0.0524, moment_per_newton=-7.0153e-6 * IYY),
    mass=dp.ConstantMass(mass=MASS, iyy=IYY),
    geometry=dp.Geometry(s_ref=S, c_ref=CBAR),
    atmosphere=dp.ConstantAtmosphere(density=0.792),
)
columns = {
    "t": "T",
    "de": "DELV",
    "thrust": "THRUST",
    "V": "TASCG",
    "alpha": "ALFCG",
    "theta": "THE",
    "q": "Q",
    "qdot": "QDOT",
    "ax": "AXCG",
    "az": "AZCG",
}
x0 = (106.023, 0.111685, 0.104887, -0.00332659)
