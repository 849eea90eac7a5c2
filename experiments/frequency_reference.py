"""An independent time-domain output-error optimum (NumPy and SciPy only, nothing of
the package), and the package's time-domain and frequency-domain output error
compared with it on the HFB-320 flight record (linear short-period model), the
unstable aircraft, and simulated ATTAS-like lateral manoeuvres.

The reference: the same estimator as the package's output error (maximum likelihood
with an unknown diagonal noise covariance, `sum_j log S_j`, `S_j` output `j`'s mean
squared residual; initial state held at the record's, the first measured sample or
the model file's `x0`), but

- the model written out here as matrices `A(p), B(p), C(p), D(p)` (the records read
  with `numpy.loadtxt`, not the package's reader);
- integrated **exactly**: the states at the samples from the matrix exponential of
  `[[A, B, 0], [0, 0, I/dt], [0, 0, 0]] dt` with the inputs linear between samples
  (what the package's engine assumes; checked against `scipy.integrate.solve_ivp`
  at `rtol=1e-11`); the package integrates by RK4 at the sample step;
- minimised by `scipy.optimize.least_squares` on the residuals weighted by the
  current `S_j`, re-weighted until the weights stop moving (the relaxation of
  Maine and Iliff: its fixed point is the stationary point of `sum_j log S_j`);
- bounds: the Cramer-Rao bound `(J^T R^-1 J)^-1` and Morelli and Klein's
  correction for coloured residuals, `M^-1 (sum_ij J_i^T R^-1 Rvv(i-j) R^-1 J_j)
  M^-1` over every lag of the residuals' sample autocorrelation `Rvv`.

`z` columns: differences in the package's time-domain corrected standard error
(`z_td`, what the frequency-domain page reports) and in the reference's corrected
standard error (`z_ref`).

Run: `python experiments/frequency_reference.py [--out DIR] [--seeds 1,2,3,4,5]`;
the last stdout line is the JSON summary (also DIR/summary.json).
"""

import argparse
import json
import pathlib

import numpy as np
import scipy.integrate
import scipy.linalg
import scipy.optimize


ROOT = pathlib.Path(__file__).resolve().parents[1]


# --- the reference estimator ------------------------------------------------------


def propagate(a, b, x0, u, dt):
    """States `(n, nx)` at the samples of `x' = A x + B u`, inputs linear between
    samples, exactly (matrix exponential)."""
    nx, nu = b.shape
    f = np.zeros((nx + 2 * nu, nx + 2 * nu))
    f[:nx, :nx], f[:nx, nx : nx + nu] = a, b
    f[nx : nx + nu, nx + nu :] = np.eye(nu) / dt
    e = scipy.linalg.expm(f * dt)
    phi, g0, g1 = e[:nx, :nx], e[:nx, nx : nx + nu], e[:nx, nx + nu :]
    # u(s) = u_k + s (u_(k+1) - u_k) / dt: the (1,2) block integrates the ramp
    x = np.empty((len(u), nx))
    x[0] = x0
    drive = u[:-1] @ (g0 - g1).T + u[1:] @ g1.T
    for k in range(len(u) - 1):
        x[k + 1] = phi @ x[k] + drive[k]
    return x


def propagate_ode(a, b, x0, t, u, rtol=1e-11):
    """The same by `solve_ivp` (DOP853) with `numpy.interp` inputs: the check."""

    def field(s, x):
        us = np.array([np.interp(s, t, u[:, j]) for j in range(u.shape[1])])
        return a @ x + b @ us

    sol = scipy.integrate.solve_ivp(
        field, (t[0], t[-1]), x0, method="DOP853", t_eval=t, rtol=rtol, atol=1e-14,
        max_step=float(t[1] - t[0]),
    )  # fmt: skip
    return sol.y.T


class LinearCase:
    """A linear model `matrices(p) -> (A, B, C, D)`, the record `(t, u, y, x0)`,
    the free parameters' names and start values."""

    def __init__(self, name, names, start, matrices, t, u, y, x0, states):
        self.name, self.names = name, list(names)
        self.states = list(states)  # the columns of y that measure the states
        self.start = np.asarray(start, float)
        self.matrices = matrices
        self.t, self.u, self.y = t, u, y
        self.x0 = np.asarray(x0, float)
        self.dt = float(t[1] - t[0])

    def simulate(self, p, exact=True):
        a, b, c, d = self.matrices(dict(zip(self.names, p, strict=True)))
        if exact:
            x = propagate(a, b, self.x0, self.u, self.dt)
        else:
            x = propagate_ode(a, b, self.x0, self.t, self.u)
        return x @ c.T + self.u @ d.T

    def residuals(self, p):
        return self.y - self.simulate(p)


