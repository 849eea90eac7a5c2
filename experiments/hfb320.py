"""HFB-320 business jet, longitudinal motion (SPEC section 7; Jategaonkar's test case 4).

The built-in vehicle's model (`dp.hfb320_model()`, the one flight model with the
book's aerodynamics) estimated by output error from the book's start values on the
real flight record `shared/data/hfb320/hfb320_1_10.asc` (3-2-1-1 then pulse, 60 s at
10 Hz), through the same column map as `diffpegasus fit --vehicle hfb320`. The last
stdout line is one JSON object with the estimates, standard errors, cost, iterations
and convergence.

Run: `python experiments/hfb320.py [--data FILE] [--out DIR]`.
"""

import argparse
import json
import pathlib

from _shared import shared_data

import diffpegasus as dp


DEFAULT_DATA = shared_data("hfb320/hfb320_1_10.asc")


def estimate(path=DEFAULT_DATA, **model_changes) -> dp.Fit:
    spec = dp.vehicle_spec("hfb320")
    model = dp.hfb320_model(**model_changes) if model_changes else spec.model
    record = dp.load_record(model, path, spec.columns, x0=spec.x0)
    return dp.fit(model, record)


def main():
    from diffpegasus._cli._runners import plot_fit

    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", type=pathlib.Path, default=DEFAULT_DATA)
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/hfb320")
    )
    args = parser.parse_args()
    res = estimate(args.data)
    plot_fit(res, args.out)
    names = res.model.parameters
    print(dp.format_parameter_table(dp.parameter_table(names, res.params, res.stderr)))
    summary = {
        "estimates": res.estimates(),
        "stderr": dict(zip(names, res.stderr.tolist(), strict=True)),
        "stderr_coloured_residuals": dict(
            zip(names, res.stderr_corrected.tolist(), strict=True)
        ),
        "cost": res.cost,
        "iterations": res.iterations,
        "converged": res.converged,
    }
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(
        json.dumps(
            {
                k: summary[k]
                for k in ("estimates", "stderr", "cost", "iterations", "converged")
            }
        )
    )


if __name__ == "__main__":
    main()
