"""Why do least squares' bands with a memory over-cover? Measured on the coverage
Monte Carlo's flights (recursive_coverage.py, the same simulation and options): the
estimator's states at the checked times are taken (kept in DIR/states.npz
with `--keep-states`), and the bound is
taken apart on them, per parameter and check:

- coverage of the band as given, of the normal quantile times `stderr_corrected`
  (the bound's scale alone), and of the band with the bounds shuffled over the
  flights (the error's dependence on its bound removed);
- the bound's degrees of freedom three ways: the estimator's `dof`, the count of
  blocks it comes from (`_blocks`, Satterthwaite's count of the block sums'
  squares), and the `nu` whose chi-square over `nu` has the realised bound's 10%
  quantile (over the mean) on these flights, for the extrapolated bound and the
  longest usable blocks' alone: the lower tail is what sets a band's coverage;
- a weighted sum of one-degree chi-squares with geometric weights (the
  forgetting's shape): Satterthwaite's count, the `nu` of its 10% quantile, and
  the coverage of a Student-t band at Satterthwaite's count for an independent
  Gaussian error (200 000 draws);
- in-sample, the coverage of the Student-t band with each flight's `dof` scaled
  by the check's lower-tail `nu` over the mean `dof` (what a count of the lower
  tail could reach; tuned on these flights, not a method);
- the block counts from the block scores at the truth against those from the
  information, and the ladder's mean bound over the scatter's square.

Run: `python experiments/recursive_memory_states.py [--memory 10 | --memory 0]
[--rate 100] [--noise-scale 2] ... --out DIR`; writes
DIR/summary.json (also the last stdout line).
"""

import argparse
import json
import os
import pathlib
import sys


os.environ.setdefault(
    "XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
)

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import scipy.optimize  # noqa: E402
import scipy.stats  # noqa: E402


sys.path.insert(0, str(pathlib.Path(__file__).parent))
import recursive_coverage as rcov  # noqa: E402

from diffpegasus._estimate import _recursive as rc  # noqa: E402


jax.config.update("jax_enable_x64", True)


def states_at(est, h, y, o, theta0, idx):
    """The estimator's state after each sample of `idx`, one flight: a pytree
    whose leaves have a leading `(len(idx),)`."""
    state = est.init(theta0)
    out, begin = [], 0
    for k in idx:
        state, _ = jax.lax.scan(
            lambda s, a: (est.update(s, *a), None),
            state,
            (h[begin : k + 1], y[begin : k + 1], o[begin : k + 1]),
        )
        out.append(state)
        begin = k + 1
    return jax.tree.map(lambda *a: jnp.stack(a), *out)


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    rcov.flight_arguments(ap)
    ap.add_argument("--memory", type=float, default=10.0, help="s; 0: all data")
    ap.add_argument("--out", type=pathlib.Path, required=True)
    ap.add_argument(
        "--keep-states", action="store_true", help="also write DIR/states.npz (150 MB)"
    )
    args = ap.parse_args()
    flights = rcov.setup(args)
    dt, regs, theta0 = flights.dt, flights.regs, flights.theta0
    h, y, o = flights.h, flights.y, flights.o
    checks, idx = flights.check_times, tuple(flights.times_idx)
    lam = rc.forgetting_for(args.memory, dt) if args.memory > 0 else 1.0
    est = rc.RecursiveLeastSquares(
        forgetting=lam, derivative=regs[0].derivative, dt=dt, bandwidth=rcov.RLS_BAND
    )
    run = jax.jit(
        lambda hh, yy, oo: jax.lax.map(
            lambda a: states_at(est, *a, theta0, idx), (hh, yy, oo)
        )
    )
    parts = []
    for i in range(0, args.flights, rcov.CHUNK):
        parts.append(
            jax.tree.map(
                np.asarray,
                jax.block_until_ready(
                    run(
                        h[i : i + rcov.CHUNK],
                        y[i : i + rcov.CHUNK],
                        o[i : i + rcov.CHUNK],
                    )
                ),
            )
        )
        print(f"flights {i + rcov.CHUNK} done", flush=True)
    leaves = [
        np.concatenate(p)
        for p in zip(*(jax.tree.leaves(p) for p in parts), strict=True)
    ]
    truth = flights.truth
    args.out.mkdir(parents=True, exist_ok=True)
    states = jax.tree.unflatten(jax.tree.structure(est.init(theta0)), leaves)
    summary = {
        "memory_s": args.memory,
        "flights": args.flights,
        "rate_hz": args.rate,
        "noise_scale": args.noise_scale,
        "sensor_correlation_s": args.sensor_correlation,
        "aircraft": args.aircraft,
        "check_times_s": checks,
        "parameters": analyse(est, states, truth, regs[0].parameters, checks),
        "weighted_chi_square": weighted_chi_square(),
        "block_counts": block_score_counts(est, h, y, o, theta0, truth),
    }
    (args.out / "summary.json").write_text(json.dumps(summary, indent=1))
    if args.keep_states:
        np.savez(
            args.out / "states.npz",
            *leaves,
            truth=truth,
            forgetting=lam,
            dt=dt,
            checks=np.asarray(checks),
            derivative=np.asarray(regs[0].derivative),
            names=np.asarray(regs[0].parameters),
        )
    print(json.dumps(summary))


