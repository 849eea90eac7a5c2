"""Decision-rule variants on the fits `misfit_null.py fit` stored (see there).

Every variant judges the first step of the rule (the strongest candidate against
a threshold; only the first finding is `significant`), from the stored score
test, without refitting:

- `sieve`: the library's rule (the stored threshold: sieve bootstrap, max-T, 0.01);
- `placebo`: the null of the largest statistic when the residuals the rule
  resamples (the fit's, the strongest candidate's step taken) are circularly
  shifted against the candidates' rows by every lag beyond the residuals'
  correlation length, each shifted series refitted to first order and
  studentised exactly as a bootstrap replicate: the misfit keeps its smoothness,
  its spectrum and its covariance between outputs, only its alignment with the
  manoeuvre is broken; threshold `max(sieve, placebo quantile)`;
- `union`: the `1 - level` quantile of the sieve's and the placebo's maxima pooled;
- `sieve_raw`: the sieve with the fit's own residuals resampled (the strongest
  candidate's step not taken, so its signature widens the null).

Across Mach resolutions, the estimates of each candidate at 6 and 12 functions
are stored beside the decisions (`top`), for the stability argument (physics
keeps its size as the baseline refines; a misfit's projection moves).
"""

import json
import pathlib

import numpy as np
from misfit_null import _flights, _stem, CACHE, HERE, RESULTS


LEVEL = 0.01


