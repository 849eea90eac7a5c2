"""Thesis chapter 6: the full 100-flight Monte Carlo comparison of LSE, NN+LSE and OEM.

Runs (or resumes) the campaign with the thesis's settings — 100 flights drop to
burnout at 1 kHz, perturbations of Table 6.1, 0.5 s windows — and regenerates
everything in `--out`: `mse.csv`, the tables of means and standard deviations
beside the thesis's (Tables 6.2 and 6.3), box plots and distributions (Figs
6.1-6.6), the OEM 2-sigma coverage and the wall times.

Run: `python experiments/montecarlo.py [--samples 100] [--seed 0] [--out DIR]`.
"""

import os


os.environ.setdefault(
    "XLA_FLAGS", f"--xla_force_host_platform_device_count={os.cpu_count()}"
)

import argparse  # noqa: E402
import json  # noqa: E402
import pathlib  # noqa: E402

from diffpegasus._campaign._montecarlo import Campaign, run_campaign  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--samples", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--batch", type=int, default=10)
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/montecarlo")
    )
    args = parser.parse_args()
    campaign = Campaign(samples=args.samples, seed=args.seed, batch=args.batch)
    summary = run_campaign(campaign, args.out)
    print((args.out / "tables.md").read_text())
    print(
        json.dumps({k: summary[k] for k in ("oem_coverage_2sigma", "times")}, indent=2)
    )


if __name__ == "__main__":
    main()