def nu_lower_tail(x, q=0.1):
    """The `nu` whose chi-square over `nu` has the `q` quantile of `x / mean(x)`."""
    r = np.quantile(x / np.mean(x), q)
    if not r < 0.999:
        return float("inf")
    return float(
        scipy.optimize.brentq(lambda v: scipy.stats.chi2.ppf(q, v) / v - r, 0.05, 1e4)
    )


def weighted_chi_square(ratios=(0.3, 0.5, 0.6, 0.77, 0.9), draws=200_000, seed=0):
    """Sums of one-degree chi-squares with weights `r^b` (b = 0 ... 59)."""
    rng = np.random.default_rng(seed)
    out = []
    for r in ratios:
        c = r ** np.arange(60)
        nu = c.sum() ** 2 / (c**2).sum()
        x = (rng.normal(size=(draws, 60)) ** 2 * c).sum(1) / c.sum()
        z = rng.normal(size=draws)
        cover = np.mean(np.abs(z) <= scipy.stats.t.ppf(0.975, nu) * np.sqrt(x))
        out.append(
            {
                "ratio": r,
                "satterthwaite_nu": float(nu),
                "nu_lower_tail": nu_lower_tail(x),
                "coverage_student_t": float(cover),
            }
        )
    return out


def block_score_counts(est, h, y, o, theta0, truth, sizes=(32, 64, 128)):
    """Satterthwaite's count of blocks two ways, per block length and check
    (600, 1000, 1250, 1500 samples absorbed): from the spread over the flights
    of the block scores at the truth, projected on each parameter (`var_f (P
    U_b)_a`), and from the information (`(P C_b P)_aa`, the estimator's way),
    with each sample's score `a_i - G_i theta` and information `G_i` as the
    estimator weighs and filters them (taken from its normal equations)."""
    lam = est.forgetting

    def one(a):
        def step(s, x):
            s2 = est.update(s, *x)
            return s2, (s2.rhs - lam * s.rhs, s2.info - lam * s.info)

        _, out = jax.lax.scan(step, est.init(theta0), a)
        return out

    ai, gi = (np.asarray(v) for v in jax.jit(lambda a: jax.lax.map(one, a))((h, y, o)))
    nf, n, p = ai.shape
    res = []
    for size in sizes:
        for k in (600, 1000, 1250, 1500):
            if k > n:
                continue
            w = lam ** (k - 1 - np.arange(k))
            sc = ai[:, :k] - np.einsum("fkab,b->fka", gi[:, :k], truth)
            blk = np.arange(k) // size
            u = np.stack(
                [np.einsum("k,fka->fa", w[blk == b], sc[:, blk == b])
                 for b in range(blk.max() + 1)], 1
            )  # fmt: skip
            c = np.stack(
                [np.einsum("k,fkab->fab", w[blk == b] ** 2, gi[:, :k][:, blk == b])
                 for b in range(blk.max() + 1)], 1
            )  # fmt: skip
            pm = np.linalg.inv(np.einsum("k,fkab->fab", w, gi[:, :k]))
            var_b = np.einsum("fab,fnb->fna", pm, u).var(0)
            c_info = np.einsum("fab,fnbc,fca->fna", pm, c, pm)
            res.append(
                {
                    "block": size,
                    "samples": k,
                    "count_from_scores": (
                        var_b.sum(0) ** 2 / (var_b**2).sum(0)
                    ).tolist(),
                    "count_from_information": (c_info.sum(1) ** 2 / (c_info**2).sum(1))
                    .mean(0)
                    .tolist(),
                }
            )
    return res


