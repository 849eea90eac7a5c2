"""Figures a person would rather look at than read."""

import os

import matplotlib


matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ._log import FlightLog  # noqa: E402


def plot_trajectory(log: FlightLog, path: str | os.PathLike) -> None:
    """Altitude, Mach, alpha, elevator, dynamic pressure, thrust, mass and CG/cp
    against time, as one PNG."""
    t = log.t
    panels = [
        ("altitude, km", [(log["h"] / 1e3, None)]),
        ("Mach", [(log["mach"], None)]),
        ("angle of attack, deg", [(np.rad2deg(log["alpha"]), None)]),
        ("elevator, deg", [(np.rad2deg(log["de"]), None)]),
        ("dynamic pressure, kPa", [(log["qbar"] / 1e3, None)]),
        ("net thrust, kN", [(log["thrust"] / 1e3, None)]),
        ("mass, t", [(log["mass"] / 1e3, None)]),
        ("station from nose, m", [(log["xcg"], "CG"), (log["xcp"], "cp")]),
    ]
    fig, axes = plt.subplots(4, 2, figsize=(11, 11), sharex=True)
    for ax, (label, series) in zip(axes.flat, panels):
        for y, name in series:
            ax.plot(t, y, lw=0.8, label=name)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        if any(name for _, name in series):
            ax.legend(loc="best")
    for ax in axes[-1]:
        ax.set_xlabel("time since drop, s")
    title = log.metadata.get("title", "Simulated Pegasus first-stage flight")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
