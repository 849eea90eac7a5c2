"""Is the launch vehicle's named effect the same in every time segment of the flight?

A structural misfit of the baseline is a function of Mach (and alpha), and Mach
rises through the flight, so its projection on a named effect changes from one time
segment to the next; a planted effect (a constant moment offset, a misalignment, a
bias, a delay) is the same in every segment. Test: the named effect's parameter
split into `S` time segments (everything else shared and re-adjusted), its segment
estimates from the Gauss-Newton step at the baseline fit (first order, as the score
test's own estimate), and a Wald test of equal segment values with the covariance
corrected for the residuals' colour and their covariance between outputs (the
score test's, `diffpegasus._estimate._score.score_variance`, as a matrix), against
chi-square with `S - 1` degrees of freedom at a level stated in advance (1%).

Segments, stated before any flight was looked at: `S = 3` of equal time, made of
whole shooting segments (a parameter changing inside one would need a new layout;
at the shooting nodes the split is exact: a segment's parameter reaches the
outputs of its own shooting segments and, through the continuity defects, the
nodes that follow).

    nice python experiments/lv_homogeneity.py capture [--flights 200:8 400:44]
    python experiments/lv_homogeneity.py evaluate [--segments 3] [--level 0.01]
    python experiments/lv_homogeneity.py evaluate --bootstrap 1000
    python experiments/lv_homogeneity.py approximate
    python experiments/lv_homogeneity.py selfcheck

`capture`: the baseline fit with `PegasusEntry(knots=12)` (`fit_log`, as
`experiments/misfit_null.py fit`), then the stacked whitened Jacobian (outputs and
continuity defects) of the free unknowns and of every held candidate at its
estimates, to `CACHE/lvhom_{rate}_{seed}_k12.npz` (large: not in the repository).
`evaluate`: the test for every flight captured, the named effect taken from
`experiments/results/misfit_null/fits.jsonl` (the twelve-function fit's first
finding); `experiments/results/lv_homogeneity_s{S}.json` (`_boot{R}` with
`--bootstrap R`: the statistic's null from the log's sieve in place of
chi-square). `approximate`: a shortcut from `misfit_null.py`'s stored score-test
parts, rejected (it does not reproduce the whole-flight estimate).
"""

import argparse
import json
import os
import pathlib
import pickle
import sys
import tempfile
import time

import numpy as np
import scipy.stats


HERE = pathlib.Path(__file__).resolve().parent
RESULTS = HERE / "results"
CACHE = pathlib.Path(os.environ.get("MISFIT_CACHE", "/tmp/misfit_null_cache"))
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE))

# what decides first: the clean findings at twelve functions, the new moment offsets
ORDER = [
    "200:8",
    "400:44",
    "50:43",
    "1000:4",
    "400:42",
    "50:1",
    "1000:7",
    "200:5",
    "100:45",
    "200:2",
    "50:3",
    "200:11",
]


def _flights():
    from acceptance import PEGASUS
    from misfit_null import NEW

    by = {f"{r:g}:{s}": (r, s, p, v) for _, r, s, p, v in PEGASUS}
    by.update({f"{r:g}:{s}": (r, s, p, v) for r, s, p, v in NEW})
    return by


def _stem(rate, seed, knots):
    return f"lvhom_{int(rate)}_{seed}_k{knots}"


