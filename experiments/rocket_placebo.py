"""A placebo null for the rocket diagnosis, measured offline: one capture of every
round's score test per flight, the decision-rule variants evaluated on them
without refitting (as experiments/misfit_null.py does for the launch vehicle).

    nice python experiments/rocket_placebo.py capture NAME=FOLDER ...
    python experiments/rocket_placebo.py evaluate

The flights measured (docs/rockets/simulated.md, "A placebo null that keeps the
baseline's misfit"): `sim-clean=tests/data/rocket_sim/clean`,
`sim-planted=tests/data/rocket_sim/planted`,
`curve-c-s5-20hz=tests/data/rocket_baro/curve-c-s5-20hz`; clean-s3-20hz,
clean-smooth, curve-b-s4, sensors-s8, thrust-s7-20hz and planted-s9-20hz as
`scripts/make_rocket_fixtures.py --validation DIR` writes them; calisto-clean-s41,
calisto-clean-s42-20hz, small-clean-s46, calisto-lag01-s44 and small-lag01-s48
as `experiments/rocket_other_airframe.py fly DIR NAME ...` writes them (both in
RocketPy's environment); `table-error` and `first-order-lag` (no folder); the six
real flights by their folder name. A flight already captured is skipped.

`capture`: `diffpegasus.rocket.diagnose` (the command's path, every round) of each
FOLDER/rocket.toml with the decision rule's inputs of each round stored (the score
test's valid rows, residuals, refit basis, curvature, slope, estimates,
correlations, statistics, the sieve's maxima) in `CACHE/NAME_rR.npz` (large: not
in the repository) and what the library named, round by round, in
`experiments/results/rocket_placebo/captures.jsonl`. `NAME=table-error` and
`NAME=first-order-lag` run tests/test_rocket_baro.py's two synthetic flights
(the model's own flight with RocketPy's table error on its barometer; with a
first-order lag of 0.1 s) exactly as the tests do.

`evaluate`: each variant's finding round by round (a variant's threshold is never
below the sieve's, so in each round it names the library's finding or stops), in
`experiments/results/rocket_placebo/variants.json` and a table:

- `sieve`: the library's rule (the sieve bootstrap's 99% point of the largest
  statistic over candidates);
- `placebo`: the larger of the sieve's point and the 99% point of the largest
  statistic when the residuals the rule resamples (the strongest candidate's step
  taken) are circularly shifted against the candidates' rows by every lag beyond
  their correlation length, each shifted series refitted to first order and
  studentised exactly as a bootstrap replicate (misfit_variants.py's);
- `placebo_max`: the same with the placebo's largest draw instead of its 99% point;
- `reversed`: the placebo's draws with the series also reversed in time at each
  shift (twice the draws; reversal keeps the spectrum and, for a stationary
  series, the law);
- `placebo_raw`: the placebo of the fit's own residuals (the strongest
  candidate's signature not taken out);
- `signflip`: the larger of the sieve's point and the 99% point of the largest
  statistic when blocks of the resampled residuals, each the correlation length
  long, are multiplied by random signs (`FLIPS` draws): a misfit's shape within a
  block kept, its sign and so its alignment across blocks broken.
"""

import argparse
import json
import os
import pathlib
import sys
import time

import numpy as np


HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / "results" / "rocket_placebo"
CACHE = pathlib.Path(os.environ.get("PLACEBO_CACHE", "/tmp/rocket_placebo_cache"))
sys.path.insert(0, str(HERE))
LEVEL = 0.01
LAGS = 1000  # at most this many shifts, evenly spaced
FLIPS = 2000  # sign-flip draws

# what was planted in each flight this page judges (None: clean); a finding is
# right on a planted flight when its name (aliases included) holds one of these
PLANTED = {
    "sim-clean": None,
    "curve-c-s5-20hz": None,
    "clean-s3-20hz": None,
    "clean-smooth": None,
    "curve-b-s4": None,
    "calisto-clean-s41": None,
    "calisto-clean-s42-20hz": None,
    "small-clean-s46": None,
    "table-error": None,
    "sim-planted": ["wind", "barometer lag", "static-pressure error", "thrust"],
    "sensors-s8": ["barometer lag", "static-pressure error"],
    "thrust-s7-20hz": ["thrust"],
    "planted-s9-20hz": ["wind", "barometer lag", "static-pressure error", "thrust"],
    "wind-s6": ["wind"],
    "calisto-lag01-s44": ["barometer lag"],
    "small-lag01-s48": ["barometer lag"],
    "first-order-lag": ["barometer lag"],
}


