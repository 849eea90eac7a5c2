"""A campaign's results: per-flight MSE, coverage, the tables beside the thesis, box
plots and `summary.json`."""

import dataclasses
import json
import pathlib

import jax
import numpy as np

from .._files import atomic_write, write_text
from .._vehicle._pegasus._aerodynamics import DERIVATIVE_NAMES
from ._settings import (
    Campaign,
    LABELS,
    THESIS_MEANS,
    THESIS_SECONDS,
    THESIS_STD,
)
from ._storage import _IDENTITY_KEYS, _read_chunk


def load_results(campaign: Campaign, out: pathlib.Path) -> dict[str, dict]:
    """Per method: arrays over all flights (chunk padding removed)."""
    results = {}
    for m in campaign.methods:
        parts = [
            _read_chunk(out / "chunks" / m / f"{c:04d}.npz", m)
            for c in range(campaign.chunks)
        ]
        merged = {
            k: np.concatenate([p[k] for p in parts])
            for k in parts[0]
            if k not in ("seconds", *_IDENTITY_KEYS)
        }
        merged["seconds"] = np.array([float(p["seconds"]) for p in parts])
        keep = np.arange(campaign.samples)
        results[m] = {k: (v[keep] if k != "seconds" else v) for k, v in merged.items()}
    return results


def counted(r: dict, window_start, campaign: Campaign) -> np.ndarray:
    """`(flights, windows)`: the windows that count for the MSE and the coverage."""
    return (
        r["valid"]
        & (window_start[None, :] >= campaign.ignition - 1e-9)
        & (r["qbar"] >= campaign.min_qbar)
    )


def flight_mse(values, truth, use) -> np.ndarray:
    """`(flights, 6)` MSE per degree squared over the windows `use` (NaN for a
    flight without any)."""
    err2 = ((values - truth) * (np.pi / 180.0)) ** 2
    err2 = np.where(use[..., None], err2, 0.0)
    n = use.sum(axis=1)[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, err2.sum(axis=1) / n, np.nan)


def coverage(values, truth, stderr, use, k=2.0):
    """Fraction of the windows `use` whose truth lies within +/- k standard errors,
    per derivative `(6,)` and overall."""
    inside = np.abs(values - truth) <= k * stderr
    per = np.array([inside[..., j][use].mean() for j in range(6)])
    return per, float(inside[use].mean())


def write_reports(campaign, out, window_start) -> dict:
    """mse.csv, the tables, the figures, times.json and summary.json from the chunk
    files in `out`."""
    import csv

    from .._report._plotting import plot_campaign

    results = load_results(campaign, out)
    mse = {
        m: flight_mse(r["values"], r["truth"], counted(r, window_start, campaign))
        for m, r in results.items()
    }

    def write_mse(f):
        w = csv.writer(f)
        w.writerow(["flight", "method", *DERIVATIVE_NAMES])
        for m in campaign.methods:
            for i in range(campaign.samples):
                w.writerow([i, m, *(f"{x:.6e}" for x in mse[m][i])])

    atomic_write(out / "mse.csv", write_mse)
    means = {m: np.nanmean(v, axis=0) for m, v in mse.items()}
    stds = {
        m: np.nanstd(v, axis=0, ddof=1) if len(v) > 1 else v[0] * np.nan
        for m, v in mse.items()
    }
    tables = {}
    for name, ours, thesis in (
        ("means", means, THESIS_MEANS),
        ("std", stds, THESIS_STD),
    ):
        cols = [f"{LABELS[m]} ours" for m in campaign.methods] + [
            f"{LABELS[m]} thesis" for m in campaign.methods
        ]
        rows = [
            [
                d,
                *(ours[m][j] for m in campaign.methods),
                *(thesis[m][j] for m in campaign.methods),
            ]
            for j, d in enumerate(DERIVATIVE_NAMES)
        ]

        def write_table(f, cols=cols, rows=rows):
            w = csv.writer(f)
            w.writerow(["derivative", *cols])
            for r in rows:
                w.writerow([r[0], *(f"{x:.3e}" for x in r[1:])])

        atomic_write(out / f"mse_{name}.csv", write_table)
        md = [
            "| derivative | " + " | ".join(cols) + " |",
            "|---" * (len(cols) + 1) + "|",
        ]
        md += [
            "| " + r[0] + " | " + " | ".join(f"{x:.3g}" for x in r[1:]) + " |"
            for r in rows
        ]
        tables[name] = "\n".join(md)
    title = {
        "means": "Means of the per-flight MSE, (1/deg)^2 (thesis Table 6.2)",
        "std": "Standard deviations of the per-flight MSE, (1/deg)^2 (thesis Table 6.3)",
    }
    dropped = {m: int(np.sum(np.all(np.isnan(v), axis=1))) for m, v in mse.items()}
    note = "Flights without any counted estimate (left out of the means): " + ", ".join(
        f"{LABELS[m]} {n}" for m, n in dropped.items()
    )
    write_text(
        out / "tables.md",
        "\n\n".join(f"{title[k]}\n\n{v}" for k, v in tables.items()) + f"\n\n{note}\n",
    )
    plot_campaign(mse, out)
    summary = {
        "campaign": dataclasses.asdict(campaign),
        "mse_definition": (
            "per flight and derivative: mean over the windows from ignition on, with "
            "a mean measured dynamic pressure >= min_qbar and an estimate of their "
            "own, of (estimate - window-mean truth)^2, (1/deg)^2"
        ),
        "means": {
            m: dict(zip(DERIVATIVE_NAMES, map(float, v), strict=True))
            for m, v in means.items()
        },
        "std": {
            m: dict(zip(DERIVATIVE_NAMES, map(float, v), strict=True))
            for m, v in stds.items()
        },
        "flights_without_estimate": {
            m: int(np.sum(np.all(np.isnan(v), axis=1))) for m, v in mse.items()
        },
    }
    if "oem" in results:
        r = results["oem"]
        per, overall = coverage(
            r["values"],
            r["truth"],
            r["stderr"],
            counted(r, window_start, campaign),
        )
        summary["oem_coverage_2sigma"] = {
            "per_derivative": dict(zip(DERIVATIVE_NAMES, map(float, per), strict=True)),
            "overall": overall,
        }
        summary["oem_converged_flights"] = int(np.sum(r["converged"]))
    stages: dict[str, list[float]] = {}
    # timings.jsonl from process 0 (or a single process), timings-p<i>.jsonl from
    # the others; a line cut short by an interruption is skipped
    for log in sorted(out.glob("timings*.jsonl")):
        for line in log.read_text().splitlines():
            try:
                entry = json.loads(line)
                stages.setdefault(entry["stage"], []).append(float(entry["seconds"]))
            except (ValueError, KeyError, TypeError):
                continue
    timing = {
        "total_s": {k: float(np.sum(v)) for k, v in stages.items()},
        "chunk_s": stages,
        "compile_s_estimate": {
            k: float(v[0] - np.median(v[1:]))
            for k, v in stages.items()
            if k != "nn_training" and len(v) > 1
        },
        "s_per_flight_after_compile": {
            k: float(np.median(v[1:]) / campaign.batch)
            for k, v in stages.items()
            if k != "nn_training" and len(v) > 1
        },
        "devices": len(jax.devices()),
        "processes": jax.process_count(),
        "thesis_s_per_100_flights": THESIS_SECONDS,
    }
    write_text(out / "times.json", json.dumps(timing, indent=2))
    summary["times"] = timing
    write_text(out / "summary.json", json.dumps(summary, indent=2))
    return summary
