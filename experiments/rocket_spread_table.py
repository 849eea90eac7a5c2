"""The drag band's coverage with and without the sensors' disagreement, as a
markdown table, from runs of `benchmarks/rocket_validation.py`.

Run: `python experiments/rocket_spread_table.py JSON [JSON ...]`: one row per flight
(planted CD inside the noise's 95% band and inside the band with the sensors'
spread, each band's mean half-width in % of CD, the Birge ratio), then the totals.
"""

import json
import pathlib
import sys


def main():
    print(
        "| flight | inside, noise band | inside, with the sensors' spread "
        "| mean half-width % of CD (noise, with spread) | Birge ratio |"
    )
    print("|---|---|---|---|---|")
    for path in sys.argv[1:]:
        rows = json.loads(pathlib.Path(path).read_text())
        total = [0, 0, 0]
        for name, r in rows.items():
            if not isinstance(r, dict):
                continue
            birge = "-" if r.get("birge") is None else f"{r['birge']:.2f}"
            print(
                f"| {name} | {r['inside_95']} of {r['points']} "
                f"| {r['inside_95_structural']} of {r['points']} "
                f"| {r['half_width_pct']:.1f}, {r['half_width_structural_pct']:.1f} "
                f"| {birge} |"
            )
            total[0] += r["inside_95"]
            total[1] += r["inside_95_structural"]
            total[2] += r["points"]
        print(
            f"| **{pathlib.Path(path).stem}** | {total[0]} of {total[2]} "
            f"| {total[1]} of {total[2]} | | |"
        )


if __name__ == "__main__":
    main()