def _capture_one(name, run):
    from diffpegasus._diagnose import _rule

    rounds = []
    original = _rule.DecisionRule.decide

    def decide(self, test, effects, parameters, *, delays, resolution):
        ranking, cals = original(
            self, test, effects, parameters, delays=delays, resolution=resolution
        )
        valid = np.asarray(test.valid, bool)
        basis = getattr(test, "basis", None)
        if basis is None:
            basis = np.zeros(np.asarray(test.residuals)[valid].shape + (0,))
        basis = (
            np.asarray(basis)[valid]
            if basis.ndim and len(basis) == len(valid)
            else basis
        )
        basis = basis[..., np.any(basis != 0.0, axis=(0, 1))]
        rounds.append(
            dict(
                rows=np.asarray(test.rows)[valid],
                residuals=np.asarray(test.residuals)[valid],
                basis=basis,
                curvature=np.asarray(test.curvature),
                slope=np.asarray(test.slope),
                estimate=np.asarray(test.estimate),
                stderr=np.asarray(test.stderr),
                correlation=np.asarray(test.correlation),
                statistic=np.asarray(test.statistic),
                maxima=np.asarray(cals[0].maxima),
                thresholds=np.array([c.threshold for c in cals]),
                names=np.array(list(parameters)),
            )
        )
        return ranking, cals

    _rule.DecisionRule.decide = decide
    try:
        t0 = time.time()
        named, rows = run()
        seconds = time.time() - t0
    finally:
        _rule.DecisionRule.decide = original
    for r, d in enumerate(rounds, start=1):
        np.savez(CACHE / f"{name}_r{r}.npz", **d)
    line = {
        "flight": name,
        "named": named,
        "rounds": [
            [
                [q["candidate"], q["statistic"], q["threshold"], q["significant"]]
                for q in rows
                if q["round"] == r
            ]
            for r in range(1, len(rounds) + 1)
        ],
        "seconds": round(seconds, 1),
    }
    with open(RESULTS / "captures.jsonl", "a") as fh:
        fh.write(json.dumps(line, default=float) + "\n")
    print(json.dumps(line, default=float), flush=True)


def _folder_run(folder):
    def run():
        import diffpegasus.rocket as dr
        from diffpegasus import read_rocket_log

        toml = pathlib.Path(folder) / "rocket.toml"
        problem = dr.prepare(dr.read_rocket(toml), read_rocket_log(toml))
        named, rows, _ = dr.diagnose(problem)
        return named, rows

    return run


def _test_run(which):
    """tests/test_rocket_baro.py's synthetic flight, diagnosed as the test does
    (the table error's test with one round)."""

    def run():
        import tempfile

        import diffpegasus.rocket as dr

        sys.path.insert(0, str(ROOT / "tests"))
        import test_rocket_baro as t

        got = {}
        original = dr.diagnose

        def diagnose(problem, **kw):
            named, rows, final = original(problem, **kw)
            got.update(named=named, rows=rows)
            return named, rows, final

        t.dr.diagnose = diagnose
        try:
            tmp = pathlib.Path(tempfile.mkdtemp(prefix="placebo_"))
            test = {
                "table-error": t.test_height_dependent_barometer_error_is_not_named_a_lag,
                "first-order-lag": t.test_first_order_barometer_lag_is_named_alone,
            }[which]
            try:
                test(tmp)
            except AssertionError:
                pass
        finally:
            t.dr.diagnose = original
        return got["named"], got["rows"]

    return run


