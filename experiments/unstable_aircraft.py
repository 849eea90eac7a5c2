"""Unstable short-period aircraft (SPEC section 7): single vs multiple shooting OEM.

Model: w' = Zw w + (u0 + Zq) q + Zde de, q' = Mw w + Mq q + Mde de; outputs az, w, q
with az = Zw w + Zq q + Zde de; u0 = 44.5695 m/s, Zq fixed at -1.4768, initial state
zero. Data: `shared/data/unstable_aircraft/unStabAC_sim.asc` (12.5 s at 20 Hz).
The last stdout line is one JSON object `{"single": {...}, "multiple": {...}}`.

Run: `python experiments/unstable_aircraft.py [--data FILE] [--out DIR]`.
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


U0 = 44.5695
NAMES = ["Zw", "Zq", "Zde", "Mw", "Mq", "Mde"]
START = jnp.array([-1.22871, -1.4768, -4.20491, 0.116197, -2.70670, -18.7718])
FREE = (True, False, True, True, True, True)
DEFAULT_DATA = shared_data("unstable_aircraft/unStabAC_sim.asc")


def rates(t, x, u, p):
    zw, zq, zde, mw, mq, mde = p
    w, q = x
    return jnp.stack(
        [zw * w + (U0 + zq) * q + zde * u[0], mw * w + mq * q + mde * u[0]]
    )


def outputs(t, x, u, p):
    zw, zq, zde = p[0], p[1], p[2]
    w, q = x
    return jnp.stack([zw * w + zq * q + zde * u[0], w, q])


def problem(data, node_interval=None):
    z = np.column_stack([data["AZ"], data["W"], data["Q"]])
    return dp.OEMProblem(
        rates=rates,
        outputs=outputs,
        t0=float(data["T"][0]),
        dt=float(data["T"][1] - data["T"][0]),
        inputs=jnp.asarray(data["DE"])[:, None],
        measured=jnp.asarray(z),
        free=FREE,
        node_interval=node_interval,
        state_scale=jnp.array([1.0, 0.1]),
    )


def fit(data, node_interval=None):
    prob = problem(data, node_interval)
    idx = dp.node_times(prob)
    nodes = np.column_stack([data["W"], data["Q"]])[idx]
    nodes[0] = 0.0
    res = dp.fit_oem(prob, START, jnp.asarray(nodes))
    p = np.asarray(res.params[0])
    a = np.array([[p[0], U0 + p[1]], [p[3], p[4]]])
    eig = np.linalg.eigvals(a)
    ok = bool(res.converged) and bool(np.isfinite(float(res.cost)))
    return res, {
        "params": {n: float(v) for n, v in zip(NAMES, p, strict=True) if n != "Zq"},
        "stderr": {
            n: float(v)
            for n, v in zip(NAMES, np.asarray(res.stderr[0]), strict=True)
            if n != "Zq"
        },
        "cost": float(res.cost),
        "converged": ok,
        "poor_fit": bool(res.poor_fit),
        "failed": (not ok) or bool(res.poor_fit),
        "tic": {
            n: float(v)
            for n, v in zip(["az", "w", "q"], np.asarray(res.tic), strict=True)
        },
        "iterations": int(res.iterations),
        "eigenvalues": {"real": eig.real.tolist(), "imag": eig.imag.tolist()},
        "max_continuity_defect": float(res.defect),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", type=pathlib.Path, default=DEFAULT_DATA)
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/unstable_aircraft")
    )
    parser.add_argument(
        "--node-interval", type=float, default=1.0, help="s between shooting nodes"
    )
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    data = dp.read_asc(args.data)
    dt = float(data["T"][1] - data["T"][0])
    single_res, single = fit(data)
    multi_res, multiple = fit(data, int(round(args.node_interval / dt)))
    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    z = np.column_stack([data["AZ"], data["W"], data["Q"]])
    for j, (ax, label) in enumerate(
        zip(axes, ["az, m/s^2", "w, m/s", "q, rad/s"], strict=True)
    ):
        ax.plot(data["T"], z[:, j], "k.", ms=3, label="measured")
        ys = np.asarray(single_res.outputs)[:, j]
        ax.plot(
            data["T"],
            np.where(np.abs(ys) < 10 * np.abs(z[:, j]).max(), ys, np.nan),
            "-",
            label="single shooting",
        )
        ax.plot(
            data["T"],
            np.asarray(multi_res.outputs)[:, j],
            "-",
            label="multiple shooting",
        )
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend()
    axes[-1].set_xlabel("time, s")
    fig.suptitle("Unstable aircraft: output-error fits")
    fig.tight_layout()
    fig.savefig(args.out / "fits.png", dpi=110)
    plt.close(fig)
    print("multiple shooting:")
    print(
        dp.format_parameter_table(
            dp.parameter_table(NAMES, multi_res.params[0], multi_res.stderr[0], FREE)
        )
    )
    summary = {"single": single, "multiple": multiple}
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