def _sensitivities(case, p, rel=1e-6):
    """`(n, ny, np)` output sensitivities by central differences."""
    cols = []
    for i in range(len(p)):
        h = rel * max(abs(p[i]), 1e-3)
        up, dn = p.copy(), p.copy()
        up[i] += h
        dn[i] -= h
        cols.append((case.simulate(up) - case.simulate(dn)) / (2 * h))
    return np.stack(cols, axis=-1)


def equation_error(case, states):
    """Start values independent of any integration: the state equations with the
    measured states (`states`: their columns in `y`) and their central-difference
    derivatives, and the output equations, by least squares with each channel
    scaled by its spread."""
    x = case.y[:, states]
    xdot = np.gradient(x, case.dt, axis=0)
    scale = np.concatenate([np.std(xdot, axis=0), np.std(case.y, axis=0)])

    def res(p):
        a, b, c, d = case.matrices(dict(zip(case.names, p, strict=True)))
        r = np.column_stack(
            [xdot - x @ a.T - case.u @ b.T, case.y - x @ c.T - case.u @ d.T]
        )
        return (r / scale).ravel()

    return scipy.optimize.least_squares(res, case.start, method="lm").x


def output_error(case, start=None, tol=1e-12, max_outer=100):
    """The maximum-likelihood estimate with a diagonal noise covariance: returns a
    dict with `params`, `stderr` (Cramer-Rao), `stderr_corrected` (Morelli-Klein,
    every lag), `cost` (`sum_j log S_j`) and `outer` (re-weightings used)."""
    p = np.array(case.start if start is None else start, float)
    s = np.mean(case.residuals(p) ** 2, axis=0)
    for outer in range(1, max_outer + 1):  # noqa: B007 (reported)
        w = 1.0 / np.sqrt(s)
        sol = scipy.optimize.least_squares(
            lambda q, w=w: (case.residuals(q) * w).ravel(),
            p, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, x_scale="jac",
        )  # fmt: skip
        step = np.max(np.abs(sol.x - p) / np.maximum(np.abs(sol.x), 1e-12))
        p = sol.x
        s_new = np.mean(case.residuals(p) ** 2, axis=0)
        moved = np.max(np.abs(s_new / s - 1.0))
        s = s_new
        if step < tol and moved < 1e-10:
            break
    v = case.residuals(p)
    n = len(v)
    jac = _sensitivities(case, p)  # d y_model / d p, (n, ny, np)
    rinv = 1.0 / s
    jw = jac * rinv[None, :, None]  # R^-1 J per sample
    info = np.einsum("nip,niq->pq", jac, jw)
    m_inv = np.linalg.inv(info)
    # sum_ij jw_i^T Rvv(i - j) jw_j, Rvv(k) = 1/n sum_i v_(i+k) v_i^T, by FFT
    size = 2 * n
    fv = np.fft.rfft(v, size, axis=0)  # (f, ny)
    fj = np.fft.rfft(jw, size, axis=0)  # (f, ny, np)
    # Rvv's transform is fv fv^H / n and the double sum sum_f fj^H Rvv_f fj / size
    # (Parseval); rfft holds half the spectrum: weights 2 except at 0 and Nyquist
    wts = np.full(fv.shape[0], 2.0)
    wts[0] = 1.0
    wts[-1] = 1.0
    mid = np.einsum("f,fap,fa,fb,fbq->pq", wts, fj.conj(), fv, fv.conj(), fj).real / (
        n * size
    )
    cov = m_inv @ mid @ m_inv
    return {
        "params": p,
        "stderr": np.sqrt(np.diag(m_inv)),
        "stderr_corrected": np.sqrt(np.maximum(np.diag(cov), np.diag(m_inv))),
        "cost": float(np.sum(np.log(s))),
        "outer": outer,
        "noise_variance": s,
    }


# --- the cases, written out from the model files' equations -----------------------


def _asc(path):
    """An FVSysID `.asc` file: columns by the header's names."""
    lines = pathlib.Path(path).read_text().splitlines()
    header = lines[3].split()
    data = np.loadtxt(lines[6:])
    return {name: data[:, i] for i, name in enumerate(header)}


HFB_V0, HFB_G, HFB_MT = 104.67, 9.80665, -7.0153e-6  # as in examples/hfb320_linear.py


