"""Where the recursive Fourier transform's bound departs from the scatter: the
bound of the short-period Monte Carlo (`recursive_coverage.py`'s flights and
model) recomputed after the flight in NumPy, one piece at a time.

For every flight: the transforms of the regression at the end of the record, the
equations weighted by their residual power, the complex least squares (with the
state equations' two end terms or without), and the leakage sandwich with the
residual transforms taken

- `truth`: at the true parameters (the end terms at their estimate): what the
  bound would be if the residuals were the errors;
- `fitted`: at the estimate, no correction;
- `corrected`: at the estimate with the fitted residuals' loss `H_f V H_f^H`
  solved for (the estimator's bound);
- `leverage`: at the estimate with each frequency's own first-order loss,
  `S_f = T_f + L_f T_f + T_f L_f^H - H_f V H_f^H`, `L_f = H_f P A_f^H` (tried,
  not adopted: see the recursive estimation page);
- `spectrum`: the estimator's bound now, the residual spectrum a quadratic in
  frequency fitted through the residuals' expectation at the estimate
  (`diffpegasus._estimate._recursive._smooth_spectrum_bound`, with its own
  degrees of freedom; where it comes out negative the estimator falls back to
  the white-residual bound, here counted as such: `negative` is their share).

Printed per parameter: the mean bound variance over the scatter's square, the
bias over the scatter, and the coverage of Student-t bands at the estimator's
degrees of freedom for `corrected` and `leverage`.

Run: `python experiments/recursive_fourier_bound_parts.py [--flights 300]
[--rate 50] [--noise-scale 1] [--no-end-terms] [--frequency-shape]`
(`--frequency-shape`: each state equation weighted per frequency by a fit of its
residual power to white plus differenced white noise, `c0 + c1 |1 - z|^2 / dt^2`).
"""

import argparse
import pathlib
import sys

import jax
import numpy as np
import scipy.optimize
import scipy.stats

from diffpegasus._estimate._recursive import _smooth_spectrum_bound


sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import recursive_coverage as rcv  # noqa: E402


NAMES = ("Zw", "Zde", "Mw", "Mq", "Mde")


