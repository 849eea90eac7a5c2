"""Prototype, outside the engine: Levenberg-Marquardt with geodesic acceleration
(Transtrum and Sethna) on the attitude's fit from the point mass's optimum. Each
iteration: the engine's linearisation at the point (`fit(..., max_iter=0)`), the
step `v` as the engine's ([`lm_step`][]), the residuals' second directional
derivative along it by a finite difference (`r_vv = 2/h ((r(z + h v) - r(z))/h - J
v)`, h = 0.1), the acceleration `a` solving the same damped normal equations with
`J' r_vv`, the trial `z + v + a/2` accepted where the R-weighted cost falls and `2
|a| / |v| <= ALPHA` (scaled as the step is), else the damping raised tenfold; R
relaxed after each accepted step, stopped where det(R) changes by less than 1e-7
of itself (the engine's rule). Prints the iterations and the estimates against the
engine's (the `.npz`'s last point).

Run: `python experiments/rocket_attitude_geodesic.py OUT.json FOLDER POINTS.npz
[--no-gyro] [--plain]` (`--plain`: the same loop without the acceleration, the
engine's relaxation step for step, as the check of the loop).
"""

import json
import pathlib
import sys
import time

import numpy as np


ALPHA = 0.75
H = 0.1


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
    plain = "--plain" in sys.argv
    rocket = dr.read_rocket(folder / "rocket.toml", attitude=True)
    problem = dr.prepare(rocket, sim_log(folder, gyro))
    model, record, kw = capture(problem)
    nx, p = len(model.states), len(model.parameters)
    structure = model.structure()
    final = saved["points"][-1]
    params = np.asarray(model.start)
    damping = 0.0
    rows = []
    t0 = time.perf_counter()
    det_prev = np.inf
    resid = None
    for it in range(200):
        f = fit(model, record, start=params, max_iter=0, **kw)
        lay = f.layout
        if resid is None:

            @jax.jit
            def resid(zz, lay):
                e, d, _ = residuals_at(structure, lay, zz, nx, p)
                return e, d

        z = np.asarray(f.z)
        free = np.asarray(lay.free_columns(np.asarray(model.free), nx, p))
        lin = f.linearisation
        h, g = jnp.asarray(lin.normal), jnp.asarray(lin.gradient)
        jyw = np.asarray(lin.jacobian)[0]  # (length, outputs, local)
        local = np.asarray(lay.local_columns(nx, p))[0]
        r = np.asarray(f.R)
        w = 1 / np.sqrt(r)
        e0, _ = resid(jnp.asarray(z), lay)
        e0 = np.asarray(e0)[0]
        j0 = float(np.sum(e0**2 / r))
        det0 = float(np.prod(np.sum(e0**2, axis=0) / np.sum(np.asarray(lay.valid))))
        if abs(det_prev - det0) <= 1e-7 * abs(det0):
            break
        det_prev = det0
        scale = np.sqrt(np.clip(np.diag(np.asarray(h)), 1e-300, None)) * free
        trials = 0
        while True:
            lam = damping if trials == 0 else max(10 * damping, 1e-8)
            damping = lam
            trials += 1
            v = np.asarray(lm_step(h, g, free, lam))
            if plain:
                step, ratio = v, 0.0
            else:
                eh, _ = resid(jnp.asarray(z + H * v), lay)
                jv = jyw @ v[local]  # whitened
                rvv = 2 / H * ((np.asarray(eh)[0] - e0) * w / H - jv)
                gvv = np.zeros(len(z))
                np.add.at(gvv, local, np.einsum("tol,to->l", jyw, rvv))
                a = np.asarray(lm_step(h, jnp.asarray(gvv), free, lam))
                ratio = 2 * np.linalg.norm(a * scale) / np.linalg.norm(v * scale)
                step = v + 0.5 * a
            e1, _ = resid(jnp.asarray(z + step), lay)
            j1 = float(np.sum(np.asarray(e1)[0] ** 2 / r))
            if (j1 < j0 and ratio <= ALPHA) or lam >= 1e8:
                break
        params = (z + step)[nx : nx + p]
        damping = damping / 10
        wind = params[model.parameters.index("wind_along")]
        rows.append(
            {
                "iteration": it + 1,
                "det_r": det0,
                "damping": lam,
                "trials": trials,
                "ratio": ratio,
                "wind": float(wind),
            }
        )
        print(rows[-1], flush=True)
    est = dict(zip(model.parameters, params.tolist(), strict=True))
    ref = dict(zip(model.parameters, final.tolist(), strict=True))
    sd = dict(zip(model.parameters, f.stderr.tolist(), strict=True))
    diff = {
        k: (est[k] - ref[k]) / sd[k]
        for k, fr in zip(model.parameters, model.free, strict=True)
        if fr
    }
    res = {
        "iterations": len(rows),
        "seconds": time.perf_counter() - t0,
        "det_r": det0,
        "rows": rows,
        "off_engine_in_stderrs": diff,
    }
    print(res["iterations"], res["seconds"], det0, max(map(abs, diff.values())))
    out.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
