"""Figures of a frequency-domain fit and of a recursive replay (PNG, units on every
axis)."""

import pathlib

import numpy as np


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def coherence(record, nperseg: int | None = None):
    """Ordinary coherence `(frequencies,)` Hz and `(frequencies, outputs, inputs)` of
    every measured output with every input (Welch, segments of a quarter of the
    record): near 1 where an output is linearly related to that input, low where
    noise, nonlinearity or other inputs dominate."""
    from scipy.signal import coherence as welch_coherence

    n = len(record.t)
    nperseg = nperseg or max(16, n // 4)
    fs = 1.0 / record.dt
    out = []
    for j in range(record.measured.shape[1]):
        row = []
        for i in range(record.inputs.shape[1]):
            f, c = welch_coherence(
                record.inputs[:, i], record.measured[:, j], fs=fs, nperseg=nperseg
            )
            row.append(np.nan_to_num(c))
        out.append(row)
    return f, np.array(out).transpose(2, 0, 1)


def plot_bode(fit, out, units: dict[str, str] | None = None, record: int = 0):
    """Write `bode.png` (per output: magnitude in dB and phase in degrees of the
    measured and the model output transforms against frequency) and
    `residual_spectrum.png` (per output: the residual power over the band, and the
    coherence of the output with each input) for a [`FrequencyFit`][] into the
    folder `out`. `units` maps a channel name to its unit for the labels.

    **Returns:** the paths written.
    """
    plt = _plt()
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    units = units or {}
    model = fit.model
    f = fit.frequencies[record]
    z, y = fit.measured[record], fit.modelled[record]
    ny = len(model.outputs)
    fig, axes = plt.subplots(2, ny, figsize=(3.2 * ny, 5.5), squeeze=False)
    for j, name in enumerate(model.outputs):
        unit = units.get(name, "unit")
        ax = axes[0, j]
        ax.semilogx(f, 20 * np.log10(np.abs(z[:, j]) + 1e-300), ".", label="measured")
        ax.semilogx(f, 20 * np.log10(np.abs(y[:, j]) + 1e-300), "-", label="model")
        ax.set_title(name)
        ax.set_ylabel(f"|{name}(f)|, dB re 1 {unit} s")
        ax.grid(True, which="both", alpha=0.3)
        ax = axes[1, j]
        ax.semilogx(f, np.degrees(np.angle(z[:, j])), ".", label="measured")
        ax.semilogx(f, np.degrees(np.angle(y[:, j])), "-", label="model")
        ax.set_ylabel("phase, deg")
        ax.set_xlabel("frequency, Hz")
        ax.set_ylim(-180, 180)
        ax.grid(True, which="both", alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(
        f"{fit.method}: {fit.records[record].name}, model and measured Fourier transforms"
    )
    fig.tight_layout()
    paths = [out / "bode.png"]
    fig.savefig(paths[0], dpi=110)
    plt.close(fig)

    fc, coh = coherence(fit.records[record])
    resid = fit.residual_spectrum(record)
    fig, axes = plt.subplots(2, ny, figsize=(3.2 * ny, 5.0), squeeze=False)
    for j, name in enumerate(model.outputs):
        unit = units.get(name, "unit")
        ax = axes[0, j]
        ax.semilogy(f, resid[:, j], ".-")
        ax.axhline(fit.noise[j], color="k", lw=0.8, ls="--", label="band mean")
        ax.set_title(name)
        ax.set_ylabel(f"residual power, ({unit} s)^2")
        ax.set_xlabel("frequency, Hz")
        ax.grid(True, alpha=0.3)
        ax = axes[1, j]
        for i, inp in enumerate(model.inputs):
            ax.plot(fc, coh[:, j, i], label=inp)
        ax.axvspan(f[0], f[-1], color="0.9", zorder=0)
        ax.set_ylim(0, 1.05)
        ax.set_ylabel("coherence, -")
        ax.set_xlabel("frequency, Hz")
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    axes[1, 0].legend(fontsize=8)
    fig.suptitle(
        "residual spectrum (top) and input-output coherence (bottom; band shaded)"
    )
    fig.tight_layout()
    paths.append(out / "residual_spectrum.png")
    fig.savefig(paths[1], dpi=110)
    plt.close(fig)
    return paths


def plot_history(
    t,
    theta,
    halfwidth,
    names,
    path,
    *,
    reference: dict[str, float] | None = None,
    truth: np.ndarray | None = None,
    units: dict[str, str] | None = None,
    title: str = "",
):
    """Every estimate against time with its 95% band (`theta +- halfwidth`, `(n,
    p)`), and optional horizontal reference values (e.g. a batch fit) or a true
    time history `(n, p)`, in one PNG at `path`."""
    plt = _plt()
    t, theta, halfwidth = (np.asarray(a) for a in (t, theta, halfwidth))
    p = len(names)
    cols = min(3, p)
    rows = -(-p // cols)
    fig, axes = plt.subplots(
        rows, cols, figsize=(4.2 * cols, 2.6 * rows), squeeze=False
    )
    units = units or {}
    for k, name in enumerate(names):
        ax = axes.flat[k]
        lo = theta[:, k] - halfwidth[:, k]
        hi = theta[:, k] + halfwidth[:, k]
        ax.fill_between(t, lo, hi, color="C0", alpha=0.25, lw=0, label="95% band")
        ax.plot(t, theta[:, k], "C0", lw=1.0, label="recursive")
        if truth is not None:
            ax.plot(t, truth[:, k], "k--", lw=1.0, label="truth")
        if reference and name in reference:
            ax.axhline(reference[name], color="C3", lw=1.0, label="batch")
        finite = np.concatenate([theta[:, k][np.isfinite(theta[:, k])]])
        if finite.size:
            centre = np.median(finite[len(finite) // 2 :])
            spread = np.nanpercentile(np.abs(finite - centre), 90) * 3 + 1e-12
            ax.set_ylim(centre - spread, centre + spread)
        ax.set_title(name)
        ax.set_xlabel("time, s")
        ax.set_ylabel(units.get(name, "parameter units"))
        ax.grid(True, alpha=0.3)
    for ax in list(axes.flat)[p:]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