def regression(w, q, az, de, dt):
    """The rows of `recursive_coverage.MODEL`'s regression (dw/dt, dq/dt, az) as
    the estimator forms them: differenced states against averaged regressors."""
    h = np.zeros(w.shape + (3, 5))
    y = np.zeros(w.shape + (3,))
    wm, qm = 0.5 * (w[..., 1:] + w[..., :-1]), 0.5 * (q[..., 1:] + q[..., :-1])
    dm = 0.5 * (de[1:] + de[:-1])
    h[..., 1:, 0, 0], h[..., 1:, 0, 1] = wm, dm
    y[..., 1:, 0] = np.diff(w) / dt - (rcv.U0 + rcv.ZQ) * qm
    h[..., 1:, 1, 2], h[..., 1:, 1, 3], h[..., 1:, 1, 4] = wm, qm, dm
    y[..., 1:, 1] = np.diff(q) / dt
    h[..., 2, 0], h[..., 2, 1] = w, de
    y[..., 2] = az - rcv.ZQ * q
    return h, y


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--flights", type=int, default=300)
    parser.add_argument("--rate", type=float, default=50.0)
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--noise-scale", type=float, default=1.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--no-end-terms", action="store_true")
    parser.add_argument("--frequency-shape", action="store_true")
    args = parser.parse_args()
    t, de, m = rcv.simulate(
        args.flights, args.duration, args.rate, args.seed, args.noise_scale
    )
    dt, n = 1.0 / args.rate, len(t)
    h, y = regression(m[..., 1], m[..., 2], m[..., 0], de, dt)
    freqs = np.arange(0.1, rcv.BAND + 0.01, 0.04)
    nf = len(freqs)
    z = np.exp(-2j * np.pi * freqs * dt)
    ph = z[:, None] ** np.arange(n)[None] * dt
    fh_all = np.einsum("fn,knqp->kfqp", ph, h)
    fy_all = np.einsum("fn,knq->kfq", ph, y)
    truth = np.array([rcv.TRUE[k] for k in NAMES])
    p0 = len(truth)
    n_end = np.zeros(3)
    if not args.no_end_terms:
        last, first = z ** (n - 1), -z
        ends = np.zeros((nf, 3, 4), complex)
        ends[:, 0, 0], ends[:, 0, 1], ends[:, 1, 2], ends[:, 1, 3] = (
            last,
            first,
            last,
            first,
        )
        fh_all = np.concatenate(
            [fh_all, np.broadcast_to(ends, (args.flights,) + ends.shape)], -1
        )
        n_end = np.array([2.0, 2.0, 0.0])
    p = fh_all.shape[-1]
    diff = freqs[:, None] - freqs[None]
    same = np.abs(diff) < 1e-12
    zz = np.where(same, 0.5, np.exp(-2j * np.pi * diff * dt))
    kappa = np.where(same, 1.0, (1 - zz**n) / (1 - zz) / n)
    out = {
        k: []
        for k in (
            *("theta", "truth", "fitted", "corrected", "leverage", "dof"),
            *("spectrum", "spectrum_dof", "white"),
        )
    }
    jax.config.update("jax_enable_x64", True)
    spectrum_bound = jax.jit(_smooth_spectrum_bound)
    for k in range(args.flights):
        fh, fy = fh_all[k], fy_all[k]

        def solve(wq, fh=fh, fy=fy):
            info = 2 * np.real(np.einsum("fq,fqa,fqb->ab", wq, fh.conj(), fh))
            rhs = 2 * np.real(np.einsum("fq,fqa,fq->a", wq, fh.conj(), fy))
            pm = np.linalg.inv(info)
            return pm @ rhs, pm

        th, pm = solve(np.ones((nf, 3)))
        e = fy - fh @ th
        power = (np.abs(e) ** 2).sum(0) / (nf - 0.5 * p0 - 0.5 * n_end)
        wq = np.broadcast_to(1 / power, (nf, 3))
        if args.frequency_shape:
            shape = np.column_stack([np.ones(nf), np.abs(1 - z) ** 2 / dt**2])
            wq = wq.copy()
            for r in (0, 1):
                c = scipy.optimize.nnls(shape, np.abs(e[:, r]) ** 2)[0]
                s = shape @ c
                wq[:, r] = 1 / np.maximum(s, 1e-6 * s.max())
        th, pm = solve(wq)
        out["theta"].append(th[:p0])
        hw = wq[:, :, None] * fh
        ak = np.einsum("fg,gqb->fqb", kappa, hw)

        def middle(tf, hw=hw, ak=ak):
            f1 = np.real(np.einsum("fqa,fqr,frb->ab", hw.conj(), tf, ak))
            return f1 + f1.T

        def outer(ee):
            return np.einsum("fq,fr->fqr", ee, ee.conj())

        at_truth = fy - fh @ np.concatenate([truth, th[p0:]])
        out["truth"].append(np.diag(pm @ middle(outer(at_truth)) @ pm)[:p0])
        tf = outer(fy - fh @ th)
        m_fit = middle(tf)
        out["fitted"].append(np.diag(pm @ m_fit @ pm)[:p0])
        x_f = np.einsum("fqa,fqc->fac", hw.conj(), fh)
        y_f = np.einsum("frd,frb->fdb", fh.conj(), ak)
        k1 = np.real(np.einsum("fac,fdb->abcd", x_f, y_f))
        k_op = (k1 + k1.transpose(1, 0, 2, 3)).reshape(p * p, p * p)
        kron = np.kron(pm, pm)
        v = np.linalg.solve(np.eye(p * p) - kron @ k_op, (pm @ m_fit @ pm).ravel())
        out["corrected"].append(np.diag(v.reshape(p, p))[:p0])
        lev = np.einsum("fqa,ab,frb->fqr", fh, pm, ak.conj())
        s_f = tf + lev @ tf + tf @ np.conj(np.swapaxes(lev, 1, 2))
        v = np.linalg.solve(
            np.eye(p * p) + kron @ k_op, (pm @ middle(s_f) @ pm).ravel()
        )
        out["leverage"].append(np.diag(v.reshape(p, p))[:p0])
        if not args.frequency_shape:  # the estimator weights whole equations
            var_s, dof_s = spectrum_bound(
                fh, hw, fy - fh @ th, wq[0], pm, kappa, freqs, dt
            )
            out["spectrum"].append(np.asarray(var_s)[:p0])
            out["spectrum_dof"].append(np.asarray(dof_s)[:p0])
            out["white"].append(np.diag(pm)[:p0])  # the estimator's fallback
        c = 2 * np.einsum("fq,fqa,fqb->fab", wq, fh.conj(), fh)
        share = np.real(np.einsum("ba,fbc,ca->fa", pm, c, pm))
        dof = (
            2
            * share.sum(0) ** 2
            / np.einsum("fa,fg,ga->a", share, np.abs(kappa) ** 2, share)
        )
        out["dof"].append(dof[:p0])
    err = np.array(out["theta"]) - truth
    scatter2 = err.var(0)
    print(
        f"{args.flights} flights, {args.rate:g} Hz, noise x{args.noise_scale:g}, "
        f"end terms {'no' if args.no_end_terms else 'yes'}, frequency shape "
        f"{'yes' if args.frequency_shape else 'no'}; per parameter {NAMES}"
    )
    print("bias / scatter", np.round(err.mean(0) / np.sqrt(scatter2), 3))
    quantile = scipy.stats.t.ppf(0.975, np.array(out["dof"]))
    for key in ("truth", "fitted", "corrected", "leverage"):
        var = np.array(out[key])
        line = f"{key}: mean bound variance / scatter^2 {np.round(var.mean(0) / scatter2, 3)}"
        if key in ("corrected", "leverage"):
            band = np.sqrt(np.clip(var, 0, None)) * quantile
            line += f", coverage {np.round((np.abs(err) <= band).mean(0), 3)}"
        print(line)
    if out["spectrum"]:
        var = np.array(out["spectrum"])
        negative = var <= 0
        var = np.where(negative, np.array(out["white"]), var)
        q_s = scipy.stats.t.ppf(0.975, np.maximum(np.array(out["spectrum_dof"]), 1.0))
        band = np.sqrt(var) * q_s
        print(
            f"spectrum: mean bound variance / scatter^2 "
            f"{np.round(var.mean(0) / scatter2, 3)}, coverage "
            f"{np.round((np.abs(err) <= band).mean(0), 3)}, negative "
            f"{np.round(negative.mean(0), 3)}"
        )


if __name__ == "__main__":
    main()