def capture(args):
    import jax

    jax.config.update("jax_enable_x64", True)
    RESULTS.mkdir(parents=True, exist_ok=True)
    CACHE.mkdir(parents=True, exist_ok=True)
    for item in args.flights:
        name, _, folder = item.partition("=")
        if (CACHE / f"{name}_r1.npz").exists():
            continue
        run = _test_run(name) if not folder else _folder_run(folder)
        _capture_one(name, run)


def correlation_length(e):
    from misfit_variants import correlation_length as ell

    return ell(e)


def _prepared(d):
    """The score test's parts as the rule reads them (an uninformed candidate's
    rows zero, its slope 0 and curvature 1)."""
    from diffpegasus._diagnose._rule import informed_parts

    rows, s, g, informed = informed_parts(d["rows"], d["curvature"], d["slope"])
    return rows, np.array(d["residuals"], float), s, g, informed


def placebo_draws(d, resample, reverse=False):
    """The largest statistic over candidates at each circular shift (beyond the
    correlation length, both ways) of `resample`, refitted and studentised as a
    bootstrap replicate; with `reverse` also of the time-reversed series."""
    import jax
    import jax.numpy as jnp

    from diffpegasus._diagnose._calibration import _pad, _spectra, _statistics

    rows, resid, s, g, _ = _prepared(d)
    n = rows.shape[0]
    offset = g - np.einsum("nok,no->k", rows, resid)
    rows, curv, offset = _pad(rows, s, offset)
    ell = correlation_length(resample)
    shifts = np.unique(
        np.linspace(ell, n - ell, min(LAGS, max(n - 2 * ell + 1, 0))).astype(int)
    )
    if shifts.size == 0:
        return np.zeros(0), ell
    basis = np.asarray(d["basis"], float)
    sp = _spectra(
        jnp.asarray(rows), jnp.asarray(curv), jnp.asarray(offset), jnp.asarray(basis)
    )
    e = resample - resample.mean(axis=0)
    series = [e, e[::-1].copy()] if reverse else [e]
    out = []
    for x in series:
        x = jnp.asarray(x)

        @jax.jit
        def all_lags(sp, x, shifts):
            def one(k):
                return jnp.max(_statistics(sp, jnp.roll(x, k, axis=0), refit=True))

            return jax.lax.map(one, shifts, batch_size=16)

        out.append(np.asarray(all_lags(sp, x, jnp.asarray(shifts))))
    return np.concatenate(out), ell


