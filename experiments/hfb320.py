"""HFB-320 business jet, longitudinal motion (SPEC section 7; Jategaonkar's test case 4).

The whole model is the two functions below, written against the public interface,
then estimated by OEM from the book's start values on the real flight record
`shared/data/hfb320/hfb320_1_10.asc` (3-2-1-1 then pulse, 60 s at 10 Hz).
The last stdout line is one JSON object with the estimates, standard errors, cost,
iterations and convergence.

Run: `python experiments/hfb320.py [--data FILE] [--out DIR]`.
"""

import argparse
import json
import pathlib

import jax.numpy as jnp
import matplotlib
import numpy as np


matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from _shared import shared_data  # noqa: E402

import diffpegasus as dp  # noqa: E402


G, S_M, SC_IY, THRUST_MOMENT = 9.80665, 4.028e-3, 8.0027e-4, -7.0153e-6
V0, MASS, SIGMA_T, RHO, CBAR = 104.67, 7472.0, 0.0524, 0.792, 1.215
NAMES = ["CD0", "CDV", "CDa", "CL0", "CLV", "CLa", "CM0", "CMV", "CMa", "CMq", "CMde"]
START = [
    5.67516e-3,
    7.72612e-3,
    0.674256,
    -0.318267,
    0.260317,
    5.37576,
    4.98218e-2,
    1.89182e-2,
    -0.498586,
    -25.8439,
    -0.990687,
]
X0 = [106.023, 0.111685, 0.104887, -0.00332659]  # V, alpha, theta, q
OUTPUTS = ["TASCG", "ALFCG", "THE", "Q", "QDOT", "AXCG", "AZCG"]
DEFAULT_DATA = shared_data("hfb320/hfb320_1_10.asc")


def _aero(x, u, p):
    v, alpha, _, q = x
    cd0, cdv, cda, cl0, clv, cla, cm0, cmv, cma, cmq, cmde = p
    cd = cd0 + cdv * v / V0 + cda * alpha
    cl = cl0 + clv * v / V0 + cla * alpha
    cm = cm0 + cmv * v / V0 + cma * alpha + cmq * q * CBAR / V0 + cmde * u[0]
    return 0.5 * RHO * v**2, cd, cl, cm


def rates(t, x, u, p):
    v, alpha, theta, q = x
    qbar, cd, cl, cm = _aero(x, u, p)
    thrust = u[1]
    vdot = (
        -qbar * S_M * cd
        + thrust / MASS * jnp.cos(alpha + SIGMA_T)
        - G * jnp.sin(theta - alpha)
    )
    alphadot = (
        -qbar * S_M / v * cl
        - thrust / (MASS * v) * jnp.sin(alpha + SIGMA_T)
        + q
        + G / v * jnp.cos(theta - alpha)
    )
    qdot = qbar * SC_IY * cm + THRUST_MOMENT * thrust
    return jnp.stack([vdot, alphadot, q, qdot])


def outputs(t, x, u, p):
    v, alpha, theta, q = x
    qbar, cd, cl, cm = _aero(x, u, p)
    thrust = u[1]
    cx = cl * jnp.sin(alpha) - cd * jnp.cos(alpha)
    cz = -cl * jnp.cos(alpha) - cd * jnp.sin(alpha)
    ax = qbar * S_M * cx + thrust / MASS * jnp.cos(SIGMA_T)
    az = qbar * S_M * cz - thrust / MASS * jnp.sin(SIGMA_T)
    qdot = qbar * SC_IY * cm + THRUST_MOMENT * thrust
    return jnp.stack([v, alpha, theta, q, qdot, ax, az])


def problem(data, free=(True,) * 11):
    return dp.OEMProblem(
        rates=rates,
        outputs=outputs,
        t0=float(data["T"][0]),
        dt=float(data["T"][1] - data["T"][0]),
        inputs=jnp.asarray(np.column_stack([data["DELV"], data["THRUST"]])),
        measured=jnp.asarray(np.column_stack([data[c] for c in OUTPUTS])),
        free=tuple(free),
    )


def estimate(data, start=START, free=(True,) * 11):
    return dp.fit_oem(problem(data, free), jnp.asarray(start), jnp.asarray([X0]))


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", type=pathlib.Path, default=DEFAULT_DATA)
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/hfb320")
    )
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    data = dp.read_asc(args.data)
    res = estimate(data)
    p, sd = np.asarray(res.params[0]), np.asarray(res.stderr[0])
    fig, axes = plt.subplots(len(OUTPUTS), 1, figsize=(9, 12), sharex=True)
    for j, (ax, name) in enumerate(zip(axes, OUTPUTS, strict=True)):
        ax.plot(data["T"], data[name], "k-", lw=1, label="measured")
        ax.plot(
            data["T"], np.asarray(res.outputs)[:, j], "r--", lw=1, label="OEM model"
        )
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    axes[0].legend()
    axes[-1].set_xlabel("time, s")
    fig.suptitle("HFB-320 output-error fit")
    fig.tight_layout()
    fig.savefig(args.out / "fit.png", dpi=110)
    plt.close(fig)
    print(dp.format_parameter_table(dp.parameter_table(NAMES, p, sd)))
    summary = {
        "estimates": dict(zip(NAMES, p.tolist(), strict=True)),
        "stderr": dict(zip(NAMES, sd.tolist(), strict=True)),
        "stderr_coloured_residuals": dict(
            zip(NAMES, np.asarray(res.stderr_corrected[0]).tolist(), strict=True)
        ),
        "cost": float(res.cost),
        "iterations": int(res.iterations),
        "converged": bool(res.converged),
    }
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(
        json.dumps(
            {
                k: summary[k]
                for k in ("estimates", "stderr", "cost", "iterations", "converged")
            }
        )
    )


if __name__ == "__main__":
    main()