def capture(args):
    import jax

    jax.config.update("jax_enable_x64", True)
    import independent_generator as gen
    import jax.numpy as jnp

    import diffpegasus as dp
    from diffpegasus._estimate._engine import evaluate
    from diffpegasus._registry._pegasus import PegasusEntry
    from diffpegasus.discrepancy import fit_log

    by = _flights()
    CACHE.mkdir(parents=True, exist_ok=True)
    folder = pathlib.Path(tempfile.mkdtemp(prefix="lvhom_"))
    for f in args.flights or ORDER:
        rate, seed, planted, value = by[f]
        stem = _stem(rate, seed, args.knots)
        if (CACHE / f"{stem}.pkl").exists():
            continue
        effects = {planted: value} if planted else None
        csv = gen.make_log(folder / f"{stem}.csv", seed, rate, args.duration, effects)
        t0 = time.time()
        base = fit_log(PegasusEntry(knots=args.knots), dp.read_log(csv))
        res = base.result
        model = res.model
        names = list(model.parameters)
        nx, p = len(model.states), len(names)
        lay = res.layout
        ev = evaluate(model.structure(), lay, jnp.asarray(res.z), nx, p)
        raw = dict(
            layout=jax.tree_util.tree_map(np.asarray, lay),
            jy=np.asarray(ev.jy),
            jx=np.asarray(ev.jx),
            e=np.asarray(ev.e),
            d=np.asarray(ev.d),
            z=np.asarray(res.z),
            free=np.asarray(res.free),
            R=np.asarray(res.R),
            nx=nx,
            p=p,
            names=names,
            candidates=list(base.spec.candidates),
            seconds=time.time() - t0,
        )
        with open(CACHE / f"{stem}.pkl", "wb") as fh:
            pickle.dump(raw, fh)
        print(f, f"{time.time() - t0:.0f} s", flush=True)


def _load(stem):
    """The stacked problem of a captured flight (built once from its raw capture)."""
    path = CACHE / f"{stem}.npz"
    if not path.exists():
        with open(CACHE / f"{stem}.pkl", "rb") as fh:
            raw = pickle.load(fh)
        st = _stacked(raw)
        np.savez(path, **st, names=np.array(raw["names"]),
                 candidates=np.array(raw["candidates"]), seconds=raw["seconds"])  # fmt: skip
    return np.load(path)


def _stacked(raw):
    """The whitened Jacobian of the stacked residual (output rows, then defect
    rows) in the free unknowns and every parameter, dense, with each row's shooting
    segment; the residual; the segments' start times."""
    from diffpegasus._estimate._engine import _columns

    lay, free, r = raw["layout"], raw["free"], raw["R"]
    nx, p = raw["nx"], raw["p"]
    valid = np.asarray(lay.valid)
    n_seg, length = valid.shape
    _, local = _columns(lay, nx, p)
    local = np.asarray(local)
    free_cols = np.asarray(lay.free_columns(free, nx, p))
    w = 1.0 / np.sqrt(r)
    jy = raw["jy"]
    ny = jy.shape[2]
    jyw = np.where(valid[..., None, None], -jy * w[None, None, :, None], 0.0)
    ew = np.where(valid[..., None], raw["e"] * w[None, None, :], 0.0)
    keep = np.flatnonzero(free_cols)
    par = n_seg * nx + np.arange(p)
    cols = np.concatenate([keep, par])  # free unknowns, then all parameters
    # a free parameter has two columns (free block and parameter block)
    where = {}
    for i, c in enumerate(cols):
        where.setdefault(int(c), []).append(i)
    # output rows: (segment, sample, output)
    out = np.zeros((n_seg, length, ny, len(cols)))
    for s in range(n_seg):
        for a, c in enumerate(local[s]):
            for i in where.get(int(c), ()):
                out[s, :, :, i] += jyw[s, :, :, a]
    # defect rows: link s joins segment s's end to segment s + 1's node
    link = np.asarray(lay.link)
    scale = np.asarray(lay.scale)
    jx = raw["jx"]
    node_cols = np.asarray(lay.node_columns(nx, p))
    dfc = np.zeros((n_seg - 1, nx, len(cols)))
    for s in range(n_seg - 1):
        if not link[s]:
            continue
        for a, c in enumerate(local[s]):
            for i in where.get(int(c), ()):
                dfc[s, :, i] += jx[s, :, a] / scale
        for i, c in enumerate(node_cols[s + 1]):
            for j in where.get(int(c), ()):
                dfc[s, i, j] -= 1.0 / scale[i]
    d = raw["d"]
    dt = np.asarray(lay.dt)[np.asarray(lay.record)]
    return dict(
        out=out.reshape(-1, len(cols)).astype(np.float64),
        defects=dfc.reshape(-1, len(cols)),
        e=ew.reshape(-1),
        d=d.reshape(-1),
        free_count=len(keep),
        segment_of_output=np.repeat(np.arange(n_seg), length * ny),
        segment_of_defect=np.repeat(np.arange(n_seg - 1), nx),
        start=np.asarray(lay.first) * dt,
        length=length,
        outputs=ny,
        n_seg=n_seg,
    )


