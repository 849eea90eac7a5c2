"""docs/rockets/simulated.md from benchmarks/results/rocket_validation.json (written by
`python benchmarks/rocket_validation.py`)."""

import json
import pathlib


ROOT = pathlib.Path(__file__).resolve().parents[1]


def main():
    d = json.loads((ROOT / "benchmarks/results/rocket_validation.json").read_text())
    lines = [
        "# Rockets: flights of an independent 6-DOF simulator",
        "",
        "Two flights simulated by RocketPy (scripts/make_rocket_fixtures.py; committed "
        "under tests/data/rocket_sim): `clean` (drag curve, white noise only) and "
        "`planted` (another drag curve, thrust scale 0.94, wind 6 m/s east and 3 m/s "
        "south, barometer lag 0.15 s, static-pressure error 0.04 q, more noise). The fit "
        "starts from a flat CD of 0.5, not the planted curve.",
        "",
        "Reproduce: `python benchmarks/rocket_validation.py` then "
        "`python scripts/rocket_sim_docs.py`.",
        "",
        "| flight | planted CD inside the 95% band | thrust scale (planted) | "
        "diagnose names | fit (s, cold, on a busy 2-core machine) |",
        "|---|---|---|---|---|",
    ]
    for name in ("clean", "planted"):
        r = d[name]
        k, s = r["thrust_scale"]
        named = ", ".join(r.get("named", [])) or "nothing"
        lines.append(
            f"| {name} | {r['inside_95']} of {r['points']} Mach points | "
            f"{k:.3f} ± {s:.3f} ({r['thrust_scale_planted']}) | {named} | "
            f"{r['fit_seconds']:.0f} |"
        )
    lines += ["", f"Coverage over both flights: {100 * d['coverage']:.0f}%.", ""]
    for name in ("clean", "planted"):
        lines += [
            f"## {name}: diagnose",
            "",
            "| round | candidate | statistic | threshold | det(R) ratio | named |",
            "|---|---|---|---|---|---|",
        ]
        for t in d[name].get("tests", []):
            lines.append(
                f"| {t['round']} | {t['candidate']} | {t['statistic']:.1f} | "
                f"{t['threshold']:.1f} | {t['cost_ratio']:.3f} | "
                f"{'yes' if t.get('significant') else ''} |"
            )
        lines.append("")
    (ROOT / "docs/rockets/simulated.md").write_text("\n".join(lines))


if __name__ == "__main__":
    main()
