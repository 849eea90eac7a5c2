"""Figures of the discrepancy workflow: fits, residuals by regime, the ranking."""

import os

import matplotlib


matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .._diagnose._workflow import channel_noise, FlightFit  # noqa: E402
from .._files import save_figure  # noqa: E402


def worst_window(fit: FlightFit, length: float | None = None) -> tuple[float, float]:
    """The stretch of the record, `(start, end)` in s, where the residuals over each
    channel's noise are largest (mean square over the channels and the stretch);
    `length` defaults to a tenth of the record, at least 20 samples."""
    t = np.asarray(fit.t)
    n = len(t)
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    width = n // 10 if length is None else int(round(length / dt))
    width = int(min(n, max(20, width)))
    noise = np.asarray(channel_noise(fit), float)
    noise = np.where(np.isfinite(noise) & (noise > 0), noise, 1.0)
    z = np.mean((np.asarray(fit.residuals) / noise) ** 2, axis=1)
    sums = np.convolve(z, np.ones(width), mode="valid")
    i = int(np.argmax(sums)) if sums.size else 0
    return float(t[i]), float(t[min(n - 1, i + width - 1)])


def plot_fits(
    fits: list[tuple[str, FlightFit]], path: str | os.PathLike, title: str = ""
) -> None:
    """Measured and model outputs against time over the whole record (left), the
    residuals (middle) and a zoom on the stretch where the first fit fails most
    (right, shaded on the others) for every channel, in the log's own units
    ([`channel_units`][]); several fits (e.g. before and after adding an effect)
    overlaid."""
    from ._units import channel_units

    first = fits[0][1]
    t = first.t
    outputs = first.outputs
    units = channel_units(outputs, first.spec.columns)
    t0, t1 = worst_window(first)
    zoom = (t >= t0) & (t <= t1)
    fig, axes = plt.subplots(
        len(outputs),
        3,
        figsize=(15, 2.0 * len(outputs) + 0.6),
        sharex="col",
        squeeze=False,
        gridspec_kw={"width_ratios": [3, 3, 2]},
    )
    for i, name in enumerate(outputs):
        unit, f = units[name]
        ax, axr, axz = axes[i]
        ax.plot(t, first.measured[:, i] * f, color="0.6", lw=0.6, label="measured")
        axz.plot(
            t[zoom], first.measured[zoom, i] * f, color="0.4", lw=0.9, label="measured"
        )
        for tag, fit in fits:
            ax.plot(t, fit.model[:, i] * f, lw=0.9, label=f"model ({tag})")
            axz.plot(t[zoom], fit.model[zoom, i] * f, lw=1.1, label=f"model ({tag})")
            rms = np.sqrt(np.mean(fit.residuals[:, i] ** 2)) * f
            axr.plot(
                t, fit.residuals[:, i] * f, lw=0.5, label=f"{tag}: rms {rms:.3g} {unit}"
            )
        for a in (ax, axr):
            a.axvspan(t0, t1, color="tab:orange", alpha=0.15, lw=0)
        ax.set_ylabel(f"{name}, {unit}")
        axr.set_ylabel(f"residual, {unit}")
        axz.set_ylabel(f"{name}, {unit}")
        axr.legend(loc="upper right", fontsize=7)
        for a in (ax, axr, axz):
            a.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=7)
    axes[0, 0].set_title("whole record")
    axes[0, 1].set_title("residual: measured minus model")
    axes[0, 2].set_title(f"zoom on the worst fit: {t0:.4g}-{t1:.4g} s")
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