def _cross_spectral(x, e, outputs):
    """`(joint, own)` `(S, S)`: the covariance of the scores `sum x[:, i] e` when the
    residuals `e` are a stationary series correlated in time and between outputs,
    over all lags, by FFT; `joint` with the covariance between outputs, `own` each
    output's own term only (the matrix form of `score_variance`). `x` `(rows *
    outputs, S)`, `e` `(rows * outputs,)`, rows in time order, outputs inner."""
    xs = x.reshape(-1, outputs, x.shape[-1])
    es = e.reshape(-1, outputs)
    n = xs.shape[0]
    m = 2 * n
    prod = np.conj(np.fft.fft(es, n=m, axis=0))[..., None] * np.fft.fft(xs, n=m, axis=0)
    tot = prod.sum(axis=1)  # (f, S)
    joint = np.real(np.einsum("fi,fj->ij", tot, np.conj(tot))) / (n * m)
    own = np.real(np.einsum("foi,foj->ij", prod, np.conj(prod))) / (n * m)
    return joint, own


def _floor(c, floor):
    """`c` raised to at least `floor` in every direction (Loewner): the eigenvalues
    of `c` relative to `floor` clipped below at 1 (for 1x1, `max(c, floor)`)."""
    val, vec = np.linalg.eigh(floor)
    half = vec / np.sqrt(val)
    inner = half.T @ c @ half
    lam, u = np.linalg.eigh((inner + inner.T) / 2)
    lam = np.maximum(lam, 1.0)
    back = vec * np.sqrt(val)
    return back @ (u * lam) @ u.T @ back.T


def segment_test(out, defects, e, d, free_count, column, groups_out, groups_def,
                 outputs, segments, replicates=0):  # fmt: skip
    """Segment estimates of the parameter in `column` (an index into the stacked
    Jacobian's columns), their covariance and the Wald statistic of equal values.

    `out` `(rows * outputs, columns)`, `defects` `(links * states, columns)`: the
    stacked whitened Jacobian (first `free_count` columns the free unknowns);
    `e`, `d` the whitened residuals and defects; `groups_out`, `groups_def` each
    row's time segment (`0 .. segments - 1`). The step from the fit (held value 0)
    with the free unknowns re-adjusted: `theta = -(X^T X)^-1 X^T r`, `X` the
    segment columns with the free unknowns projected out; covariance `M^-1 C M^-1`,
    `M = X^T X`, `C` the scores' covariance from the residuals the step leaves, with
    their colour and their covariance between outputs, never below each output's
    own term nor below `M` (as the score test's variance). Returns `(theta, cov,
    wald, dof)`; with `replicates`, `(theta, cov, wald, null)`, `null` the
    statistic's bootstrap replicates ([`_null`][])."""
    a = np.concatenate([out, defects])
    r = np.concatenate([e, d])
    groups = np.concatenate([groups_out, groups_def])
    af = a[:, :free_count]
    col = a[:, column]
    xs = np.stack([np.where(groups == g, col, 0.0) for g in range(segments)], axis=1)
    # least squares, not normal equations: a free unknown the log does not
    # inform (a Mach function beyond the flight's Mach range) is a zero column
    coef = np.linalg.lstsq(af, xs, rcond=None)[0]
    x = xs - af @ coef
    m = x.T @ x
    theta = -np.linalg.solve(m, x.T @ r)
    rows = out.shape[0]
    after = e + x[:rows] @ theta
    joint, own = _cross_spectral(x[:rows], after, outputs)
    c = (
        _floor(_floor(joint, own), m)
        if segments > 1
        else np.atleast_2d(max(joint[0, 0], own[0, 0], m[0, 0]))
    )
    minv = np.linalg.inv(m)
    cov = minv @ c @ minv
    if segments == 1:
        return theta, cov, 0.0, 0
    wald = _wald(theta, cov)
    if replicates:
        null = _null(x[:rows], m, af[:rows], after, outputs, replicates)
        return theta, cov, wald, null
    return theta, cov, wald, segments - 1


