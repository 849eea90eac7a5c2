"""The HFB-320 business jet, longitudinal motion (Jategaonkar, *Flight Vehicle System
Identification*, 2nd ed., test case 4; SPEC section 7).

States `V, alpha, theta, q`; inputs elevator `de` (rad) and `thrust` (N, from the
log); outputs `V, alpha, theta, q, qdot, ax, az`. Aerodynamics, with `V0` the
reference speed:

    CD = CD0 + CDV V/V0 + CDa alpha
    CL = CL0 + CLV V/V0 + CLa alpha
    CM = CM0 + CMV V/V0 + CMa alpha + CMq q c/V0 + CMde de

Constant mass, air density and the book's constants. The record shipped in
`shared/data/hfb320/hfb320_1_10.asc` (FVSysID ASCII columns) loads through
[`COLUMNS`][].
"""

import jax.numpy as jnp

from .._identify._model import Model


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


def _coefficients(x, u, p):
    v, alpha, _, q = x
    cd = p["CD0"] + p["CDV"] * v / V0 + p["CDa"] * alpha
    cl = p["CL0"] + p["CLV"] * v / V0 + p["CLa"] * alpha
    cm = (
        p["CM0"]
        + p["CMV"] * v / V0
        + p["CMa"] * alpha
        + p["CMq"] * q * CBAR / V0
        + p["CMde"] * u[0]
    )
    return 0.5 * RHO * v**2, cd, cl, cm


def rates(t, x, u, p):
    """`[Vdot, alphadot, thetadot, qdot]` of the point-mass-plus-pitch model."""
    del t
    v, alpha, theta, q = x
    qbar, cd, cl, cm = _coefficients(x, u, p)
    thrust = u[1]
    vdot = (
        -qbar * S_OVER_M * cd
        + thrust / MASS * jnp.cos(alpha + SIGMA_T)
        - G * jnp.sin(theta - alpha)
    )
    alphadot = (
        -qbar * S_OVER_M / v * cl
        - thrust / (MASS * v) * jnp.sin(alpha + SIGMA_T)
        + q
        + G / v * jnp.cos(theta - alpha)
    )
    qdot = qbar * SC_OVER_IY * cm + THRUST_MOMENT * thrust
    return jnp.stack([vdot, alphadot, q, qdot])


def observe(t, x, u, p):
    """`[V, alpha, theta, q, qdot, ax, az]`; accelerations at the CG, body axes."""
    del t
    v, alpha, theta, q = x
    qbar, cd, cl, cm = _coefficients(x, u, p)
    thrust = u[1]
    cx = cl * jnp.sin(alpha) - cd * jnp.cos(alpha)
    cz = -cl * jnp.cos(alpha) - cd * jnp.sin(alpha)
    ax = qbar * S_OVER_M * cx + thrust / MASS * jnp.cos(SIGMA_T)
    az = qbar * S_OVER_M * cz - thrust / MASS * jnp.sin(SIGMA_T)
    qdot = qbar * SC_OVER_IY * cm + THRUST_MOMENT * thrust
    return jnp.stack([v, alpha, theta, q, qdot, ax, az])


def hfb320_model(**changes) -> Model:
    """The HFB-320 longitudinal model with the book's start values; keyword
    arguments change fields (e.g. `fixed=("CMq",)`, `start={"CMq": 0.0}`)."""
    model = Model(
        states=("V", "alpha", "theta", "q"),
        inputs=("de", "thrust"),
        outputs=("V", "alpha", "theta", "q", "qdot", "ax", "az"),
        parameters=START,
        rates=rates,
        observe=observe,
    )
    return model.replace(**changes) if changes else model
