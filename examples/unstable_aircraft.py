"""Model file: short-period motion of an unstable aircraft (FVSysID's
`unStabAC_sim.asc`, which comes with the textbook's software: the documentation's data
page says where to get it). With it in the current folder, fit it with

    diffpegasus fit unStabAC_sim.asc \
        --model examples/unstable_aircraft.py --json

Single shooting cannot integrate an unstable model over 12.5 s from wrong start
values; multiple shooting (a node every 1 s) can, so this file asks for it.
"""

import jax.numpy as jnp

import diffpegasus as dp


U0 = 44.5695  # m/s


def rates(t, x, u, p):
    w, q = x
    return jnp.stack(
        [
            p["Zw"] * w + (U0 + p["Zq"]) * q + p["Zde"] * u[0],
            p["Mw"] * w + p["Mq"] * q + p["Mde"] * u[0],
        ]
    )


def observe(t, x, u, p):
    w, q = x
    return jnp.stack([p["Zw"] * w + p["Zq"] * q + p["Zde"] * u[0], w, q])


model = dp.Model(
    states=("w", "q"),
    inputs=("de",),
    outputs=("az", "w", "q"),
    parameters={
        "Zw": -1.22871,
        "Zq": -1.4768,
        "Zde": -4.20491,
        "Mw": 0.116197,
        "Mq": -2.70670,
        "Mde": -18.7718,
    },
    fixed=("Zq",),
    rates=rates,
    observe=observe,
)
columns = {"t": "T", "de": "DE", "az": "AZ", "w": "W", "q": "Q"}
x0 = (0.0, 0.0)
shooting = dp.MultipleShooting(interval=1.0)