def _wald(theta, cov):
    """Wald statistic of equal values of `theta` `(S,)` with covariance `cov`."""
    contrast = np.eye(len(theta))[:-1] - np.eye(len(theta))[1:]
    diff = contrast @ theta
    return float(diff @ np.linalg.solve(contrast @ cov @ contrast.T, diff))


def _null(x, m, af, after, outputs, replicates):
    """`(replicates,)` Wald statistics of the same test when the output residuals
    are drawn from the autoregression fitted to the residuals the segmented step
    leaves (the diagnosis's sieve, `diffpegasus._diagnose._calibration.sieve`),
    each replicate refitted to first order (free unknowns projected out, then the
    segment step) and studentised as the observed one: the statistic's own
    scatter, from the log, in place of chi-square."""
    from diffpegasus._diagnose._calibration import sieve

    valid = np.any(af != 0.0, axis=1).reshape(-1, outputs).all(axis=1)
    series = after.reshape(-1, outputs)[valid]
    sv = sieve(series)
    n = series.shape[0]
    transfer = sv.transfer(n)
    inn = np.asarray(sv.innovations)
    q, rr = np.linalg.qr(af)
    q = q[:, np.abs(np.diag(rr)) > 1e-10 * np.abs(np.diag(rr)).max()]
    minv = np.linalg.inv(m)
    rng = np.random.default_rng(0)
    out = np.empty(replicates)
    for k in range(replicates):
        u = np.fft.rfft(inn[rng.integers(0, len(inn), n)], axis=0)
        es = np.fft.irfft(np.einsum("fab,fb->fa", transfer, u), n=n, axis=0)
        full = np.zeros((valid.shape[0], outputs))
        full[valid] = es
        e = full.reshape(-1)
        e = e - q @ (q.T @ e)
        th = -minv @ (x.T @ e)
        aft = e + x @ th
        joint, own = _cross_spectral(x, aft, outputs)
        c = _floor(_floor(joint, own), m)
        out[k] = _wald(th, minv @ c @ minv)
    return out


def _groups(start, segments):
    """Equal-time segments of whole shooting segments: each shooting segment to
    the third (`segments`-th) of the flight its start falls in."""
    span = start[-1] + (start[-1] - start[-2]) if len(start) > 1 else 1.0
    return np.minimum((start / span * segments).astype(int), segments - 1)


def _named12():
    """`{(rate, seed): (effect named first at twelve functions or None, top)}`."""
    named = {}
    for line in open(RESULTS / "misfit_null" / "fits.jsonl"):
        row = json.loads(line)
        if row["knots"] != 12:
            continue
        sig = row["significant"]
        first = sig[0] if sig else None
        if isinstance(first, dict):
            first = first.get("effect")
        named[(row["rate"], row["seed"])] = (first, row["top"][0][0])
    return named


