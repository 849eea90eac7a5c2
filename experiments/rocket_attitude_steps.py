"""The attitude fit's step at points of its walk (`rocket_attitude_convergence.py`'s
`.npz`): along the Gauss-Newton step `d` (R held at the point's residuals), the
R-weighted cost and det(R) at `t d` for `t` from 1 down to 1e-3 (which shares of the
step the engine's damping search could accept), the cost the linear model predicts,
and the same for the Levenberg-Marquardt steps at the damping the search would
settle at; and the straight jump to the final optimum.

Run: `python experiments/rocket_attitude_steps.py OUT.json FOLDER POINTS.npz
[--no-gyro] [INDEX ...]` (INDEX: which saved points, default 1 and 5).
"""

import json
import pathlib
import sys

import numpy as np


def main():
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    import jax
    import jax.numpy as jnp
    from rocket_attitude_convergence import capture, sim_log

    import diffpegasus.rocket as dr
    from diffpegasus._estimate._engine import lm_step, residuals_at
    from diffpegasus._estimate._fit import fit

    out = pathlib.Path(sys.argv[1])
    folder = pathlib.Path(sys.argv[2])
    saved = np.load(sys.argv[3])
    gyro = "--no-gyro" not in sys.argv
    which = [int(a) for a in sys.argv[4:] if not a.startswith("--")] or [1, 5]
    rocket = dr.read_rocket(folder / "rocket.toml", attitude=True)
    problem = dr.prepare(rocket, sim_log(folder, gyro))
    model, record, kw = capture(problem)
    nx, p = len(model.states), len(model.parameters)
    points = saved["points"]
    final = points[-1]
    structure = model.structure()
    results = {}
    for i in which:
        f = fit(model, record, start=points[i], max_iter=0, **kw)
        lay = f.layout
        z = np.asarray(f.z)
        free = np.asarray(lay.free_columns(np.asarray(model.free), nx, p))
        lin = f.linearisation
        h, g = np.asarray(lin.normal), np.asarray(lin.gradient)
        r = np.asarray(f.R)

        @jax.jit
        def costs(zz, lay=lay, r=r):
            e, d, _ = residuals_at(structure, lay, zz, nx, p)
            n = jnp.sum(lay.valid)
            rr = jnp.sum(e**2, axis=(0, 1)) / n
            return jnp.sum(e**2 / r) + jnp.sum(d**2), jnp.prod(rr)

        j0, det0 = map(float, costs(jnp.asarray(z)))
        row = {"det_r": det0, "weighted": j0, "lines": {}}
        for lam in (0.0, 1e-8, 1e-6, 1e-4, 1e-3, 1e-2, 1e-1):
            d = np.asarray(lm_step(jnp.asarray(h), jnp.asarray(g), free, lam))
            pred = float(j0 + 2 * g @ d + d @ h @ d)
            line = []
            for t in (1.0, 0.5, 0.2, 0.1, 0.03, 0.01):
                j1, det1 = map(float, costs(jnp.asarray(z + t * d)))
                lin_t = float(j0 + 2 * t * g @ d + t * t * d @ h @ d)
                line.append({"t": t, "weighted": j1, "predicted": lin_t, "det_r": det1})
            wind = model.parameters.index("wind_along") + nx
            row["lines"][str(lam)] = {
                "wind_step": float(d[wind]),
                "predicted_full": pred,
                "line": line,
            }
            print(i, lam, "wind", round(float(d[wind]), 4), flush=True)
            for x in line:
                print("   ", x, flush=True)
        zf = z.copy()
        zf[nx : nx + p] = final
        j1, det1 = map(float, costs(jnp.asarray(zf)))
        row["jump_to_final"] = {"weighted": j1, "det_r": det1}
        print(i, "jump", row["jump_to_final"], "from", j0, det0, flush=True)
        results[str(i)] = row
    out.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