def analyse(est, states, truth, names, checks):
    """The summary (see the module docstring) from the states `(flights, checks)`."""
    nf, nc = states.count.shape
    flat = jax.tree.map(
        lambda a: jnp.asarray(a.reshape((nf * nc,) + a.shape[2:])), states
    )

    def parts(state):
        pm = rc._inverse(state.info)
        blocks = est._blocks(state, pm)
        usable = jnp.all(blocks >= 3.0, axis=1)
        j = jnp.max(jnp.where(usable, jnp.arange(est.levels), 0))
        e = est.estimates(state)
        return (
            e.theta,
            e.stderr_corrected,
            e.dof,
            e.halfwidth,
            est._variance(state, pm, j),
            blocks[j],
            jax.vmap(lambda lev: est._variance(state, pm, lev))(jnp.arange(est.levels)),
        )

    theta, sdc, dof, hw, vj, blocks, ladder = (
        np.asarray(a).reshape(nf, nc, -1)
        for a in jax.jit(lambda s: jax.lax.map(parts, s))(flat)
    )
    ladder = ladder.reshape(nf, nc, est.levels, -1)
    err = theta - truth
    rng = np.random.default_rng(1)
    perms = [rng.permutation(nf) for _ in range(200)]
    out = {}
    for a, n in enumerate(names):
        inside = np.abs(err[..., a]) <= hw[..., a]
        shuffled = np.mean(
            [np.mean(np.abs(err[..., a]) <= hw[pi, :, a], 0) for pi in perms], 0
        )
        out[n] = {
            "coverage": inside.mean(0).tolist(),
            "coverage_normal_quantile": np.mean(
                np.abs(err[..., a]) <= 1.959963984540054 * sdc[..., a], 0
            ).tolist(),
            "coverage_bounds_shuffled": shuffled.tolist(),
            "scatter_over_rms_bound": (
                err[..., a].std(0) / np.sqrt(np.mean(sdc[..., a] ** 2, 0))
            ).tolist(),
            "scatter_over_rms_longest_blocks": (
                err[..., a].std(0) / np.sqrt(np.mean(vj[..., a], 0))
            ).tolist(),
            "extrapolated_fraction": np.mean(
                np.abs(sdc[..., a] ** 2 - vj[..., a]) > 1e-12 * vj[..., a], 0
            ).tolist(),
            "correlation_squared_error_bound": [
                float(np.corrcoef(err[:, c, a] ** 2, sdc[:, c, a] ** 2)[0, 1])
                for c in range(nc)
            ],
            "ladder_over_scatter_squared": (
                ladder[..., a].mean(0) / err[..., a].var(0)[:, None]
            ).tolist(),
            "dof_mean": dof[..., a].mean(0).tolist(),
            # in-sample: each flight's dof scaled by the check's lower-tail nu
            # over the mean dof (what a count of the lower tail could reach)
            "coverage_student_t_lower_tail_dof": [
                float(
                    np.mean(
                        np.abs(err[:, c, a])
                        <= scipy.stats.t.ppf(
                            0.975,
                            dof[:, c, a]
                            * nu_lower_tail(sdc[:, c, a] ** 2)
                            / dof[:, c, a].mean(),
                        )
                        * sdc[:, c, a]
                    )
                )
                for c in range(nc)
            ],
            "blocks_mean": blocks[..., a].mean(0).tolist(),
            "nu_lower_tail_bound": [
                nu_lower_tail(sdc[:, c, a] ** 2) for c in range(nc)
            ],
            "nu_lower_tail_longest_blocks": [
                nu_lower_tail(vj[:, c, a]) for c in range(nc)
            ],
        }
    return out


if __name__ == "__main__":
    main()
