"""Figures of the discrepancy workflow: fits, residuals by regime, the ranking."""

import os

import matplotlib


matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .._diagnose._workflow import channel_noise, FlightFit  # noqa: E402
from .._files import save_figure  # noqa: E402


# display unit of every output channel: (label, factor from SI)
_DISPLAY = {
    "ax": ("ax, m/s^2", 1.0),
    "az": ("az, m/s^2", 1.0),
    "q": ("q, deg/s", np.rad2deg(1.0)),
    "qdot": ("qdot, deg/s^2", np.rad2deg(1.0)),
    "alpha": ("alpha, deg", np.rad2deg(1.0)),
    "V": ("V, m/s", 1.0),
    "theta": ("theta, deg", np.rad2deg(1.0)),
    "h": ("h, km", 1e-3),
}


def plot_fits(
    fits: list[tuple[str, FlightFit]], path: str | os.PathLike, title: str = ""
) -> None:
    """Measured and model outputs against time (left) and the residuals (right) for
    every channel; several fits (e.g. before and after adding an effect) overlaid."""
    first = fits[0][1]
    t = first.t
    OUTPUTS = first.outputs
    fig, axes = plt.subplots(
        len(OUTPUTS), 2, figsize=(13, 2.0 * len(OUTPUTS)), sharex=True
    )
    for i, name in enumerate(OUTPUTS):
        label, f = _DISPLAY.get(name, (f"{name}, SI", 1.0))
        ax, axr = axes[i]
        ax.plot(t, first.measured[:, i] * f, color="0.6", lw=0.6, label="measured")
        for tag, fit in fits:
            ax.plot(t, fit.model[:, i] * f, lw=0.9, label=f"model ({tag})")
            rms = np.sqrt(np.mean(fit.residuals[:, i] ** 2)) * f
            axr.plot(t, fit.residuals[:, i] * f, lw=0.5, label=f"{tag}: rms {rms:.3g}")
        ax.set_ylabel(label)
        axr.set_ylabel("residual")
        axr.legend(loc="upper right", fontsize=7)
        ax.grid(alpha=0.3)
        axr.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time, s")
    fig.suptitle(title or "measured vs model")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def plot_regimes(fit: FlightFit, path: str | os.PathLike) -> None:
    """Residuals over the noise sigma of every channel against the flight
    condition (alpha, airspeed, altitude, where the model has them), thrust on
    and off in two colours (where the model reads thrust)."""
    variables = [
        (label, fit.channel(name) * factor)
        for name, label, factor in (
            ("alpha", "alpha, deg", np.rad2deg(1.0)),
            ("V", "airspeed, m/s", 1.0),
            ("h", "altitude, km", 1e-3),
        )
        if fit.channel(name) is not None
    ]
    thrust = fit.channel("thrust")
    if thrust is not None and np.max(np.abs(thrust)) > 0:
        on = thrust > 0.01 * np.max(np.abs(thrust))
    else:
        on = np.zeros(len(fit.t), bool)
    noise = channel_noise(fit)
    outputs = fit.outputs
    fig, axes = plt.subplots(
        len(outputs),
        max(1, len(variables)),
        figsize=(12, 1.8 * len(outputs)),
        sharex="col",
        squeeze=False,
    )
    for i, name in enumerate(outputs):
        sigma = noise[i] or 1.0
        r = fit.residuals[:, i] / sigma
        for j, (xlabel, x) in enumerate(variables):
            ax = axes[i, j]
            ax.scatter(x[on], r[on], s=1, color="tab:red", label="thrust on")
            ax.scatter(x[~on], r[~on], s=1, color="tab:blue", label="thrust off")
            ax.axhline(2, color="0.5", lw=0.5, ls="--")
            ax.axhline(-2, color="0.5", lw=0.5, ls="--")
            if j == 0:
                ax.set_ylabel(f"{name} / noise")
            if i == len(outputs) - 1:
                ax.set_xlabel(xlabel)
    axes[0, 0].legend(loc="upper right", fontsize=7, markerscale=5)
    fig.suptitle("where the model fails: residual / noise sigma by flight regime")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def plot_ranking(diagnosis: dict, path: str | os.PathLike) -> None:
    """Predicted fall of the output-error cost per candidate effect."""
    ranking = diagnosis["ranking"]
    names = [r["effect"] for r in ranking][::-1]
    values = [100 * max(r["cost_reduction"], 0.0) for r in ranking][::-1]
    colours = ["tab:red" if r["significant"] else "0.6" for r in ranking][::-1]
    fig, ax = plt.subplots(figsize=(8, 0.3 * len(names) + 1.5))
    ax.barh(names, values, color=colours)
    ax.set_xlabel("predicted fall of the output-error cost det(R), %")
    ax.set_title("diagnosis: which effect explains the misfit (red: significant)")
    ax.grid(alpha=0.3, axis="x")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
