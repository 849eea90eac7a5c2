"""Why a planted moment offset of 0.006 scores low on the launch vehicle: fit
flights of the independent generator as `diagnose --vehicle pegasus` does, keep
each score test's parts, and compare the decision's statistic and null with
alternatives.

    nice python experiments/offset_power.py fit DIR RATE:SEED[:EFFECT=VALUE][,nonoise] ... [--knots K]
    nice python experiments/offset_power.py analyse DIR/*.npz [--replicates 4000] [--out F.json]

`fit` writes `DIR/<rate>_<seed>_<effect>[_nonoise][_knotsK].npz` (the score test
of the baseline fit with every candidate held; `--knots`: Mach functions of the
baseline, default 6 as `diagnose`). `analyse` prints, per flight and
candidate: the diagnosis's statistic (coloured variance over all lags) and its
standard error against the white-noise one (`1 / sqrt(information)`); the
statistic with the variance from the sieve's autoregressive spectrum instead; the
family-wise threshold of the rule (max over candidates, sieve bootstrap, level
0.01) and each candidate's own (marginal) null quantiles and p-value from the
same replicates, with the min-P critical value (Westfall and Young's single-step
min-P at the same level).
"""

import argparse
import functools
import json
import pathlib
import sys
import time

import numpy as np


HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

import independent_generator as gen  # noqa: E402


FIELDS = (
    "statistic",
    "estimate",
    "stderr",
    "correlation",
    "rows",
    "residuals",
    "valid",
    "curvature",
    "slope",
    "basis",
)


def fit(
    out: pathlib.Path,
    rate: float,
    seed: int,
    effects: dict,
    noise: bool,
    knots: int | None = 6,
):
    import jax.numpy as jnp

    from diffpegasus._diagnose._calibration import padded_count
    from diffpegasus._diagnose._workflow import fit_log
    from diffpegasus._estimate._score import score
    from diffpegasus._registry._pegasus import PegasusEntry

    tag = "_".join(f"{k}={v}" for k, v in effects.items()) or "clean"
    stem = f"{int(rate)}_{seed}_{tag}{'' if noise else '_nonoise'}".replace(":", "_")
    stem += "" if knots == 6 else f"_knots{knots}"
    csv = out / f"{stem}.csv"
    gen.write(csv, *gen.generate(seed, rate, 30.0, effects, noise))
    t0 = time.perf_counter()
    ff = fit_log(PegasusEntry(knots=knots), str(csv))
    result = ff.result
    candidates = list(ff.spec.candidates)
    names = list(result.model.parameters)
    idx = np.array([names.index(c) for c in candidates])
    k = len(idx)
    padded = np.concatenate([idx, np.full(padded_count(k) - k, idx[0])])
    st = score(
        result.model.structure(),
        result.layout,
        jnp.asarray(result.z),
        jnp.asarray(result.R),
        jnp.asarray(result.free),
        jnp.asarray(padded),
        nx=len(result.model.states),
        p=len(names),
    )
    np.savez(
        out / f"{stem}.npz",
        candidates=np.array(candidates),
        k=k,
        converged=bool(result.converged),
        **{f: np.asarray(getattr(st, f)) for f in FIELDS},
    )
    print(stem, f"fit and score {time.perf_counter() - t0:.0f} s", flush=True)


def _ar_variance(fitted, rows, length):
    """Variance of `sum rows * e` for `e` from the autoregression `fitted` (its
    spectrum `H S_u H^*`), `(k,)`: a smooth estimate, where the rule's is over
    all lags of one record."""
    u = np.asarray(fitted.innovations)
    h = fitted.transfer(length)
    spectrum = np.einsum("fab,bc,fdc->fad", h, u.T @ u / len(u), np.conj(h))
    r = np.fft.rfft(rows, n=length, axis=0)
    w = np.full(r.shape[0], 2.0)
    w[0] = w[-1] = 1.0
    return np.einsum("f,fak,fab,fbk->k", w, np.conj(r), spectrum, r).real / length


@functools.cache
def _null():
    import jax
    import jax.numpy as jnp

    from diffpegasus._diagnose import _calibration as C

    @functools.partial(jax.jit, static_argnames=("replicates",))
    def null(rows, innovations, count, transfer, curvature, offset, key, basis, *, replicates):  # fmt: skip
        # the rule's bootstrap (`_calibration._bootstrap`), every candidate's
        # statistic kept instead of their maximum
        n = rows.shape[0]
        sp = C._spectra(rows, curvature, offset, basis)

        def one(k):
            index = jax.random.randint(k, (n,), 0, count)
            u = jnp.fft.rfft(innovations[index], axis=0)
            e = jnp.fft.irfft(jnp.einsum("fab,fb->fa", transfer, u), n=n, axis=0)
            return C._statistics(sp, e, refit=True)

        keys = jax.random.split(key, replicates)
        return jax.lax.map(one, keys, batch_size=64)

    return null


