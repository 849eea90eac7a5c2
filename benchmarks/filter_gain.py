"""The filter-error method's gain on a vehicle whose flight condition changes:
one steady-state gain, a gain scheduled along the trajectory, or an extended
Kalman filter (covariance propagated and gain solved per sample) -- cost and
accuracy measured side by side in one run.

The vehicle is the short-period model of `tests/test_filter_gain.py` whose
dynamic pressure grows twentyfold over the record (400 samples at 20 Hz),
flown through process noise. For each filter, at the true parameters and
noise: the det of the innovations' sample covariance (the filter-error cost:
lower is a better filter; the EKF, exact for this linear time-varying system,
is the bound) and the time of one forward-mode Jacobian of the innovations in
the 7 unknowns (what every Gauss-Newton iteration evaluates), after
compilation. Then the steady and scheduled filter-error fits over seeds: the
estimates' RMSE against the truth.

Run: `python benchmarks/filter_gain.py` (writes `benchmarks/results/filter_gain.json`).
"""

import json
import pathlib
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np


jax.config.update("jax_enable_x64", True)
ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.test_filter_gain import (  # noqa: E402
    _observe,
    _rates,
    DT,
    F_TRUE,
    MODEL,
    NOISE,
    simulate,
    TRUE,
)

from diffpegasus._estimate._filter_error import (  # noqa: E402
    fit_filter_error,
    innovations,
    problem,
)
from diffpegasus._estimate._filter_gain import (  # noqa: E402
    ScheduledGain,
    SteadyStateGain,
)
from diffpegasus._estimate._riccati import discretise  # noqa: E402


def ekf_innovations(rec, z):
    """Innovations `(samples, outputs)` of the extended Kalman filter at unknowns
    `z = [theta, F]` with the true measurement noise: per sample the model
    linearised at the filtered state, `P` propagated by the exact discretisation,
    the gain from `S = C P C^T + Rm`."""
    names = MODEL.parameters
    p = {k: z[i] for i, k in enumerate(names)}
    f = jnp.diag(z[len(names) :])
    rm = jnp.diag(jnp.asarray(NOISE) ** 2)
    t = jnp.asarray(rec.t)
    u = jnp.asarray(rec.inputs)
    meas = jnp.asarray(rec.measured)

    def field(tk, x, uk):
        return _rates(tk, x, uk, p)

    def step(carry, k):
        x, pk = carry
        tk, uk, u1 = t[k], u[k], u[jnp.minimum(k + 1, len(rec.t) - 1)]
        y = _observe(tk, x, uk, p)
        c = jax.jacfwd(lambda s: _observe(tk, s, uk, p))(x)
        s = c @ pk @ c.T + rm
        gain = jnp.linalg.solve(s, c @ pk).T
        nu = meas[k] - y
        xc = x + gain @ nu
        pc = (jnp.eye(2) - gain @ c) @ pk
        um = 0.5 * (uk + u1)
        k1 = field(tk, xc, uk)
        k2 = field(tk + DT / 2, xc + DT / 2 * k1, um)
        k3 = field(tk + DT / 2, xc + DT / 2 * k2, um)
        k4 = field(tk + DT, xc + DT * k3, u1)
        x1 = xc + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        a = jax.jacfwd(lambda s: field(tk, s, uk))(xc)
        phi, q = discretise(a, f, DT)
        return (x1, phi @ pc @ phi.T + q), nu

    _, nu = jax.lax.scan(
        step, (jnp.zeros(2), jnp.zeros((2, 2))), jnp.arange(len(rec.t))
    )
    return nu


def timed(fn, *args, repeat=5):
    t0 = time.perf_counter()
    jax.block_until_ready(fn(*args))
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    for _ in range(repeat):
        jax.block_until_ready(fn(*args))
    return compile_s, (time.perf_counter() - t0) / repeat


def main():
    truth = np.array(list(TRUE.values()))
    z = jnp.asarray([*truth, *F_TRUE])
    seeds = (1, 2, 3)
    recs = [simulate(s) for s in seeds]
    out = {"filters": {}, "fits": {}}
    # the filter-error filters at the truth: R relaxed to the innovations
    # (twice from the noise, as the method converges to it)
    gains = {
        "steady": SteadyStateGain(),
        **{f"scheduled_{m}": ScheduledGain(points=m) for m in (8, 16)},
    }
    for name, g in gains.items():
        logdet, jac_s, comp_s = [], None, None
        for rec in recs:
            prob = problem(MODEL, [rec], (0, 1), g)
            r = jnp.diag(jnp.asarray(NOISE) ** 2 * 4)
            for _ in range(4):
                nu = innovations(MODEL, prob, z, r)[0][0]
                r = jnp.diag(jnp.mean(nu**2, axis=0))
            logdet.append(float(jnp.sum(jnp.log(jnp.diag(r)))))
            if jac_s is None:
                fn = jax.jit(
                    jax.jacfwd(
                        lambda v, prob=prob, r=r: innovations(MODEL, prob, v, r)[0]
                    )
                )
                comp_s, jac_s = timed(fn, z)
        out["filters"][name] = {
            "log_det_R_mean": float(np.mean(logdet)),
            "jacobian_s": jac_s,
            "compile_s": comp_s,
        }
        print(name, out["filters"][name], flush=True)
    logdet = []
    for rec in recs:
        nu = ekf_innovations(rec, z)
        logdet.append(float(jnp.sum(jnp.log(jnp.mean(nu**2, axis=0)))))
    fn = jax.jit(jax.jacfwd(lambda v: ekf_innovations(recs[0], v)))
    comp_s, jac_s = timed(fn, z)
    out["filters"]["ekf"] = {
        "log_det_R_mean": float(np.mean(logdet)),
        "jacobian_s": jac_s,
        "compile_s": comp_s,
    }
    print("ekf", out["filters"]["ekf"], flush=True)
    steady_j = out["filters"]["steady"]["jacobian_s"]
    for v in out["filters"].values():
        v["jacobian_vs_steady"] = v["jacobian_s"] / steady_j
    # full fits: steady against scheduled (8 points)
    for name, g in (
        ("steady", SteadyStateGain()),
        ("scheduled_8", ScheduledGain(points=8)),
    ):
        est, cost = [], []
        for rec in recs:
            f = fit_filter_error(
                MODEL,
                rec,
                process_noise={"alpha": 0.02, "q": 0.1},
                gain=g,
                full_R=True,
                throw=False,
            )
            est.append(f.params)
            cost.append(float(np.log(f.cost)))
        est = np.array(est)
        out["fits"][name] = {
            "rmse_relative": dict(
                zip(
                    MODEL.parameters,
                    (
                        np.sqrt(np.mean((est - truth) ** 2, axis=0)) / np.abs(truth)
                    ).tolist(),
                    strict=True,
                )
            ),
            "log_det_R_mean": float(np.mean(cost)),
        }
        print(name, out["fits"][name], flush=True)
    res = ROOT / "benchmarks" / "results"
    res.mkdir(exist_ok=True)
    (res / "filter_gain.json").write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
