"""Frequency-domain output error against time-domain output error on every real
record at hand, through the command line as a user runs it (a model file or a
built-in vehicle, and the log): `diffpegasus fit LOG --model FILE --json` and the
same with `--method fdoe` (the default band: where the inputs have 99% of their
power). For every parameter both estimate: `z = (frequency - time) / stderr_time`,
the difference in the time domain's corrected standard errors.

Records: the HFB-320 flight record (`hfb320_1_10.asc`) with the linear
short-period model file and with the built-in lateral model (`--vehicle
hfb320-lateral`, the record's lateral columns), and the unstable aircraft
(`unStabAC_sim.asc`, a simulated record that comes with the same book's software).

Run: `python experiments/frequency_cli.py [--out DIR]`; the last stdout line is the
JSON summary (also DIR/summary.json).
"""

import argparse
import json
import pathlib
import subprocess
import sys

from _shared import shared_data


ROOT = pathlib.Path(__file__).resolve().parents[1]
CASES = {
    "HFB-320, short period (model file)": (
        "hfb320/hfb320_1_10.asc", ["--model", str(ROOT / "examples" / "hfb320_linear.py")]
    ),
    "HFB-320, lateral (built-in model)": (
        "hfb320/hfb320_1_10.asc", ["--vehicle", "hfb320-lateral"]
    ),
    "unstable aircraft (model file)": (
        "unstable_aircraft/unStabAC_sim.asc",
        ["--model", str(ROOT / "examples" / "unstable_aircraft.py")],
    ),
}  # fmt: skip


def cli(log, model_args, method):
    cmd = [sys.executable, "-m", "diffpegasus", "fit", str(log), *model_args, "--json"]
    if method != "oem":
        cmd += ["--method", method]
    res = subprocess.run(cmd, capture_output=True, text=True, check=True)
    return json.loads(res.stdout)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/frequency_cli")
    )
    args = parser.parse_args()
    summary = {}
    for label, (name, model_args) in CASES.items():
        log = shared_data(name)
        if not log.exists():
            continue
        td, fd = cli(log, model_args, "oem"), cli(log, model_args, "fdoe")
        rows = {}
        for p, value in fd["estimates"].items():
            if fd["stderr"][p] is None:
                continue  # not estimated in the frequency domain (biases, trim)
            rows[p] = {
                "time_oe": td["estimates"][p],
                "time_oe_stderr": td["stderr"][p],
                "freq_oe": value,
                "freq_oe_stderr": fd["stderr"][p],
                "z": (value - td["estimates"][p]) / td["stderr"][p],
            }
        summary[label] = {
            "log": pathlib.Path(name).name,
            "converged": [td["converged"], fd["converged"]],
            "max_abs_z": max(abs(r["z"]) for r in rows.values()),
            "parameters": rows,
        }
        print(f"{label}: max |z| = {summary[label]['max_abs_z']:.2f}")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
