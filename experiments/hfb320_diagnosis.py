"""Diagnosis on real flight data: the HFB-320 model with its pitch-damping term
removed, fitted to the real record, then every candidate effect scored (SPEC
section 6, issue "model discrepancy").

The model is `hfb320.py`'s, written against the public interface, extended by the
candidate terms of the effect library that make sense for it, each a parameter held
at zero: pitch damping (the removed CMq), alpha-dot damping, alpha^2 terms in lift,
drag and moment, and a bias on each measured channel. `dp.fit_global_oem` fits the
model with CMq fixed at zero (one shooting segment, initial state estimated) and
`dp.score_test` ranks the candidates.

Run: `python experiments/hfb320_diagnosis.py [--data FILE] [--out DIR]`; the last
stdout line is one JSON object `{"ranking": [...], "significant": [...]}`.
"""

import argparse
import json
import pathlib

import hfb320 as base
import jax.numpy as jnp
import numpy as np
from _shared import shared_data  # noqa: F401

import diffpegasus as dp


CANDIDATES = [
    ("pitch_damping", "CMq"),
    ("alpha_dot_damping", "CMad"),
    ("lift_alpha_squared", "CLa2"),
    ("drag_alpha_squared", "CDa2"),
    ("moment_alpha_squared", "CMa2"),
] + [(f"sensor_bias:{c}", f"b_{c}") for c in base.OUTPUTS]
N_BASE = len(base.NAMES)
EXTRA = len(CANDIDATES) - 1  # CMq is already a parameter of the model


def _terms(x, u, p):
    v, alpha, theta, q = x
    qbar, cd, cl, cm = base._aero(x, u, p[:N_BASE])
    cmad, cla2, cda2, cma2 = p[N_BASE : N_BASE + 4]
    cl = cl + cla2 * alpha**2
    cd = cd + cda2 * alpha**2
    thrust = u[1]
    alphadot = (
        -qbar * base.S_M / v * cl
        - thrust / (base.MASS * v) * jnp.sin(alpha + base.SIGMA_T)
        + q
        + base.G / v * jnp.cos(theta - alpha)
    )
    cm = cm + cma2 * alpha**2 + cmad * alphadot * base.CBAR / base.V0
    return qbar, cd, cl, cm, alphadot


def rates(t, x, u, p):
    v, alpha, theta, q = x
    qbar, cd, cl, cm, alphadot = _terms(x, u, p)
    thrust = u[1]
    vdot = (
        -qbar * base.S_M * cd
        + thrust / base.MASS * jnp.cos(alpha + base.SIGMA_T)
        - base.G * jnp.sin(theta - alpha)
    )
    qdot = qbar * base.SC_IY * cm + base.THRUST_MOMENT * thrust
    return jnp.stack([vdot, alphadot, q, qdot])


def outputs(t, x, u, p):
    v, alpha, theta, q = x
    qbar, cd, cl, cm, _ = _terms(x, u, p)
    thrust = u[1]
    cx = cl * jnp.sin(alpha) - cd * jnp.cos(alpha)
    cz = -cl * jnp.cos(alpha) - cd * jnp.sin(alpha)
    ax = qbar * base.S_M * cx + thrust / base.MASS * jnp.cos(base.SIGMA_T)
    az = qbar * base.S_M * cz - thrust / base.MASS * jnp.sin(base.SIGMA_T)
    qdot = qbar * base.SC_IY * cm + base.THRUST_MOMENT * thrust
    y = jnp.stack([v, alpha, theta, q, qdot, ax, az])
    return y + p[N_BASE + 4 :]


def diagnose_missing_pitch_damping(data) -> dict:
    """Fit without CMq, score every candidate; returns the ranking (best first)."""
    n = len(data["T"])
    problem = dp.OEMProblem(
        rates=rates,
        outputs=outputs,
        t0=float(data["T"][0]),
        dt=float(data["T"][1] - data["T"][0]),
        inputs=jnp.asarray(np.column_stack([data["DELV"], data["THRUST"]])),
        measured=jnp.asarray(np.column_stack([data[c] for c in base.OUTPUTS])),
        free=(True,) * (N_BASE + 4 + len(base.OUTPUTS)),
        node_interval=n,
        state_scale=jnp.ones(4),
    )
    theta0 = np.zeros(N_BASE + 4 + len(base.OUTPUTS))
    theta0[:N_BASE] = base.START
    cmq = base.NAMES.index("CMq")
    theta0[cmq] = 0.0
    free = np.zeros_like(theta0, bool)
    free[:N_BASE] = True
    free[cmq] = False
    fit = dp.fit_global_oem(
        problem, jnp.asarray(theta0), jnp.asarray([base.X0]), jnp.asarray(free)
    )
    index = [cmq] + list(range(N_BASE, len(theta0)))
    st = dp.score_test(problem, fit, index)
    fall = 1.0 - np.asarray(st.cost_ratio)
    p = np.minimum(1.0, np.asarray(st.p_value) * len(index))
    order = np.argsort(-fall)
    ranking = [
        {
            "effect": CANDIDATES[i][0],
            "parameter": CANDIDATES[i][1],
            "cost_reduction": float(fall[i]),
            "p_value": float(p[i]),
            "estimate": float(st.estimate[i]),
            "stderr": float(st.stderr[i]),
        }
        for i in order
    ]
    return {
        "cost": float(fit.cost),
        "converged": bool(fit.converged),
        "ranking": ranking,
        "significant": [
            r["effect"]
            for r in ranking
            if r["p_value"] < 0.01 and r["cost_reduction"] >= 0.05
        ],
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", type=pathlib.Path, default=base.DEFAULT_DATA)
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/hfb320")
    )
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    result = diagnose_missing_pitch_damping(dp.read_asc(args.data))
    print(f"HFB-320 without CMq: det(R) = {result['cost']:.4g}")
    for r in result["ranking"]:
        print(
            f"{r['effect']:>22s} cost fall {100 * r['cost_reduction']:5.1f}%  "
            f"p {r['p_value']:.2g}  {r['parameter']} = {r['estimate']:.4g} +/- {r['stderr']:.2g}"
        )
    (args.out / "diagnosis.json").write_text(json.dumps(result, indent=2))
    print(json.dumps({k: result[k] for k in ("ranking", "significant")}))


if __name__ == "__main__":
    main()