def hfb320_case(path):
    """`examples/hfb320_linear.py`: states alpha, q; inputs de, V, thrust and the
    constant 1 (trim terms); outputs alpha, q, qdot, az."""
    col = _asc(path)
    t = col["T"]
    u = np.column_stack([col["DELV"], col["TASCG"], col["THRUST"], np.ones_like(t)])
    y = np.column_stack([col["ALFCG"], col["Q"], col["QDOT"], col["AZCG"]])
    names = ("Za", "ZV", "Z0", "Ma", "Mq", "Mde", "MV", "M0", "az0")
    start = (-0.56, -0.0023, 0.3, -3.6, -1.1, -5.1, 0.0009, 0.3, 0.0)

    def matrices(p):
        a = np.array([[p["Za"], 1.0], [p["Ma"], p["Mq"]]])
        b = np.array([[0.0, p["ZV"], 0.0, p["Z0"]],
                      [p["Mde"], p["MV"], HFB_MT, p["M0"]]])  # fmt: skip
        c = np.array([[1.0, 0.0], [0.0, 1.0], a[1], [HFB_V0 * p["Za"], 0.0]])
        d = np.zeros((4, 4))
        d[2] = b[1]
        d[3] = [0.0, HFB_V0 * p["ZV"], 0.0, HFB_V0 * p["Z0"] - HFB_G + p["az0"]]
        return a, b, c, d

    return LinearCase("hfb320", names, start, matrices, t, u, y, y[0, :2], (0, 1))


UNSTABLE_U0, UNSTABLE_ZQ = 44.5695, -1.4768  # as in examples/unstable_aircraft.py


def unstable_case(path):
    """`examples/unstable_aircraft.py`: states w, q; input de; outputs az, w, q;
    `Zq` held; `x0 = 0`."""
    col = _asc(path)
    t = col["T"]
    u = col["DE"][:, None]
    y = np.column_stack([col["AZ"], col["W"], col["Q"]])
    names = ("Zw", "Zde", "Mw", "Mq", "Mde")
    start = (-1.22871, -4.20491, 0.116197, -2.70670, -18.7718)

    def matrices(p):
        a = np.array([[p["Zw"], UNSTABLE_U0 + UNSTABLE_ZQ], [p["Mw"], p["Mq"]]])
        b = np.array([[p["Zde"]], [p["Mde"]]])
        c = np.array([[p["Zw"], UNSTABLE_ZQ], [1.0, 0.0], [0.0, 1.0]])
        d = np.array([[p["Zde"]], [0.0], [0.0]])
        return a, b, c, d

    return LinearCase(
        "unstable_aircraft", names, start, matrices, t, u, y, (0.0, 0.0), (1, 2)
    )


LATERAL = ("Lp", "Lr", "Lda", "Ldr", "Lbeta", "Np", "Nr", "Nda", "Ndr", "Nbeta",
           "Yp", "Yr", "Yda", "Ydr", "Ybeta")  # fmt: skip


def attas_case(seed):
    """The lateral model without biases on `_shared.attas_like(seed)`; start values
    the package's (`lateral_model`'s) book values."""
    from _shared import attas_like

    import diffpegasus as dp  # only for the start values the package fit uses

    t, u, y = attas_like(seed=seed)
    model = dp.lateral.lateral_model(state_biases=False, output_biases=False)
    start = [float(model.start[model.parameters.index(n)]) for n in LATERAL]

    def matrices(p):
        a = np.array([[p["Lp"], p["Lr"]], [p["Np"], p["Nr"]]])
        b = np.array([[p["Lda"], p["Ldr"], p["Lbeta"]],
                      [p["Nda"], p["Ndr"], p["Nbeta"]]])  # fmt: skip
        c = np.vstack([a, [[p["Yp"], p["Yr"]]], np.eye(2)])
        d = np.vstack([b, [[p["Yda"], p["Ydr"], p["Ybeta"]]], np.zeros((2, 3))])
        return a, b, c, d

    return LinearCase(f"attas_like_seed{seed}", LATERAL, start, matrices, t, u, y,
                      (0.0, 0.0), (3, 4))  # fmt: skip


# --- the comparison ---------------------------------------------------------------


