"""Model file: the HFB-320's short-period motion as a linear model (dimensional
derivatives about the record's trim), for the frequency-domain estimators and for
output error in the time domain alike. With the textbook's flight record
`hfb320_1_10.asc` in the current folder (it comes with the book's software FVSysID;
the documentation's data page says where to get it):

    diffpegasus fit hfb320_1_10.asc \
        --model examples/hfb320_linear.py --method fdoe --json

States `alpha` (rad), `q` (rad/s); inputs elevator `de` (rad), and the measured
airspeed `V` (m/s) and thrust (N) as pseudo-inputs (the slow phugoid is then data,
not model); outputs `alpha`, `q`, `qdot` (rad/s^2) and `az` (m/s^2):

    alpha' = Za alpha + q + ZV V + Z0
    q'     = Ma alpha + Mq q + Mde de + MV V + Mt thrust + M0
    az     = V0 (Za alpha + ZV V + Z0) - g + az0

(`az = V0 (alpha' - q) - g` for small flight-path angles; `Mt` is the book's thrust
moment, held). The constants `Z0, M0, az0` carry the trim; the frequency-domain
estimators do not see them (they have no transform on the frequency grid) and report
them as not estimated.
"""

import jax.numpy as jnp

import diffpegasus as dp


G = 9.80665  # m/s^2
V0 = 104.67  # m/s
THRUST_MOMENT = -7.0153e-6  # pitch acceleration per newton of thrust, 1/(N s^2)


def rates(t, x, u, p):
    alpha, q = x
    de, v, thrust = u
    return jnp.stack(
        [
            p["Za"] * alpha + q + p["ZV"] * v + p["Z0"],
            p["Ma"] * alpha
            + p["Mq"] * q
            + p["Mde"] * de
            + p["MV"] * v
            + THRUST_MOMENT * thrust
            + p["M0"],
        ]
    )


def observe(t, x, u, p):
    alpha, q = x
    qdot = rates(t, x, u, p)[1]
    az = V0 * (p["Za"] * alpha + p["ZV"] * u[1] + p["Z0"]) - G + p["az0"]
    return jnp.stack([alpha, q, qdot, az])


model = dp.Model(
    states=("alpha", "q"),
    inputs=("de", "V", "thrust"),
    outputs=("alpha", "q", "qdot", "az"),
    # start values: the nonlinear model's linearisation at the record's trim
    parameters={
        "Za": -0.56,
        "ZV": -0.0023,
        "Z0": 0.3,
        "Ma": -3.6,
        "Mq": -1.1,
        "Mde": -5.1,
        "MV": 0.0009,
        "M0": 0.3,
        "az0": 0.0,
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
    "q": "Q",
    "qdot": "QDOT",
    "az": "AZCG",
}
