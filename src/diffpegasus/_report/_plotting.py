"""Figures a person would rather look at than read."""

import os

import matplotlib


matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .._files import save_figure  # noqa: E402
from .._log._format import FlightLog  # noqa: E402


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
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def plot_estimates(estimates, path: str | os.PathLike, units: str = "deg") -> None:
    """The six derivatives per window against the window-mean truth (if known), with
    +/- 2 standard-error bands and windows without an estimate of their own marked."""
    from .._vehicle._pegasus._aerodynamics import DERIVATIVE_NAMES

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
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def plot_campaign(mse: dict, out) -> None:
    """Monte Carlo figures from per-flight MSEs `{method: (flights, 6)}`: box plots
    (thesis Figs 6.4-6.6) and distributions (thesis Figs 6.1-6.3) of log10 MSE per
    derivative, one colour per method."""
    import pathlib

    from .._vehicle._pegasus._aerodynamics import DERIVATIVE_NAMES

    labels = {"lse": "LSE", "nn": "NN+LSE", "oem": "OEM"}
    out = pathlib.Path(out)
    methods = list(mse)
    fig, axes = plt.subplots(3, 2, figsize=(11, 10))
    for j, (ax, name) in enumerate(zip(axes.flat, DERIVATIVE_NAMES, strict=True)):
        data = [np.log10(v[:, j][np.isfinite(v[:, j])]) for v in mse.values()]
        ax.boxplot(data, tick_labels=[labels[m] for m in methods])
        ax.set_ylabel(f"log10 MSE {name}, (1/deg)^2")
        ax.grid(alpha=0.3)
    fig.suptitle("Per-flight MSE of the window estimates (thesis Figs 6.4-6.6)")
    fig.tight_layout()
    save_figure(fig, out / "fig6_4_6_boxplots.png", dpi=110)
    plt.close(fig)
    fig, axes = plt.subplots(3, 2, figsize=(11, 10))
    for j, (ax, name) in enumerate(zip(axes.flat, DERIVATIVE_NAMES, strict=True)):
        finite = [np.log10(v[:, j][np.isfinite(v[:, j])]) for v in mse.values()]
        lo = min(x.min() for x in finite if x.size)
        hi = max(x.max() for x in finite if x.size)
        bins = np.linspace(lo, hi + 1e-9, 30)
        for m, x in zip(methods, finite, strict=True):
            ax.hist(x, bins=bins, alpha=0.5, label=labels[m])
        ax.set_xlabel(f"log10 MSE {name}, (1/deg)^2")
        ax.set_ylabel("flights")
        ax.grid(alpha=0.3)
    axes.flat[0].legend()
    fig.suptitle("Distributions of the per-flight MSE (thesis Figs 6.1-6.3)")
    fig.tight_layout()
    save_figure(fig, out / "fig6_1_3_distributions.png", dpi=110)
    plt.close(fig)


def plot_design(design, result: dict, out) -> None:
    """Input design figures: the excitations and the alpha response
    (`design_inputs.png`), and the predicted standard errors per derivative and
    input (`design_stderr.png`)."""
    import pathlib

    from .._design._optimal import simulate_outputs
    from .._vehicle._pegasus._aerodynamics import DERIVATIVE_NAMES

    out = pathlib.Path(out)
    t = np.asarray(design.times)
    names = list(result["inputs"])
    fig, axes = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    base = np.asarray(simulate_outputs(design, None))[:, design.excursion_output]
    for name in names:
        exc = result["inputs"][name]
        e = np.rad2deg(np.asarray([exc(s) for s in t]))
        y = np.asarray(simulate_outputs(design, exc))[:, design.excursion_output]
        lw = 1.6 if name == "optimised" else 0.8
        axes[0].plot(t, e, lw=lw, label=name)
        axes[1].plot(t, np.rad2deg(y - base), lw=lw, label=name)
    axes[0].set_ylabel("excitation, deg")
    axes[1].set_ylabel("alpha response, deg")
    axes[1].set_xlabel("time since drop, s")
    axes[0].legend(ncol=3)
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle("Elevator excitations under the same limits")
    fig.tight_layout()
    save_figure(fig, out / "design_inputs.png", dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(10, 5))
    width = 0.8 / len(names)
    x = np.arange(6)
    for i, name in enumerate(names):
        sd = np.asarray(result["rows"][name]["stderr"]) * np.pi / 180
        ax.bar(x + i * width, sd, width, label=name)
    ax.set_xticks(x + 0.4 - width / 2, DERIVATIVE_NAMES)
    ax.set_yscale("log")
    ax.set_ylabel("predicted standard error, 1/deg")
    ax.legend(ncol=3)
    ax.grid(alpha=0.3, axis="y")
    ax.set_title("Cramér-Rao standard errors by input (lower is better)")
    fig.tight_layout()
    save_figure(fig, out / "design_stderr.png", dpi=110)
    plt.close(fig)
