"""The barometer lag scored against a null that carries a height-dependent barometer
error: the first round of `diagnose` (its base fit, every candidate scored against
the log's own bootstrap threshold) twice per flight, as `diagnose` does it and with
the barometer's reading given a piecewise-linear error in height (zero at the pad,
knots every `burnout height` m to above apogee) estimated in the base fit.

Why the burnout height: on an ascent the climb rate is a function of height, so a
lag (`tau` times the climb rate) is one; what no function of height smoother than
the boost can take is the lag's rise from zero over the boost's height span. A
knot spacing of the burnout height leaves that rise to the lag. Measured, it does
not separate them on RocketPy's flights: the table's error varies on the boost's
height scale too, and the lag scores higher with the nuisance (see
docs/rockets/simulated.md, Diagnose).

`python experiments/rocket_baro_nuisance.py FOLDER [FOLDER ...]`: each FOLDER one
flight as `scripts/make_rocket_fixtures.py` writes it (or a real flight's folder
with its rocket.toml); `--spacing F` knots every F burnout heights (1);
`--hold-atmosphere` the pad temperature and lapse rate held at the base fit's in the
nuisance fit. Writes experiments/results/rocket_baro_nuisance.json, keyed
`PARENT/FOLDER xF[-held]`.
"""

import json
import pathlib
import sys
import time

import numpy as np


ROOT = pathlib.Path(__file__).resolve().parents[1]


def rows_of(ranking):
    return {
        r["parameter"]: {
            "statistic": float(r["statistic"]),
            "threshold": float(r["threshold"]),
            "estimate": float(r["estimate"]),
            "significant": bool(r["significant"]),
        }
        for r in ranking
    }


def main():
    import jax.numpy as jnp
    from rocket_baro_lag_alarm import first_round

    import diffpegasus.rocket as dr
    from diffpegasus._diagnose._candidates import score_candidates
    from diffpegasus._estimate._fit import fit, SingleShooting
    from diffpegasus._model import Model

    path = ROOT / "experiments" / "results" / "rocket_baro_nuisance.json"
    results = json.loads(path.read_text()) if path.exists() else {}
    args = sys.argv[1:]
    # --spacing F: knots every F burnout heights; --hold-atmosphere: the pad
    # temperature and lapse rate held at the base fit's (the nuisance takes the
    # barometer's departure from them, the density keeps them)
    spacing = float(args[args.index("--spacing") + 1]) if "--spacing" in args else 1.0
    hold_atm = "--hold-atmosphere" in args
    args = [
        a
        for i, a in enumerate(args)
        if not a.startswith("--") and (i == 0 or args[i - 1] != "--spacing")
    ]
    label = f"x{spacing:g}" + ("-held" if hold_atm else "")
    for arg in args:
        folder = pathlib.Path(arg)
        folder = folder.parent if folder.is_file() else folder
        t0 = time.perf_counter()
        toml = folder / "rocket.toml"
        rocket = dr.read_rocket(toml)
        from diffpegasus._log._rocketlogs import read_rocket_log

        log = folder / "log.csv" if (folder / "log.csv").exists() else toml
        problem = dr.prepare(rocket, read_rocket_log(log))
        base, held = first_round(problem, spread=False)
        model = base.fit.model
        plain = rows_of(score_candidates(base.fit, held, 0.01))

        speed = np.linalg.norm(base.states[:, 3:6], axis=1)
        burnout_h = spacing * float(base.states[np.argmax(speed), 2])
        top = float(np.max(base.states[:, 2]))
        n = int(np.ceil(top / burnout_h))
        knots = np.arange(n + 1) * burnout_h
        names = tuple(f"baro_h{k}" for k in range(1, n + 1))

        def observe(t, x, u, p, _obs=model.observe, names=names, knots=knots):
            y = _obs(t, x, u, p)
            c = jnp.stack([0.0] + [p[k] for k in names])
            err = jnp.interp(x[2], jnp.asarray(knots), c)
            return y.at[0].add(err * u[1])

        params = dict(zip(model.parameters, base.fit.params, strict=True))
        params.update({k: 0.0 for k in names})
        free = tuple(
            nm
            for nm, f in zip(model.parameters, base.fit.free, strict=True)
            if f and not (hold_atm and nm in ("temperature", "lapse_rate"))
        )
        ext = Model(
            states=model.states,
            inputs=model.inputs,
            outputs=model.outputs,
            parameters={k: float(v) for k, v in params.items()},
            rates=model.rates,
            observe=observe,
            fixed=tuple(k for k in params if k not in free + names),
            state_scale=model.state_scale,
        )
        nf = fit(
            ext,
            problem.record,
            shooting=SingleShooting(),
            initial_state="fixed",
            throw=False,
        )
        nuis = rows_of(score_candidates(nf, held, 0.01))
        shape = dict(zip(ext.parameters, nf.params, strict=True))
        key = f"{folder.parent.name}/{folder.name} {label}"
        results[key] = {
            "burnout_height_m": burnout_h,
            "knots_m": knots.tolist(),
            "det_r": float(base.fit.cost),
            "det_r_nuisance": float(nf.cost),
            "converged": bool(nf.converged),
            "error_at_knots_m": [float(shape[k]) for k in names],
            "plain": plain,
            "nuisance": nuis,
            "base_params": {k: float(v) for k, v in params.items()},
            "seconds": time.perf_counter() - t0,
        }
        path.write_text(json.dumps(results, indent=1))
        for which, rows in (("plain", plain), ("nuisance", nuis)):
            named = [k for k, r in rows.items() if r["significant"]]
            top3 = sorted(rows.items(), key=lambda kv: -kv[1]["statistic"])[:3]
            print(
                f"{key} {which}: named {named}; "
                + ", ".join(
                    f"{k} {r['statistic']:.1f}/{r['threshold']:.1f} ({r['estimate']:+.3g})"
                    for k, r in top3
                ),
                flush=True,
            )
        print(
            f"{folder.name}: burnout {burnout_h:.0f} m, {n} knots, det(R) "
            f"{base.fit.cost:.4g} -> {nf.cost:.4g}, error at knots "
            f"{np.round(results[key]['error_at_knots_m'], 2).tolist()} "
            f"({results[key]['seconds']:.0f} s)",
            flush=True,
        )


if __name__ == "__main__":
    main()
