"""Which within-window structure of the derivatives removes the OEM's secant bias?

Issue 15 item 4. On one noise-free campaign flight (seed 0, flight `--flight`), each
coefficient `C = c(t) alpha + d(t) de` (CL, CD, CM; `c` the alpha derivative, `d` the
elevator derivative, both the database's secant values along the flight) is fitted by
linear least squares at the OEM's 200 Hz model samples, for several
parameterisations of `c(t)` and `d(t)`:

- `lin`: continuous and linear in time between window boundaries (`linear`);
- `const`: constant per window (the thesis's model);
- `+tau`, `+alpha`: per window a change with time in the window (`tau`, mean zero)
  and with alpha about the window's mean alpha (the window terms of
  `parameters="window"`); `win` is `const+tau+alpha`.

Printed: the rms over the counted windows (from ignition, mean qbar >= 2 kPa) of the
window mean of the fitted `c`, `d` minus the window-mean truth (1/rad). No noise and
no dynamics: what remains is the structure's own error (the OEM adds noise and the
states). `hybrid` is `c: win, d: lin` for CL and CD, `lin` for CM.

    python experiments/oem_structure.py [--flight 0]
"""

import argparse
import dataclasses

import jax


jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import diffpegasus as dp  # noqa: E402
import diffpegasus._campaign._montecarlo as mc  # noqa: E402
from diffpegasus._simulate._sensors import SensorModel  # noqa: E402


STRUCTURES = [
    ("lin", "lin"),
    ("lin+alpha", "lin"),
    ("lin+alpha", "lin+alpha"),
    ("const", "const"),
    ("const+tau", "const+tau"),
    ("win", "const"),
    ("win", "const+tau"),
    ("win", "win"),
    ("win", "lin"),
]


def basis(kind, win, frac, tau, da, nw):
    """Columns of one parameter's time function at the model samples."""
    n, cols = len(win), []
    if kind.startswith("lin"):  # hat functions, knots at the window boundaries
        for k in range(nw + 1):
            c = np.zeros(n)
            c[win == k] += 1 - frac[win == k]
            c[win == k - 1] += frac[win == k - 1]
            cols.append(c)
    if kind.startswith(("const", "win")):
        cols += [(win == k).astype(float) for k in range(nw)]
    if "tau" in kind or kind.startswith("win"):
        cols += [np.where(win == k, tau, 0.0) for k in range(nw)]
    if "alpha" in kind or kind.startswith("win"):
        cols += [np.where(win == k, da, 0.0) for k in range(nw)]
    return np.array(cols).T


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--flight", type=int, default=0)
    i = parser.parse_args().flight
    camp = mc.Campaign(samples=i + 1, batch=1)
    keys, pert = mc.draws(camp)
    cfg = dataclasses.replace(camp.config, sensors=SensorModel.noise_free())
    idx1 = jnp.arange(i, i + 1)
    log = dp.flight_to_log(
        mc._take(dp.simulate_batch(cfg, keys[idx1], mc._take(pert, idx1)), 0)
    )
    per = int(round(camp.window * log.sample_rate))
    nw = len(log) // per
    idx = np.arange(0, nw * per, camp.decimate)
    win = idx // per
    m = per // camp.decimate
    j = np.arange(len(idx)) % m
    tau, frac = (j + 0.5) / m - 0.5, j / m

    def wmean(x):
        return x[: nw * per].reshape(nw, per).mean(axis=1)

    alpha, de = log["alpha"][idx], log["de"][idx]
    da = alpha - wmean(log["alpha"])[win]
    start = np.arange(nw) * camp.window
    count = (start >= camp.ignition) & (wmean(log["qbar"]) >= camp.min_qbar)
    keep = count[win]
    for coef in ("CL", "CD", "CM"):
        ta, td = log[f"true_{coef}a"], log[f"true_{coef}de"]
        y = ta[idx] * alpha + td[idx] * de
        for kc, kd in STRUCTURES:
            bc = basis(kc, win, frac, tau, da, nw)
            bd = basis(kd, win, frac, tau, da, nw)
            x = np.hstack([bc * alpha[:, None], bd * de[:, None]])
            th, *_ = np.linalg.lstsq(x[keep], y[keep], rcond=None)
            c, d = bc @ th[: bc.shape[1]], bd @ th[bc.shape[1] :]
            errs = []
            for fit, truth in ((c, ta), (d, td)):
                mean = np.array([fit[win == k].mean() for k in range(nw)])
                errs.append(np.sqrt(np.mean((mean - wmean(truth))[count] ** 2)))
            print(
                f"{coef}  c: {kc:10s} d: {kd:10s} rms error {coef}a {errs[0]:.4f}"
                f"  {coef}de {errs[1]:.4f}  (1/rad)"
            )


if __name__ == "__main__":
    main()