def signflip_draws(d, resample, seed=0):
    """The largest statistic over candidates when blocks of `resample` (the
    correlation length long, from a random start) are each multiplied by a random
    sign, refitted and studentised as a bootstrap replicate: `FLIPS` draws."""
    import jax
    import jax.numpy as jnp

    from diffpegasus._diagnose._calibration import _pad, _spectra, _statistics

    rows, resid, s, g, _ = _prepared(d)
    n = rows.shape[0]
    offset = g - np.einsum("nok,no->k", rows, resid)
    rows, curv, offset = _pad(rows, s, offset)
    ell = correlation_length(resample)
    sp = _spectra(
        jnp.asarray(rows),
        jnp.asarray(curv),
        jnp.asarray(offset),
        jnp.asarray(np.asarray(d["basis"], float)),
    )
    e = jnp.asarray(resample - resample.mean(axis=0))
    blocks = n // ell + 2

    @jax.jit
    def draws(sp, e, keys):
        def one(k):
            k1, k2 = jax.random.split(k)
            start = jax.random.randint(k1, (), 0, ell)
            signs = jax.random.rademacher(k2, (blocks,), dtype=float)
            flip = signs[(jnp.arange(n) + start) // ell]
            return jnp.max(_statistics(sp, e * flip[:, None], refit=True))

        return jax.lax.map(one, keys, batch_size=16)

    keys = jax.random.split(jax.random.key(seed), FLIPS)
    return np.asarray(draws(sp, e, keys)), ell


def _quantile(m):
    return float(np.quantile(m, 1 - LEVEL, method="higher")) if m.size else 0.0


def judge_round(d):
    rows, resid, s, g, informed = _prepared(d)
    stat = np.where(informed, np.asarray(d["statistic"], float), -np.inf)
    top = int(np.argmax(stat))
    resample = resid - (g[top] / s[top]) * rows[..., top]
    sieve = float(d["thresholds"][0])
    pm, ell = placebo_draws(d, resample)
    pr, _ = placebo_draws(d, resample, reverse=True)
    raw, _ = placebo_draws(d, resid)
    flips, _ = signflip_draws(d, resample)
    thr = {
        "sieve": sieve,
        "placebo": max(sieve, _quantile(pm)),
        "placebo_max": max(sieve, float(pm.max()) if pm.size else 0.0),
        "reversed": max(sieve, _quantile(pr)),
        "placebo_raw": max(sieve, _quantile(raw)),
        "signflip": max(sieve, _quantile(flips)),
    }
    names = [str(x) for x in d["names"]]
    return {
        "samples": int(rows.shape[0]),
        "correlation_length": ell,
        "placebo_draws": int(pm.size),
        "placebo_q99": _quantile(pm),
        "placebo_median": float(np.median(pm)) if pm.size else None,
        "top": [names[top], float(stat[top]), float(d["estimate"][top])],
        "thresholds": thr,
        "passes": {k: bool(stat[top] > v) for k, v in thr.items()},
    }


def _right(flight, named):
    planted = PLANTED.get(flight, "real")
    if planted == "real":
        return None
    if planted is None:
        return not named
    return bool(named) and any(p in named[0] for p in planted)


def evaluate(args):
    captures = {}
    for line in open(RESULTS / "captures.jsonl"):
        r = json.loads(line)
        captures[r["flight"]] = r
    path = RESULTS / "variants.json"
    old = json.loads(path.read_text()) if path.exists() and not args.again else {}
    out = {}
    for flight, cap in captures.items():
        if flight in old and old[flight]["library"] == cap["named"]:
            out[flight] = old[flight]
            continue
        rounds = []
        r = 1
        while (CACHE / f"{flight}_r{r}.npz").exists():
            rounds.append(judge_round(dict(np.load(CACHE / f"{flight}_r{r}.npz"))))
            r += 1
        variants = list(rounds[0]["thresholds"]) if rounds else []
        named = {}
        for v in variants:
            # the library's findings up to the first round this variant stops at
            k = next((i for i, q in enumerate(rounds) if not q["passes"][v]), None)
            named[v] = cap["named"][: len(rounds) if k is None else k]
        out[flight] = {
            "library": cap["named"],
            "rounds": rounds,
            "named": named,
            "right": {v: _right(flight, n) for v, n in named.items()},
        }
        print(flight, json.dumps(named), flush=True)
    path.write_text(json.dumps(out, indent=1))
    _table(out)


def _table(out):
    variants = [
        "sieve",
        "placebo",
        "placebo_max",
        "reversed",
        "placebo_raw",
        "signflip",
    ]
    print(
        "| flight | samples | round 1 top | "
        + " | ".join(variants)
        + " | named (sieve / placebo) |"
    )
    print("|---|---|---|" + "---|" * len(variants) + "---|")
    score = {v: [0, 0] for v in variants}
    for flight, r in out.items():
        if not r["rounds"]:
            continue
        q = r["rounds"][0]
        cells = [f"{q['thresholds'][v]:.1f}" for v in variants]
        for v in variants:
            ok = r["right"][v]
            if ok is not None:
                score[v][0] += ok
                score[v][1] += 1
        print(
            f"| {flight} | {q['samples']} | {q['top'][0]} {q['top'][1]:.1f} | "
            + " | ".join(cells)
            + f" | {'; '.join(r['named']['sieve']) or 'nothing'} / "
            f"{'; '.join(r['named']['placebo']) or 'nothing'} |"
        )
    for v, (ok, n) in score.items():
        print(f"{v}: {ok}/{n} simulated flights right")


def main():
    p = argparse.ArgumentParser(description=__doc__)
    sub = p.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("capture")
    c.add_argument("flights", nargs="+", metavar="NAME=FOLDER")
    e = sub.add_parser("evaluate")
    e.add_argument("--again", action="store_true")
    args = p.parse_args()
    capture(args) if args.cmd == "capture" else evaluate(args)


if __name__ == "__main__":
    main()
