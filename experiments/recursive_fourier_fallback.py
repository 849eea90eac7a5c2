"""Why the recursive Fourier transform's bound falls back to the white-residual one
for `Zw` and `Zde` on a few flights: the bound split into what the fitted residual
spectrum's own powers and its cross-spectra contribute.

The short-period Monte Carlo of `recursive_coverage.py` (same flights: seed 0),
each flight replayed to the check time, then the estimator's own `estimates` run
with the residual-spectrum fit's coefficients returned as well (its source is
taken from the package and only its `return` lines extended: no copy of the fit
is kept here). The bound is linear in the coefficients, `V_aa = sum_j coef_j
(cols_j)_aa`; the split is over the coefficients of the equations' own powers and
of the cross-spectra, and whether the fitted spectrum is positive semi-definite at
every frequency (its smallest eigenvalue over its largest).

Run: `python experiments/recursive_fourier_fallback.py [--rate 50] [--check 10]
[--flights 200]` (writes `results/recursive_coverage/fourier_fallback_*.json`).
"""

import argparse
import inspect
import json
import os
import pathlib


os.environ.setdefault(
    "XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
)

import jax  # noqa: E402
import numpy as np  # noqa: E402
import recursive_coverage as rcov  # noqa: E402

import diffpegasus as dp  # noqa: E402
from diffpegasus._estimate import _recursive as rc  # noqa: E402


jax.config.update("jax_enable_x64", True)


def _with_parts():
    """The estimator's `estimates` and spectrum fit, returning their parts."""
    fit = inspect.getsource(rc._smooth_spectrum_bound)
    fit = fit.replace("def _smooth_spectrum_bound(", "def _fit_parts(")
    fit = fit.replace(
        "    return var_c, dof\n", "    return var_c, dof, coef, s_f, cols\n"
    )
    est = inspect.getsource(rc.RecursiveFourier.estimates)
    est = "\n".join(line[4:] for line in est.splitlines())
    est = est.replace(
        "def estimates(self, state):", "def _estimate_parts(self, state):"
    )
    est = est.replace(
        "var_c, dof = _smooth_spectrum_bound(",
        "var_c, dof, coef, s_f, cols = _fit_parts(",
    )
    ret = "    var_c = jnp.where(known & (var_c > 0), var_c, var)\n    return _finish("
    assert ret in est, "the estimator's code changed: update this script"
    est = (
        est[: est.index(ret)] + "    return var_c[:p0], coef, s_f, cols[:, :p0, :p0]\n"
    )
    space = dict(rc.__dict__)
    exec(fit, space)  # noqa: S102
    exec(est, space)  # noqa: S102
    return space["_estimate_parts"]


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rate", type=float, default=50.0)
    parser.add_argument("--check", type=float, default=10.0, help="s")
    parser.add_argument("--flights", type=int, default=200)
    args = parser.parse_args()
    parts = _with_parts()
    t, de, measured = rcov.simulate(args.flights, 30.0, args.rate, 0, 1.0, 0.0)
    dt = 1.0 / args.rate
    regs = [
        rc.model_regression(
            rcov.MODEL, dp.Record(t, de[:, None], measured[i], x0=np.zeros(2))
        )
        for i in range(args.flights)
    ]
    names = regs[0].parameters
    theta0 = np.asarray(rcov.MODEL.start)[list(regs[0].index)]
    freqs = tuple(float(f) for f in np.arange(0.1, rcov.BAND + 0.01, 0.04))
    est = rc.RecursiveFourier(
        frequencies=freqs, forgetting=1.0, derivative=regs[0].derivative, dt=dt
    )
    k = int(round(args.check / dt)) + 1
    herm = rc._hermitian_basis(3)
    own = np.tile(
        [
            np.trace(np.abs(b)) == 1
            and np.all(b.imag == 0)
            and np.count_nonzero(b) == 1
            for b in herm
        ],
        3,
    )

    @jax.jit
    def one(h, y, o):
        state = est.init(theta0)
        state, _ = jax.lax.scan(
            lambda s, x: (est.update(s, *x), None), state, (h[:k], y[:k], o[:k])
        )
        return parts(est, state)

    rows = []
    for r in regs:
        var_c, coef, s_f, cols = (np.asarray(x) for x in one(r.h, r.y, r.o))
        share = np.einsum("j,jaa->ja", coef, cols)
        eig = np.linalg.eigvalsh(s_f)
        rows.append(
            {
                "bound": var_c.tolist(),
                "own": share[own].sum(0).tolist(),
                "cross": share[~own].sum(0).tolist(),
                "min_eig_over_max": float((eig.min(1) / eig.max(1)).min()),
            }
        )
    summary = {"rate_hz": args.rate, "check_s": args.check, "flights": args.flights}
    summary["psd_everywhere"] = float(
        np.mean([r["min_eig_over_max"] > -1e-9 for r in rows])
    )
    summary["min_eig_over_max_percentiles_1_5_50_95_99"] = np.percentile(
        [r["min_eig_over_max"] for r in rows], [1, 5, 50, 95, 99]
    ).tolist()
    for a, n in enumerate(names):
        bound = np.array([r["bound"][a] for r in rows])
        ratio = np.array([r["cross"][a] / r["own"][a] for r in rows])
        summary[n] = {
            "negative_bound": float(np.mean(bound <= 0)),
            "own_positive": float(np.mean([r["own"][a] > 0 for r in rows])),
            "cross_over_own_percentiles_1_5_50_95_99": np.percentile(
                ratio, [1, 5, 50, 95, 99]
            ).tolist(),
        }
    out = pathlib.Path(__file__).parent / "results" / "recursive_coverage"
    out.mkdir(parents=True, exist_ok=True)
    name = f"fourier_fallback_rate{args.rate:g}_check{args.check:g}.json"
    (out / name).write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
