"""Model file: the HFB-320 longitudinal model (Jategaonkar's test case 4), written
against the public interface only; the same model as the built-in `--vehicle hfb320`.

    diffpegasus fit ../shared/data/hfb320/hfb320_1_10.asc --model examples/hfb320.py
"""

import jax.numpy as jnp

import diffpegasus as dp


G, S_M, SC_IY, THRUST_MOMENT = 9.80665, 4.028e-3, 8.0027e-4, -7.0153e-6
V0, MASS, SIGMA_T, RHO, CBAR = 104.67, 7472.0, 0.0524, 0.792, 1.215


def _aero(x, u, p):
    v, alpha, _, q = x
    qbar = 0.5 * RHO * v**2
    cd = p["CD0"] + p["CDV"] * v / V0 + p["CDa"] * alpha
    cl = p["CL0"] + p["CLV"] * v / V0 + p["CLa"] * alpha
    cm = (
        p["CM0"]
        + p["CMV"] * v / V0
        + p["CMa"] * alpha
        + p["CMq"] * q * CBAR / V0
        + p["CMde"] * u[0]
    )
    return qbar, cd, cl, cm


def rates(t, x, u, p):
    v, alpha, theta, q = x
    qbar, cd, cl, cm = _aero(x, u, p)
    thrust = u[1]
    return jnp.stack(
        [
            -qbar * S_M * cd
            + thrust / MASS * jnp.cos(alpha + SIGMA_T)
            - G * jnp.sin(theta - alpha),
            -qbar * S_M / v * cl
            - thrust / (MASS * v) * jnp.sin(alpha + SIGMA_T)
            + q
            + G / v * jnp.cos(theta - alpha),
            q,
            qbar * SC_IY * cm + THRUST_MOMENT * thrust,
        ]
    )


def observe(t, x, u, p):
    v, alpha, theta, q = x
    qbar, cd, cl, cm = _aero(x, u, p)
    thrust = u[1]
    cx = cl * jnp.sin(alpha) - cd * jnp.cos(alpha)
    cz = -cl * jnp.cos(alpha) - cd * jnp.sin(alpha)
    return jnp.stack(
        [
            v,
            alpha,
            theta,
            q,
            qbar * SC_IY * cm + THRUST_MOMENT * thrust,
            qbar * S_M * cx + thrust / MASS * jnp.cos(SIGMA_T),
            qbar * S_M * cz - thrust / MASS * jnp.sin(SIGMA_T),
        ]
    )


model = dp.Model(
    states=("V", "alpha", "theta", "q"),
    inputs=("de", "thrust"),
    outputs=("V", "alpha", "theta", "q", "qdot", "ax", "az"),
    parameters={
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
    },
    rates=rates,
    observe=observe,
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
