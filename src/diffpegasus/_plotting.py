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
    for ax, (label, series) in zip(axes.flat, panels, strict=True):
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


def plot_estimates(estimates, path: str | os.PathLike, units: str = "deg") -> None:
    """The six derivatives per window against the window-mean truth (if known), with
    +/- 2 standard-error bands and windows without an estimate of their own marked."""
    from ._aerodynamics import DERIVATIVE_NAMES

    scale = np.pi / 180 if units == "deg" else 1.0
    mid = 0.5 * (np.asarray(estimates.window_start) + np.asarray(estimates.window_end))
    values = np.asarray(estimates.values) * scale
    valid = np.asarray(estimates.valid)
    fig, axes = plt.subplots(3, 2, figsize=(12, 9), sharex=True)
    for j, (ax, name) in enumerate(zip(axes.flat, DERIVATIVE_NAMES, strict=True)):
        if estimates.truth is not None:
            ax.plot(
                mid,
                np.asarray(estimates.truth)[:, j] * scale,
                "k-",
                lw=1.2,
                label="truth (window mean)",
            )
        ax.plot(
            mid,
            values[:, j],
            ".-",
            ms=3,
            lw=0.6,
            label=f"{estimates.method.upper()} estimate",
        )
        if estimates.stderr is not None:
            s = np.asarray(estimates.stderr)[:, j] * scale
            ax.fill_between(
                mid,
                values[:, j] - 2 * s,
                values[:, j] + 2 * s,
                alpha=0.25,
                lw=0,
                label="±2 std. err.",
            )
        if (~valid).any():
            ax.plot(
                mid[~valid], values[~valid, j], "rx", ms=4, label="held / no estimate"
            )
        ax.set_ylabel(f"{name}, 1/{units}")
        ax.grid(alpha=0.3)
    axes.flat[0].legend(loc="best", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("time since drop, s")
    fig.suptitle(f"{estimates.method.upper()} derivative estimates per window")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