def package_fits(label, case):
    """The package's time-domain output error (single and, for the unstable
    aircraft, multiple shooting as its model file asks) and frequency-domain
    output error (default band and the band of the frequency-domain page)."""
    from _shared import attas_like, shared_data

    import diffpegasus as dp

    if label == "hfb320":
        spec = dp.load_model_file(ROOT / "examples" / "hfb320_linear.py")
        model = spec.model
        rec = dp.load_record(model, shared_data("hfb320/hfb320_1_10.asc"), spec.columns)
        tds = {"single shooting": dp.fit(model, rec)}
        band = (0.0, 1.5)
    elif label == "unstable_aircraft":
        spec = dp.load_model_file(ROOT / "examples" / "unstable_aircraft.py")
        model = spec.model
        rec = dp.load_record(
            model, shared_data("unstable_aircraft/unStabAC_sim.asc"), spec.columns,
            x0=spec.x0,
        )  # fmt: skip
        tds = {
            "multiple shooting": dp.fit(model, rec, shooting=spec.shooting),
            # single shooting from the multiple-shooting optimum (it cannot start
            # from the model file's values on this unstable model)
        }
        tds["single shooting"] = dp.fit(
            model, rec, start=tds["multiple shooting"].params
        )
        band = (0.0, 2.0)
    else:
        model = dp.lateral.lateral_model(state_biases=False, output_biases=False)
        seed = int(label.rsplit("seed", 1)[1])
        rec = dp.Record(*attas_like(seed=seed), x0=np.zeros(2))
        tds = {"single shooting": dp.fit(model, rec)}
        band = (0.0, 3.0)
    fds = {
        "default band": dp.estimate(model, rec, dp.FrequencyOutputError()),
        f"band {band[0]:g}-{band[1]:g} Hz": dp.estimate(
            model, rec, dp.FrequencyOutputError(band=band)
        ),
    }
    idx = [model.parameters.index(n) for n in case.names]

    def pick(f):
        # parameters a method does not estimate (the frequency domain's trim
        # constants) are NaN, left out of the comparison
        free = np.asarray(getattr(f, "free", np.ones(len(model.parameters), bool)))
        return (
            np.where(free, np.asarray(f.params), np.nan)[idx],
            np.asarray(f.stderr_corrected)[idx],
        )

    return {k: pick(v) for k, v in tds.items()}, {k: pick(v) for k, v in fds.items()}


def reference_optimum(case):
    """Output error from the model file's start values and from the equation-error
    estimate; the lower cost wins (an unstable model's single shooting from the
    file's values can end in a local minimum)."""
    fits = [
        output_error(case),
        output_error(case, start=equation_error(case, case.states)),
    ]
    best = min(fits, key=lambda f: f["cost"])
    best["costs_from_starts"] = [f["cost"] for f in fits]
    return best


def compare(case):
    ref = reference_optimum(case)
    # the exact propagation against an adaptive integrator, at the optimum
    ode_gap = float(
        np.max(
            np.abs(case.simulate(ref["params"]) - case.simulate(ref["params"], False))
        )
        / np.max(np.abs(case.y), initial=1e-300)
    )
    # the optimum does not depend on the start: again from 10% off
    again = output_error(case, start=ref["params"] * 1.1)
    tds, fds = package_fits(case.name, case)
    sd_ref = ref["stderr_corrected"]
    out = {
        "samples": len(case.t),
        "dt_s": case.dt,
        "reference_reweightings": ref["outer"],
        "reference_cost_from_file_start_and_equation_error_start": ref[
            "costs_from_starts"
        ],
        "exact_vs_solve_ivp_max_rel": ode_gap,
        "restart_max_change_in_ref_stderr": float(
            np.max(np.abs(again["params"] - ref["params"]) / sd_ref)
        ),
        "parameters": {},
        "max_abs_z_ref": {},
        "max_abs_z_td": {},
    }
    for i, n in enumerate(case.names):
        row = {
            "reference": float(ref["params"][i]),
            "reference_crb": float(ref["stderr"][i]),
            "reference_stderr": float(sd_ref[i]),
        }
        td_sd = next(iter(tds.values()))[1][i]
        for k, (p, _sd) in {**{"td " + a: b for a, b in tds.items()},
                           **{"fd " + a: b for a, b in fds.items()}}.items():  # fmt: skip
            row[k] = float(p[i])
            row[k + " z_ref"] = float((p[i] - ref["params"][i]) / sd_ref[i])
            row[k + " z_td"] = float((p[i] - ref["params"][i]) / td_sd)
        row["package_td_stderr"] = float(td_sd)
        out["parameters"][n] = row
    for k in [*("td " + a for a in tds), *("fd " + a for a in fds)]:
        for z in ("z_ref", "z_td"):
            out["max_abs_" + z][k] = float(
                np.nanmax([abs(r[f"{k} {z}"]) for r in out["parameters"].values()])
            )
    return out


def main():
    import sys

    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    from _shared import shared_data

    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/frequency_reference")
    )
    parser.add_argument("--seeds", default="1,2,3,4,5", help="ATTAS-like seeds")
    args = parser.parse_args()
    cases = []
    path = shared_data("hfb320/hfb320_1_10.asc")
    if path.exists():
        cases.append(hfb320_case(path))
    path = shared_data("unstable_aircraft/unStabAC_sim.asc")
    if path.exists():
        cases.append(unstable_case(path))
    cases += [attas_case(int(s)) for s in args.seeds.split(",") if s]
    summary = {}
    for case in cases:
        summary[case.name] = res = compare(case)
        print(f"{case.name}: |z| in the reference's corrected standard errors "
              + ", ".join(f"{k} {v:.2f}" for k, v in res["max_abs_z_ref"].items()))  # fmt: skip
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