def evaluate_all(args):
    by = _flights()
    named = _named12()
    rows = []
    for f in ORDER + [k for k in by if k not in ORDER]:
        rate, seed, planted, value = by[f]
        if not (CACHE / f"{_stem(rate, seed, 12)}.pkl").exists():
            continue
        st = _load(_stem(rate, seed, 12))
        names = [str(n) for n in st["names"]]
        first, top = named.get((rate, seed), (None, None))
        effect = first or top
        cands = [str(c) for c in st["candidates"]]
        params = [c for c in cands if c.split(".")[0] == effect]
        seg = _groups(st["start"], args.segments)
        g_out = seg[st["segment_of_output"]]
        g_def = seg[st["segment_of_defect"]]
        free_count = int(st["free_count"])
        column = free_count + names.index(params[0])
        common = (st["out"], st["defects"], st["e"], st["d"], free_count, column)
        one, cov1, _, _ = segment_test(
            *common, np.zeros_like(g_out), np.zeros_like(g_def), int(st["outputs"]), 1
        )
        theta, cov, wald, null = segment_test(
            *common, g_out, g_def, int(st["outputs"]), args.segments, args.bootstrap
        )
        dof = args.segments - 1
        p_value = float(scipy.stats.chi2.sf(wald, dof))
        p_chi2 = p_value
        if args.bootstrap:
            # the log's own null of the statistic in place of chi-square
            p_value = float((1 + np.sum(null >= wald)) / (1 + len(null)))
        # the whole-flight step must be the score test's own (stored by misfit_null)
        stored = CACHE / f"pegasus_{int(rate)}_{seed}_k12.npz"
        check = None
        if stored.exists():
            sc = np.load(stored)
            i = [str(n) for n in sc["names"]].index(params[0])
            check = [float(sc["estimate"][i]), float(sc["stderr"][i])]
        homogeneous = p_value >= args.level
        row = {
            "flight": f,
            "rate": rate,
            "seed": seed,
            "planted": planted,
            "value": value,
            "named_at_12": first,
            "tested": params[0],
            "whole": [float(one[0]), float(np.sqrt(cov1[0, 0]))],
            "score_test": check,
            "segments": [
                [float(t), float(s)]
                for t, s in zip(theta, np.sqrt(np.diag(cov)), strict=True)
            ],
            "wald": wald,
            "dof": dof,
            "p_chi2": p_chi2,
            "p": p_value,
            "null_99": float(np.quantile(null, 0.99)) if args.bootstrap else None,
            "homogeneous": bool(homogeneous),
            "named_after": first if (first and homogeneous) else None,
        }
        want = planted.split(":")[0] if planted else None
        got = row["named_after"]
        tied = {"pitch_damping", "alpha_dot_damping"}
        row["right"] = (
            got == planted
            or (got in tied and planted in tied)
            or (got is None and planted is None)
            or (got is not None and want is not None and got == planted)
        )
        rows.append(row)
        segs = "  ".join(f"{t:.3g}+/-{s:.2g}" for t, s in row["segments"])
        print(
            f"{f:>8} {str(planted):>20} named12={str(first):>20} "
            f"whole {row['whole'][0]:.4g}+/-{row['whole'][1]:.3g} "
            f"(score test {check}) | {segs} | "
            f"W={wald:.1f} p={p_value:.3g} (chi2 {p_chi2:.2g}) -> {got} ({'yes' if row['right'] else 'no'})"
        )
    tail = f"_boot{args.bootstrap}" if args.bootstrap else ""
    out = RESULTS / f"lv_homogeneity_s{args.segments}{tail}.json"
    meta = {
        "segments": args.segments,
        "level": args.level,
        "knots": 12,
        "bootstrap": args.bootstrap,
    }
    out.write_text(json.dumps({"settings": meta, "flights": rows}, indent=1) + "\n")