def analyse(path: pathlib.Path, replicates: int, level: float = 0.01) -> dict:
    import jax
    import jax.numpy as jnp

    from diffpegasus._diagnose import _calibration as C

    d = np.load(path)
    k, valid = int(d["k"]), d["valid"]
    names = [str(c).split(".")[0] for c in d["candidates"]]
    rows, e = d["rows"][valid][..., :k], d["residuals"][valid]
    s, g, stat = d["curvature"][:k], d["slope"][:k], d["statistic"][:k]
    basis = d["basis"][valid]
    basis = basis[..., np.any(basis != 0.0, axis=(0, 1))]
    n = rows.shape[0]
    # the series the rule resamples: the strongest candidate's step taken
    top = int(np.argmax(stat))
    resample = e - (g[top] / s[top]) * rows[..., top]
    fitted = C.sieve(resample - resample.mean(axis=0))
    ar_stat = g**2 / np.maximum(_ar_variance(fitted, rows, 2 * n), s)
    offset = g - np.einsum("nok,no->k", rows, e)
    rows_p, s_p, off_p = C._pad(rows, s, offset)
    innovations = np.zeros((n, e.shape[1]))
    innovations[: len(fitted.innovations)] = fitted.innovations
    null = np.asarray(
        _null()(
            jnp.asarray(rows_p),
            jnp.asarray(innovations),
            jnp.asarray(len(fitted.innovations)),
            jnp.asarray(fitted.transfer(n)),
            jnp.asarray(s_p),
            jnp.asarray(off_p),
            jax.random.key(0),
            jnp.asarray(basis),
            replicates=replicates,
        )
    )[:, :k]
    max_t = float(np.quantile(null.max(axis=1), 1.0 - level, method="higher"))
    # min-P: each replicate's smallest marginal p-value over the candidates
    marginal = (null[None, :, :] >= null[:, None, :]).sum(axis=1) / replicates
    min_p = float(np.quantile(marginal.min(axis=1), level))
    p = (1.0 + (null >= stat[None]).sum(axis=0)) / (1.0 + replicates)
    rows_out = []
    for j in np.argsort(-stat):
        rows_out.append(
            {
                "effect": names[j],
                "statistic": float(stat[j]),
                "estimate": float(d["estimate"][j]),
                "stderr": float(d["stderr"][j]),
                "stderr_white": float(1.0 / np.sqrt(s[j])),
                "statistic_ar_variance": float(ar_stat[j]),
                "marginal_q99": float(np.quantile(null[:, j], 0.99)),
                "marginal_q999": float(np.quantile(null[:, j], 0.999)),
                "marginal_p": float(p[j]),
                "max_t_significant": bool(stat[j] > max_t),
                "min_p_significant": bool(p[j] <= min_p),
            }
        )
    # share of each output's residual that is white (first differences)
    white = np.var(np.diff(e, axis=0), axis=0) / 2.0 / np.var(e, axis=0)
    return {
        "flight": path.stem,
        "converged": bool(d["converged"]),
        "replicates": replicates,
        "max_t_threshold": max_t,
        "min_p_critical": min_p,
        "white_share": [float(w) for w in white],
        "candidates": rows_out,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    f = sub.add_parser("fit")
    f.add_argument("dir", type=pathlib.Path)
    f.add_argument("flights", nargs="+", help="RATE:SEED[:EFFECT=VALUE][,nonoise]")
    f.add_argument(
        "--knots", type=int, default=6, help="Mach functions of the baseline"
    )
    a = sub.add_parser("analyse")
    a.add_argument("files", nargs="+", type=pathlib.Path)
    a.add_argument("--replicates", type=int, default=4000)
    a.add_argument("--out", type=pathlib.Path)
    args = parser.parse_args()
    if args.command == "fit":
        args.dir.mkdir(parents=True, exist_ok=True)
        for spec in args.flights:
            parts = spec.split(":", 2)
            effects, noise = {}, True
            for item in parts[2].split(",") if len(parts) > 2 else ():
                if item == "nonoise":
                    noise = False
                else:
                    name, value = item.rsplit("=", 1)
                    effects[name] = float(value)
            fit(args.dir, float(parts[0]), int(parts[1]), effects, noise, args.knots)
        return
    results = []
    for path in args.files:
        r = analyse(path, args.replicates)
        results.append(r)
        print(
            f"{r['flight']}: max-T threshold {r['max_t_threshold']:.1f}, "
            f"min-P critical p {r['min_p_critical']:.2g}"
        )
        for c in r["candidates"][:5]:
            print(
                f"  {c['effect']:22s} {c['statistic']:7.1f} "
                f"({c['estimate']:.3g} +/- {c['stderr']:.2g}, white {c['stderr_white']:.2g}) "
                f"AR-variance {c['statistic_ar_variance']:7.1f}  own null q99.9 "
                f"{c['marginal_q999']:5.1f} p {c['marginal_p']:.4f}"
                + (" max-T" if c["max_t_significant"] else "")
                + (" min-P" if c["min_p_significant"] else "")
            )
    if args.out is not None:
        args.out.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