def correlation_length(e: np.ndarray) -> int:
    """The first lag after which 5 autocorrelations in a row of every channel of
    `e` `(samples, channels)` are below `2 sqrt(log10 n / n)` (Politis and White's
    rule, as in `block_length`), the largest over channels."""
    n = e.shape[0]
    e = e - e.mean(axis=0)
    spec = np.abs(np.fft.rfft(e, n=2 * n, axis=0)) ** 2
    gamma = np.fft.irfft(spec, axis=0)[:n]
    bound = 2.0 * np.sqrt(np.log10(n) / n)
    longest = 1
    for c in range(e.shape[1]):
        g = gamma[:, c]
        if not g[0] > 0:
            continue
        small = np.abs(g[1:] / g[0]) < bound
        run = np.convolve(small.astype(int), np.ones(5, int), "valid") == 5
        hit = np.flatnonzero(run)
        longest = max(longest, int(hit[0]) + 1 if hit.size else n // 2)
    return longest


def placebo_maxima(d, resample, lags: int = 400):
    """Largest statistic over candidates at each circular shift of `resample`."""
    import jax
    import jax.numpy as jnp

    from diffpegasus._diagnose._calibration import _pad, _spectra, _statistics

    rows = np.asarray(d["rows"], float)
    n = rows.shape[0]
    offset = d["slope"] - np.einsum("nok,no->k", rows, d["residuals"])
    rows, curv, offset = _pad(rows, np.asarray(d["curvature"], float), offset)
    ell = correlation_length(resample)
    if n - 2 * ell < 1:
        return np.zeros(0), ell
    shifts = np.unique(
        np.linspace(ell, n - ell, min(lags, n - 2 * ell + 1)).astype(int)
    )
    basis = jnp.asarray(np.asarray(d["basis"], float))
    sp = _spectra(jnp.asarray(rows), jnp.asarray(curv), jnp.asarray(offset), basis)
    e = jnp.asarray(resample - resample.mean(axis=0))

    @jax.jit
    def all_lags(sp, e, shifts):
        def one(s):
            return jnp.max(_statistics(sp, jnp.roll(e, s, axis=0), refit=True))

        return jax.lax.map(one, shifts, batch_size=16)

    return np.asarray(all_lags(sp, e, jnp.asarray(shifts))), ell


def _sieve_raw(d):
    """The sieve threshold with the fit's own residuals resampled (the strongest
    candidate's step not taken: its signature, effect or misfit, widens the null)."""
    import jax

    from diffpegasus._diagnose._calibration import calibrate

    cal = calibrate(
        d["rows"], d["residuals"], d["curvature"], d["slope"], level=LEVEL,
        key=jax.random.key(0), basis=np.asarray(d["basis"], float),
    )  # fmt: skip
    return float(cal.threshold)


def _load(rate, seed, knots):
    path = CACHE / f"{_stem(rate, seed, knots)}.npz"
    if not path.exists():
        return None
    d = dict(np.load(path))
    d["names"] = [str(x) for x in d["names"]]
    return d


def _first(d, threshold):
    """The first finding at `threshold`, or None (a lead or sub-sample delay is
    never one)."""
    stat, est = d["statistic"], d["estimate"]
    order = np.argsort(-stat)
    for j in order:
        if stat[j] <= threshold:
            return None
        if d["delays"][j] and (est[j] < 0 or abs(est[j]) < d["resolution"]):
            continue  # approximately: the rule would go on given it
        return d["names"][j].split(".")[0]
    return None


def judge(d, rate, seed, planted):
    """Every single-resolution variant's named effect on one stored fit."""
    stat, s, g = d["statistic"], d["curvature"], d["slope"]
    top = int(np.argmax(stat))
    rows, resid = d["rows"], d["residuals"]
    resample = resid - (g[top] / s[top]) * rows[..., top]
    sieve_thr = float(d["thresholds"][0])
    pm, ell = placebo_maxima(d, resample)
    pm_raw, ell_raw = placebo_maxima(d, np.asarray(resid, float))
    q = float(np.quantile(pm, 1 - LEVEL, method="higher")) if pm.size else 0.0
    q_raw = (
        float(np.quantile(pm_raw, 1 - LEVEL, method="higher")) if pm_raw.size else 0.0
    )
    pooled = np.concatenate([d["maxima"], pm])
    raw = _sieve_raw(d)
    thr = {
        "sieve": sieve_thr,
        "placebo": max(sieve_thr, q),
        "placebo_raw": max(sieve_thr, q_raw),
        "placebo_max": max(sieve_thr, float(pm.max()) if pm.size else 0.0),
        "union": float(np.quantile(pooled, 1 - LEVEL, method="higher")),
        "sieve_raw": raw,
    }
    out = {
        "correlation_length": ell,
        "correlation_length_raw": ell_raw,
        "placebo_lags": int(pm.size),
        "placebo_q99": q,
        "placebo_raw_q99": q_raw,
        "placebo_median": float(np.median(pm)) if pm.size else None,
        "thresholds": thr,
        "named": {k: _first(d, v) for k, v in thr.items()},
        "top": [
            [d["names"][j].split(".")[0], float(stat[j]), float(d["estimate"][j]),
             float(d["stderr"][j])]
            for j in np.argsort(-stat)[:4]
        ],
    }  # fmt: skip
    out["right"] = {k: _right(v, planted) for k, v in out["named"].items()}
    return out


def _right(named, planted):
    if planted is None:
        return named is None
    alike = {"pitch_damping": {"alpha_dot_damping"}}.get(planted, set())
    return named in {planted, *alike}


def evaluate(args):
    by, order = _flights()
    path = RESULTS / "variants.json"
    old = json.loads(path.read_text()) if path.exists() else {}
    rows = {}
    for f in order:
        rate, seed, planted, value = by[f]
        for knots in (6, 9, 12):
            key = f"{f}:k{knots}"
            if key in old and (CACHE / f"{_stem(rate, seed, knots)}.npz").exists():
                rows[key] = old[key]
                continue
            d = _load(rate, seed, knots)
            if d is None:
                continue
            rows[key] = {
                "planted": planted,
                "value": value,
                **judge(d, rate, seed, planted),
            }
            print(key, json.dumps(rows[key]["named"]), flush=True)
    path.write_text(json.dumps(rows, indent=1))
    _table(rows, by, order)


def _table(rows, by, order):
    variants = ["sieve", "placebo", "placebo_raw", "placebo_max", "union", "sieve_raw"]
    print("| flight | planted | K | top stat | " + " | ".join(variants) + " |")
    print("|---|---|---|---|" + "---|" * len(variants))
    score = {}
    for f in order:
        for knots in (6, 9, 12):
            r = rows.get(f"{f}:k{knots}")
            if r is None:
                continue
            cells = []
            for v in variants:
                named = r["named"][v] or "none"
                ok = r["right"][v]
                score.setdefault((knots, v), []).append(ok)
                cells.append(
                    f"{named} / {r['thresholds'][v]:.1f} {'ok' if ok else 'WRONG'}"
                )
            top = r["top"][0]
            print(
                f"| {f} | {r['planted'] or 'clean'} | {knots} | {top[0]} {top[1]:.1f} | "
                + " | ".join(cells)
                + " |"
            )
    for (knots, v), oks in sorted(score.items()):
        print(f"K={knots} {v}: {sum(oks)}/{len(oks)} right")
    _across(rows, by, order)


def _six(by):
    """The library's decision with 6 functions on every flight, from the recorded
    acceptance run (`acceptance_s7.json`: the same sieve rule, as a user runs it)."""
    path = HERE / "results" / "acceptance_s7.json"
    out = {}
    for r in json.loads(path.read_text()):
        if r.get("kind") == "pegasus":
            out[f"{r['rate']:g}:{r['seed']}"] = (r["significant"] or [None])[0]
    return out


def _across(rows, by, order):
    """Across resolutions, sieve thresholds: `either` names what 12 functions
    name, else what 6 name; `both` only what both name."""
    six = _six(by)
    print("\n| flight | planted | 6 functions | 12 functions | either | both |")
    print("|---|---|---|---|---|---|")
    count = {"6": [], "12": [], "either": [], "both": []}
    for f in order:
        r = rows.get(f"{f}:k12")
        if r is None or f not in six:
            continue
        planted = by[f][2]
        a, b = six[f], r["named"]["sieve"]
        same = a == b or {a, b} <= {"pitch_damping", "alpha_dot_damping"}  # tied
        named = {"6": a, "12": b, "either": b or a, "both": a if same else None}
        cells = []
        for k, v in named.items():
            ok = _right(v, planted)
            count[k].append(ok)
            cells.append(f"{v or 'none'} {'ok' if ok else 'WRONG'}")
        print(f"| {f} | {planted or 'clean'} | " + " | ".join(cells) + " |")
    for k, oks in count.items():
        print(f"{k}: {sum(oks)}/{len(oks)} right")


def agree(pair=(9, 12)):
    """The rule's own stability across two Mach resolutions, sieve thresholds as
    stored: an effect is named only when both resolutions' first findings name it
    (the tied dampings count as one); what the misfit projects on moves from one
    candidate to another as the baseline refines, an effect stays."""
    by, order = _flights()
    print(
        f"| flight | planted | {pair[0]} functions | {pair[1]} functions | both | right |"
    )
    print("|---|---|---|---|---|---|")
    oks = []
    for f in order:
        rate, seed, planted, _ = by[f]
        d = [_load(rate, seed, k) for k in pair]
        if any(x is None for x in d):
            continue
        a, b = (_first(x, float(x["thresholds"][0])) for x in d)
        same = a == b or {a, b} <= {"pitch_damping", "alpha_dot_damping"}
        named = a if same else None
        ok = _right(named, planted)
        oks.append(ok)
        print(
            f"| {f} | {planted or 'clean'} | {a or 'none'} | {b or 'none'} "
            f"| {named or 'none'} | {'yes' if ok else 'no'} |"
        )
    print(f"both at {pair}: {sum(oks)}/{len(oks)} right")


def _summary(rate, seed, knots):
    """The last stored summary line (`fits.jsonl`) of a flight's fit at `knots`."""
    row = None
    for line in open(RESULTS / "fits.jsonl"):
        r = json.loads(line)
        if r["rate"] == rate and r["seed"] == seed and r["knots"] == knots:
            row = r
    return row


def refine(first: int = 12, new: bool = False, out=None, second: int | None = None):
    """The rule stated before measuring: the log's resolution `first` (what
    `choose_knots` picks on these flights) and one function more, fitted only
    where `first` names something; named only when both resolutions' first
    findings (the library's `significant`, as stored) agree, the tied dampings
    counting as one. With `new` the flights of `misfit_null.NEW`; `second`: another
    second resolution than `first + 1` (the pair 9 and 12 measured before)."""
    by, order = _flights(new)
    second = first + 1 if second is None else second
    print(
        f"| flight | planted | {first} functions | {second} functions | named | right |"
    )
    print("|---|---|---|---|---|---|")
    rows, oks = [], []
    for f in order:
        rate, seed, planted, value = by[f]
        a_row = _summary(rate, seed, first)
        if a_row is None:
            continue
        a = a_row["significant"][0] if a_row["significant"] else None
        cell_a = _cell(a_row)
        b, cell_b = None, "not fitted"
        if a is not None:
            b_row = _summary(rate, seed, second)
            if b_row is None:
                continue
            b = b_row["significant"][0] if b_row["significant"] else None
            cell_b = _cell(b_row)
        same = a == b or {a, b} <= {"pitch_damping", "alpha_dot_damping"}
        named = a if same else None
        ok = _right(named, planted)
        oks.append(ok)
        rows.append(
            dict(
                flight=f,
                planted=planted,
                value=value,
                first=a,
                second=b,
                named=named,
                right=ok,
            )
        )
        print(
            f"| {f} | {planted or 'clean'} {value or ''} | {cell_a} | {cell_b} "
            f"| {named or 'none'} | {'yes' if ok else 'no'} |"
        )
    print(f"{first} then {second}: {sum(oks)}/{len(oks)} right")
    if out is not None:
        pathlib.Path(out).write_text(json.dumps(rows, indent=1) + "\n")
    return rows


def _cell(row):
    """`effect (statistic / threshold)` of a stored summary; with nothing named,
    `none (the largest statistic's candidate, statistic / threshold)` from the
    stored score test (the summary's `top` follows the ranking's order)."""
    thr = row["threshold"]
    if row["significant"]:
        name = row["significant"][0]
        stat = next((t[1] for t in row["top"] if t[0] == name), row["top"][0][1])
        return f"{name} ({stat:.1f} / {thr:.1f})"
    d = _load(row["rate"], row["seed"], row["knots"])
    if d is None:
        top = max(row["top"], key=lambda t: t[1])
        return f"none ({top[0]} {top[1]:.1f} / {thr:.1f})"
    j = int(np.argmax(d["statistic"]))
    name = d["names"][j].split(".")[0]
    return f"none ({name} {float(d['statistic'][j]):.1f} / {thr:.1f})"


def columns(knots=(6, 9, 12, 13), new: bool = False):
    """Each resolution's first finding per flight (stored summaries), and the
    rules `12 then 13` (stated in advance) and `12 then 9` (the pair measured
    before) where both are stored."""
    by, order = _flights(new)
    head = " | ".join(f"{k} functions" for k in knots)
    print(f"| flight | planted | {head} | 12 then 13 | 12 then 9 |")
    print("|---" * (len(knots) + 4) + "|")
    for f in order:
        rate, seed, planted, value = by[f]
        rows = {k: _summary(rate, seed, k) for k in knots}
        cells = [_cell(r) if r else "not fitted" for r in rows.values()]

        def first(k, rows=rows):
            r = rows.get(k)
            return (r["significant"] or [None])[0] if r else "?"

        rules = []
        for second in (13, 9):
            a = first(12)
            b = first(second) if a else None
            if a == "?" or b == "?":
                rules.append("?")
                continue
            same = a == b or {a, b} <= {"pitch_damping", "alpha_dot_damping"}
            named = a if same else None
            ok = _right(named, planted)
            rules.append(f"{named or 'none'} ({'yes' if ok else 'no'})")
        print(
            f"| {f} | {planted or 'clean'} {value or ''} | "
            + " | ".join(cells + rules)
            + " |"
        )
