"""The drag band's coverage with and without the sensors' disagreement, as a
markdown table, from runs of `benchmarks/rocket_validation.py`.

Run: `python experiments/rocket_spread_table.py JSON [JSON ...] [--before JSON
...]`: one row per flight (planted CD inside the noise's 95% band and inside the
band with the sensors' spread, each band's mean half-width in % of CD, the Birge
ratio), then the totals. With `--before` (one earlier run per JSON, in the same
order; several comma-separated, read as one), that run's band with the spread
beside it, flight by flight.
"""

import json
import pathlib
import sys


def main():
    args = sys.argv[1:]
    before = [args[i + 1] for i, a in enumerate(args) if a == "--before"]
    after = [
        a
        for i, a in enumerate(args)
        if a != "--before" and args[i - 1 : i] != ["--before"]
    ]
    head = (
        "| flight | inside, noise band | inside, with the sensors' spread "
        "| mean half-width % of CD (noise, with spread) | Birge ratio |"
    )
    rule = "|---|---|---|---|---|"
    if before:
        head += " inside, with the spread before | half-width before |"
        rule += "---|---|"
    print(head)
    print(rule)
    for k, path in enumerate(after):
        rows = json.loads(pathlib.Path(path).read_text())
        old = {}
        for b in before[k].split(",") if before else ():
            old.update(json.loads(pathlib.Path(b).read_text()))
        total = [0, 0, 0, 0]
        for name, r in rows.items():
            if not isinstance(r, dict):
                continue
            birge = "-" if r.get("birge") is None else f"{r['birge']:.2f}"
            line = (
                f"| {name} | {r['inside_95']} of {r['points']} "
                f"| {r['inside_95_structural']} of {r['points']} "
                f"| {r['half_width_pct']:.1f}, {r['half_width_structural_pct']:.1f} "
                f"| {birge} |"
            )
            if before:
                o = old.get(name)
                line += (
                    " - | - |"
                    if o is None
                    else f" {o['inside_95_structural']} of {o['points']} "
                    f"| {o['half_width_structural_pct']:.1f} |"
                )
                total[3] += 0 if o is None else o["inside_95_structural"]
            print(line)
            total[0] += r["inside_95"]
            total[1] += r["inside_95_structural"]
            total[2] += r["points"]
        line = (
            f"| **{pathlib.Path(path).stem}** | {total[0]} of {total[2]} "
            f"| {total[1]} of {total[2]} | | |"
        )
        if before:
            line += f" {total[3]} | |"
        print(line)


if __name__ == "__main__":
    main()