def approximate(args):
    """The same test from the score test's stored parts (`experiments/misfit_null.py
    fit --knots 12`), without a new fit: the segment columns taken as the
    candidate's projected rows cut by segment, the free unknowns' output signatures
    (the refit basis) projected out again; defects left out. Exact only where the
    free unknowns' share of the candidate's signature (projected out before the
    cut) is reproduced segment by segment; compared with `evaluate` where both
    exist."""
    by = _flights()
    named = _named12()
    rows = []
    for f in ORDER + [k for k in by if k not in ORDER]:
        rate, seed, planted, value = by[f]
        path = CACHE / f"pegasus_{int(rate)}_{seed}_k12.npz"
        if not path.exists():
            continue
        sc = np.load(path)
        first, top = named.get((rate, seed), (None, None))
        effect = first or top
        names = [str(n) for n in sc["names"]]
        i = [n.split(".")[0] for n in names].index(effect)
        basis = np.asarray(sc["basis"], float)
        n, ny, u = basis.shape
        col = sc["rows"][:, :, i]
        out = np.concatenate([basis, col[..., None]], axis=2).reshape(n * ny, u + 1)
        e = sc["residuals"].reshape(-1)
        g = np.repeat(
            np.minimum(np.arange(n) * args.segments // n, args.segments - 1), ny
        )
        none = np.zeros((0, u + 1))
        common = (out, none, e, np.zeros(0), u, u)
        one, cov1, _, _ = segment_test(
            *common, np.zeros_like(g), np.zeros(0, int), ny, 1
        )
        theta, cov, wald, dof = segment_test(
            *common, g, np.zeros(0, int), ny, args.segments
        )
        p_value = float(scipy.stats.chi2.sf(wald, dof))
        row = {
            "flight": f,
            "planted": planted,
            "named_at_12": first,
            "tested": names[i],
            "score_test": [float(sc["estimate"][i]), float(sc["stderr"][i])],
            "whole": [float(one[0]), float(np.sqrt(cov1[0, 0]))],
            "segments": [
                [float(t), float(s)]
                for t, s in zip(theta, np.sqrt(np.diag(cov)), strict=True)
            ],
            "wald": wald,
            "p": p_value,
            "homogeneous": bool(p_value >= args.level),
        }
        rows.append(row)
        segs = "  ".join(f"{t:.3g}+/-{s:.2g}" for t, s in row["segments"])
        print(
            f"{f:>8} {str(planted):>20} {str(first):>18} {names[i]:>24} "
            f"st {row['score_test'][0]:.3g}+/-{row['score_test'][1]:.2g} "
            f"whole {row['whole'][0]:.3g}+/-{row['whole'][1]:.2g} | {segs} | "
            f"W={wald:.1f} p={p_value:.2g}"
        )
    out = RESULTS / f"lv_homogeneity_approx_s{args.segments}.json"
    meta = {"segments": args.segments, "level": args.level, "knots": 12}
    out.write_text(json.dumps({"settings": meta, "flights": rows}, indent=1) + "\n")


def selfcheck(args):
    """The test's level on a linear problem with white noise: six Mach-like hat
    functions times a manoeuvre in one output and a constant in another, free; a
    constant effect in both; `args.draws` noise draws; rejections at 1% and 5%."""
    rng = np.random.default_rng(0)
    n, ny = 600, 2
    t = np.linspace(0.0, 1.0, n)
    mach = 0.5 + 2.0 * t
    knots = np.linspace(mach.min(), mach.max(), 6)
    hats = np.maximum(0.0, 1.0 - np.abs(mach[:, None] - knots) / (knots[1] - knots[0]))
    sig = np.sin(2.0 * np.pi * 7.0 * t)
    free = np.zeros((n, ny, 7))
    free[:, 0, :6] = hats * sig[:, None]
    free[:, 1, 6] = 1.0
    eff = np.stack([np.ones(n), 0.5 * sig], axis=1)
    out = np.concatenate([free.reshape(n * ny, 7), eff.reshape(n * ny, 1)], axis=1)
    g = np.repeat(np.minimum((t * 3).astype(int), 2), ny)
    p = []
    for _ in range(args.draws):
        e = rng.standard_normal(n * ny) + 0.3 * out[:, 7]
        _, _, w, dof = segment_test(
            out, np.zeros((0, 8)), e, np.zeros(0), 7, 7, g, np.zeros(0, int), ny, 3
        )
        p.append(scipy.stats.chi2.sf(w, dof))
    p = np.array(p)
    print(f"rejected at 1%: {np.mean(p < 0.01):.4f}, at 5%: {np.mean(p < 0.05):.4f}")


def main():
    p = argparse.ArgumentParser(description=__doc__)
    sub = p.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("capture")
    c.add_argument("--knots", type=int, default=12)
    c.add_argument("--flights", nargs="+", default=None, metavar="RATE:SEED")
    c.add_argument("--duration", type=float, default=30.0, help="s (smoke tests)")
    e = sub.add_parser("evaluate")
    e.add_argument("--segments", type=int, default=3)
    e.add_argument("--level", type=float, default=0.01)
    e.add_argument(
        "--bootstrap",
        type=int,
        default=0,
        metavar="R",
        help="judge by R sieve-bootstrap replicates of the statistic, not chi-square",
    )
    a = sub.add_parser("approximate")
    a.add_argument("--segments", type=int, default=3)
    a.add_argument("--level", type=float, default=0.01)
    k = sub.add_parser("selfcheck")
    k.add_argument("--draws", type=int, default=400)
    args = p.parse_args()
    if args.cmd == "selfcheck":
        selfcheck(args)
    elif args.cmd == "capture":
        capture(args)
    elif args.cmd == "approximate":
        approximate(args)
    else:
        evaluate_all(args)


if __name__ == "__main__":
    main()
