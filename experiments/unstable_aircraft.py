"""Unstable short-period aircraft (SPEC section 7): single vs multiple shooting OEM.

Model (`examples/unstable_aircraft.py`, a model-definition file): w' = Zw w + (u0 +
Zq) q + Zde de, q' = Mw w + Mq q + Mde de; outputs az, w, q with az = Zw w + Zq q +
Zde de; u0 = 44.5695 m/s, Zq held at -1.4768, initial state zero. Data:
`shared/data/unstable_aircraft/unStabAC_sim.asc` (12.5 s at 20 Hz).
The last stdout line is one JSON object `{"single": {...}, "multiple": {...}}`.

Run: `python experiments/unstable_aircraft.py [--data FILE] [--out DIR]`.
"""

import argparse
import json
import pathlib

import matplotlib
import numpy as np


matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from _shared import shared_data  # noqa: E402

import diffpegasus as dp  # noqa: E402


DEFAULT_DATA = shared_data("unstable_aircraft/unStabAC_sim.asc")
U0 = 44.5695  # m/s, the model file's trim speed (for the eigenvalues)
MODEL_FILE = (
    pathlib.Path(__file__).resolve().parents[1] / "examples" / "unstable_aircraft.py"
)


def fit(path=DEFAULT_DATA, node_interval: float | None = None):
    """The fit with single shooting (`node_interval=None`) or multiple shooting with
    a node every `node_interval` s, and a JSON-ready summary."""
    spec = dp.load_model_file(MODEL_FILE)
    record = dp.load_record(spec.model, path, spec.columns, x0=spec.x0)
    shooting = (
        dp.SingleShooting()
        if node_interval is None
        else dp.MultipleShooting(interval=node_interval)
    )
    res = dp.fit(spec.model, record, shooting=shooting, throw=False)
    p = res.estimates()
    a = np.array([[p["Zw"], U0 + p["Zq"]], [p["Mw"], p["Mq"]]])
    eig = np.linalg.eigvals(a)
    rms = np.sqrt(np.mean((record.measured - res.outputs[0]) ** 2, axis=0))
    scale = np.sqrt(np.mean(record.measured**2, axis=0)) + np.sqrt(
        np.mean(res.outputs[0] ** 2, axis=0)
    )
    tic = rms / scale
    return res, {
        "params": {n: v for n, v in p.items() if n != "Zq"},
        "stderr": {
            n: float(v)
            for n, v, free in zip(
                res.model.parameters, res.stderr, res.free, strict=True
            )
            if free
        },
        "cost": res.cost,
        "converged": res.converged,
        "message": res.message,
        "tic": dict(zip(res.model.outputs, tic.tolist(), strict=True)),
        "poor_fit": bool(np.any(tic > 0.3)),
        "iterations": res.iterations,
        "eigenvalues": {"real": eig.real.tolist(), "imag": eig.imag.tolist()},
        "max_continuity_defect": res.defect,
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
    single_res, single = fit(args.data)
    multi_res, multiple = fit(args.data, args.node_interval)
    record = single_res.records[0]
    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    for j, (ax, label) in enumerate(
        zip(axes, ["az, m/s^2", "w, m/s", "q, rad/s"], strict=True)
    ):
        z = record.measured[:, j]
        ax.plot(record.t, z, "k.", ms=3, label="measured")
        ys = single_res.outputs[0][:, j]
        ax.plot(
            record.t,
            np.where(np.abs(ys) < 10 * np.abs(z).max(), ys, np.nan),
            "-",
            label="single shooting",
        )
        ax.plot(record.t, multi_res.outputs[0][:, j], "-", label="multiple shooting")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend()
    axes[-1].set_xlabel("time, s")
    fig.suptitle("Unstable aircraft: output-error fits")
    fig.tight_layout()
    fig.savefig(args.out / "fits.png", dpi=110)
    plt.close(fig)
    print("multiple shooting:")
    names = multi_res.model.parameters
    print(
        dp.format_parameter_table(
            dp.parameter_table(
                names, multi_res.params, multi_res.stderr, multi_res.free
            )
        )
    )
    summary = {"single": single, "multiple": multiple}
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
