"""Why the attitude's fit walks the wind slowly: the engine's iteration from the
point mass's optimum, in chunks of `CHUNK` Gauss-Newton steps (each chunk a fit
from where the last stopped: the relaxation carries nothing between steps but the
point, and the damping stays 0 while every step is accepted), and at each chunk's
end, from the engine's own linearisation there:

- the normal matrix `H = sum_k J_k' J_k / R_k` the step uses, its condition number
  over the free parameters scaled to unit diagonal (as the step scales them);
- the curvature of the maximum-likelihood cost itself, `n/2 sum_k log S_k`
  (`S_k` channel k's sum of squares, R relaxed to `S_k / n`): `H - (2/n) sum_k c_k
  c_k'` with `c_k = J_k' e_k / R_k`, channel k's pull (the engine's R-weighted
  gradient is their sum, zero at the optimum; each alone is not where the channels
  disagree);
- the relaxation's rate: the largest eigenvalue of `(2/n) H^-1 sum_k c_k c_k'`,
  the share of the remaining distance a full Gauss-Newton step leaves in its
  direction; and that direction's largest components;
- each chunk's step against the distance left to the final optimum.

Writes JSON and an `.npz` of the points (the final optimum for other methods'
comparison).

Run: `python experiments/rocket_attitude_convergence.py OUT.json FOLDER [--no-gyro]`
(FOLDER a simulated flight with its `log.csv`; gyros used where it has a column).
"""

import json
import pathlib
import sys
import time

import numpy as np


CHUNK = 10


def sim_log(folder, gyro=True):
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    from rocket_attitude_gyro import sim_log as read

    return read(folder, gyro)


def capture(problem, free=None):
    """The attitude fit's model and record as fit_rocket builds them (the point
    mass's continuation run for real), without running it."""
    from diffpegasus._rocket import _identify

    seen = {}
    real = _identify.fit

    def fake(model, record, **kw):
        if len(model.states) > 6:
            seen["model"], seen["record"], seen["kw"] = model, record, kw
            raise _Stop
        return real(model, record, **kw)

    _identify.fit = fake
    try:
        _identify.fit_rocket(problem, free=free, throw=False)
    except _Stop:
        pass
    finally:
        _identify.fit = real
    return seen["model"], seen["record"], seen["kw"]


class _Stop(Exception):
    pass


def analyse(f):
    """Geometry of the step at `f`'s linearisation (see the module)."""
    lin = f.linearisation
    lay = f.layout
    nx, p = len(f.model.states), len(f.model.parameters)
    free = np.asarray(lay.free_columns(np.asarray(f.model.free), nx, p))
    local = np.asarray(lay.local_columns(nx, p))[0]
    jyw = np.asarray(lin.jacobian)[0]  # (length, outputs, local)
    ew = np.asarray(lin.whitened)[0]  # (length, outputs)
    n = int(np.sum(np.asarray(lay.valid)))
    h = np.asarray(lin.normal)
    g = np.asarray(lin.gradient)
    cols = np.flatnonzero(free)
    h = h[np.ix_(cols, cols)]
    g = g[cols]
    where = {c: i for i, c in enumerate(local)}
    pick = [where[c] for c in cols]
    c = np.einsum("tkl,tk->kl", jyw[:, :, pick], ew)  # (outputs, free)
    coupling = (2.0 / n) * c.T @ c
    d = np.sqrt(np.diag(h))
    hs = h / np.outer(d, d)
    true = h - coupling
    ts = true / np.outer(d, d)
    rate_matrix = np.linalg.solve(h, coupling)
    w, v = np.linalg.eig(rate_matrix)
    top = int(np.argmax(w.real))
    vec = v[:, top].real
    names = [f.model.parameters[i - nx] for i in cols]
    # the direction in parameter units scaled by the standard error
    cov = np.linalg.inv(h)
    se = np.sqrt(np.diag(cov))
    vz = vec / se
    vz = vz / np.linalg.norm(vz)
    order = np.argsort(-np.abs(vz))[:6]
    gn = -np.linalg.solve(h, g)
    newton = -np.linalg.solve(true, g)
    ev_t = np.linalg.eigvalsh(ts)
    return {
        "n": n,
        "cond_gn_scaled": float(np.linalg.cond(hs)),
        "cond_true_scaled": float(abs(ev_t[-1] / ev_t[0])),
        "true_min_eig_scaled": float(ev_t[0]),
        "rate": float(w.real[top]),
        "rates_top3": sorted(w.real.tolist(), reverse=True)[:3],
        "direction_in_stderrs": {names[i]: float(vz[i]) for i in order},
        "gn_step": dict(zip(names, gn.tolist(), strict=True)),
        "newton_step": dict(zip(names, newton.tolist(), strict=True)),
        "stderr": dict(zip(names, se.tolist(), strict=True)),
        "R": np.asarray(f.R).tolist(),
        "cost": float(f.cost),
    }


def main():
    out = pathlib.Path(sys.argv[1])
    folder = pathlib.Path(sys.argv[2])
    gyro = "--no-gyro" not in sys.argv
    import diffpegasus.rocket as dr
    from diffpegasus._estimate._fit import fit

    rocket = dr.read_rocket(folder / "rocket.toml", attitude=True)
    problem = dr.prepare(rocket, sim_log(folder, gyro))
    t0 = time.perf_counter()
    model, record, kw = capture(problem)
    t_pm = time.perf_counter() - t0
    names = list(model.parameters)
    rows, points = [], [np.asarray(model.start)]
    start = np.asarray(model.start)
    total = 0
    t0 = time.perf_counter()
    while True:
        t1 = time.perf_counter()
        f = fit(model, record, start=start, max_iter=CHUNK, **kw)
        row = analyse(f)
        row["iterations"] = total + int(f.iterations)
        row["seconds"] = time.perf_counter() - t1
        row["params"] = dict(zip(names, f.params.tolist(), strict=True))
        rows.append(row)
        print(
            row["iterations"],
            f"det(R) {row['cost']:.8g} rate {row['rate']:.5f}",
            f"cond {row['cond_gn_scaled']:.3g} ({row['cond_true_scaled']:.3g} true)",
            "wind",
            round(row["params"]["wind_along"], 3),
            f"{row['seconds']:.1f} s",
            flush=True,
        )
        points.append(np.asarray(f.params))
        total += int(f.iterations)
        start = np.asarray(f.params)
        if f.converged or total >= 500:
            break
    final = points[-1]
    free = np.asarray(model.free)
    for row, pt in zip(rows, points[1:], strict=True):
        left = (final - pt)[free]
        row["left_in_stderrs"] = float(
            np.max(np.abs(left) / np.array(list(rows[-1]["stderr"].values())))
        )
    res = {
        "folder": str(folder),
        "outputs": list(problem.outputs),
        "point_mass_seconds": t_pm,
        "attitude_seconds": time.perf_counter() - t0,
        "chunks": rows,
    }
    out.write_text(json.dumps(res, indent=1))
    np.savez(
        out.with_suffix(".npz"),
        points=np.array(points),
        names=np.array(names),
        free=free,
    )


if __name__ == "__main__":
    main()
