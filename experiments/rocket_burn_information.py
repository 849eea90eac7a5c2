"""Can a log tell the motor's burn time (`burn_scale`) from the drag? The
information matrix of a flight's channels at its start values (the team's drag
curve, catalogue thrust), from central-difference sensitivities of the model's
outputs over the ascent, white noise of `--sigma-alt` m on the altitude and
`--sigma-accel` m/s^2 on the accelerometer: the burn scale's standard error and its
multiple correlation with the other estimated parameters (the drag knots, the
thrust scale, the motor time, the static-pressure error; with an accelerometer its
offset too), with the altitude alone and with both channels.

`python experiments/rocket_burn_information.py ROCKET_TOML [--log CSV] [--sigma-alt
0.5] [--sigma-accel 0.3]`: a rocket.toml (its [log] tables name the logs, or `--log`
one simulated log.csv as scripts/make_rocket_fixtures.py writes it). Prints one line
per channel set; writes experiments/results/rocket_burn_information_NAME.json.
"""

import json
import pathlib
import sys

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]


def option(args, name, default):
    return args[args.index(name) + 1] if name in args else default


def main():
    import diffpegasus.rocket as dr
    from diffpegasus._estimate._fit import simulate_outputs
    from diffpegasus._rocket._identify import altitude_only

    args = sys.argv[1:]
    toml = pathlib.Path(args[0])
    from diffpegasus._log._rocketlogs import read_rocket_log

    rocket = dr.read_rocket(toml)
    log_path = option(args, "--log", None)
    log = read_rocket_log(pathlib.Path(log_path) if log_path else toml)
    sig = {
        "altitude": float(option(args, "--sigma-alt", 0.5)),
        "accel": float(option(args, "--sigma-accel", 0.3)),
    }
    full = dr.prepare(rocket, log)
    rows = {}
    sets = [("altitude alone", altitude_only(full))]
    if "accel" in full.outputs:
        sets.append(("altitude and accelerometer", full))
    for label, problem in sets:
        free = list(problem.flight.knots.names) + [
            "thrust_scale",
            "motor_time",
            "static_error",
            "burn_scale",
        ]
        if "accel" in problem.outputs:
            free.append("accel_bias")
        model = dr.rocket_model(problem.flight, problem.outputs, problem.start, free)
        names = model.parameters
        p0 = np.array([problem.start[n] for n in names], float)
        rec = problem.record
        keep = rec.t >= 0
        t, u = rec.t[keep], rec.inputs[keep]
        x0 = problem.flight.initial_state()

        def outputs(p, t=t, u=u, model=model, x0=x0):
            return simulate_outputs(model, t, u, p, x0)

        cols = []
        for n in free:
            i = names.index(n)
            h = 1e-4 * max(1.0, abs(p0[i]))
            up, down = p0.copy(), p0.copy()
            up[i] += h
            down[i] -= h
            cols.append(((outputs(up) - outputs(down)) / (2 * h)).ravel())
        # (samples, outputs) raveled sample by sample, as the outputs are
        weight = np.column_stack(
            [u[:, 1 + k] / sig[o] for k, o in enumerate(problem.outputs)]
        ).ravel()
        j = np.column_stack(cols) * weight[:, None]
        info = j.T @ j
        cov = np.linalg.inv(info)
        k = free.index("burn_scale")
        se = float(np.sqrt(cov[k, k]))
        # multiple correlation of burn_scale with the rest: 1 - 1/(C_kk I_kk)
        r2 = 1.0 - 1.0 / (cov[k, k] * info[k, k])
        corr = cov[k] / np.sqrt(np.diag(cov) * cov[k, k])
        top = sorted(
            ((free[i], float(corr[i])) for i in range(len(free)) if i != k),
            key=lambda a: -abs(a[1]),
        )[:3]
        rows[label] = {
            "burn_scale_stderr": se,
            "multiple_correlation": float(np.sqrt(max(r2, 0.0))),
            "stderr_if_alone": float(1 / np.sqrt(info[k, k])),
            "most_correlated": top,
        }
        print(
            f"{label}: burn_scale stderr {se:.4f} (alone {1 / np.sqrt(info[k, k]):.5f}),"
            f" multiple correlation {np.sqrt(max(r2, 0)):.6f}, most correlated {top}"
        )
    out = (
        ROOT / "experiments" / "results" / f"rocket_burn_information_{rocket.name}.json"
    )
    out.write_text(
        json.dumps({"toml": str(toml), "sigma": sig, "sets": rows}, indent=1)
    )


if __name__ == "__main__":
    main()
