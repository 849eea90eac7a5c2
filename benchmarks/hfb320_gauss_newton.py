"""An independent HFB-320 output-error fit: the straightforward JAX Gauss-Newton a
user would write, sharing no code with diffpegasus (its own reader, model, RK4 and
optimiser). The baseline of `benchmarks/hfb320_process.py`.

Model (Jategaonkar, *Flight Vehicle System Identification*, test case 4): states
`V, alpha, theta, q`, inputs elevator and thrust, outputs `V, alpha, theta, q, qdot,
ax, az`; the book's constants and start values; initial state held at the book's.
RK4 at the sample step, the middle stages seeing the inputs averaged over the step.
Cost det(R), R diagonal, relaxed (re-estimated after every step); Gauss-Newton with
step halving; Jacobians by `jax.jacfwd`; float64.

Run: `python benchmarks/hfb320_gauss_newton.py [FILE.asc]`; prints a JSON line with
det(R), the estimates and iterations.
"""

import json
import pathlib
import sys
import time


T_START = time.perf_counter()

import jax  # noqa: E402


jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402


DEFAULT = (
    pathlib.Path(__file__).resolve().parents[2] / "shared/data/hfb320/hfb320_1_10.asc"
)

G, S_M, SC_IY, T_MOMENT = 9.80665, 4.028e-3, 8.0027e-4, -7.0153e-6
V0, MASS, SIGMA_T, RHO, CBAR = 104.67, 7472.0, 0.0524, 0.792, 1.215
X0 = np.array([106.023, 0.111685, 0.104887, -0.00332659])
NAMES = ["CD0", "CDV", "CDa", "CL0", "CLV", "CLa", "CM0", "CMV", "CMa", "CMq", "CMde"]
START = np.array(
    [5.67516e-3, 7.72612e-3, 0.674256, -0.318267, 0.260317, 5.37576,
     4.98218e-2, 1.89182e-2, -0.498586, -25.8439, -0.990687]
)  # fmt: skip
OUTPUTS = ["TASCG", "ALFCG", "THE", "Q", "QDOT", "AXCG", "AZCG"]


def read_asc(path):
    """The FVSysID text file: a line of column names, then rows of numbers."""
    lines = pathlib.Path(path).read_text().splitlines()
    names = next(ln.split() for ln in lines if ln.split()[:1] == ["T"])
    rows = []
    for ln in lines:
        try:
            rows.append([float(v) for v in ln.split()])
        except ValueError:
            continue
    data = np.array([r for r in rows if len(r) == len(names)])
    return {n: data[:, i] for i, n in enumerate(names)}


def model(x, u, p):
    """State rates and outputs."""
    v, a, th, q = x
    de, thrust = u
    cd0, cdv, cda, cl0, clv, cla, cm0, cmv, cma, cmq, cmde = p
    qb = 0.5 * RHO * v * v
    cd = cd0 + cdv * v / V0 + cda * a
    cl = cl0 + clv * v / V0 + cla * a
    cm = cm0 + cmv * v / V0 + cma * a + cmq * q * CBAR / V0 + cmde * de
    qdot = qb * SC_IY * cm + T_MOMENT * thrust
    vdot = -qb * S_M * cd + thrust / MASS * jnp.cos(a + SIGMA_T) - G * jnp.sin(th - a)
    adot = (
        -qb * S_M / v * cl
        - thrust / (MASS * v) * jnp.sin(a + SIGMA_T)
        + q
        + G / v * jnp.cos(th - a)
    )
    cx = cl * jnp.sin(a) - cd * jnp.cos(a)
    cz = -cl * jnp.cos(a) - cd * jnp.sin(a)
    ax = qb * S_M * cx + thrust / MASS * jnp.cos(SIGMA_T)
    az = qb * S_M * cz - thrust / MASS * jnp.sin(SIGMA_T)
    return jnp.stack([vdot, adot, q, qdot]), jnp.stack([v, a, th, q, qdot, ax, az])


def simulate(p, u, dt):
    """Outputs at every sample, `(samples, 7)`, by RK4 at the sample step."""
    um = 0.5 * (u[1:] + u[:-1])

    def step(x, uu):
        u0, uh, u1 = uu
        k1, y = model(x, u0, p)
        k2, _ = model(x + dt / 2 * k1, uh, p)
        k3, _ = model(x + dt / 2 * k2, uh, p)
        k4, _ = model(x + dt * k3, u1, p)
        return x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4), y

    x_last, ys = jax.lax.scan(step, jnp.asarray(X0), (u[:-1], um, u[1:]))
    return jnp.concatenate([ys, model(x_last, u[-1], p)[1][None]])


@jax.jit
def linearise(p, u, z, dt):
    """Residuals `(samples, 7)` and their Jacobian `(samples, 7, params)`."""
    jac = jax.jacfwd(simulate)(p, u, dt)
    return z - simulate(p, u, dt), -jac


@jax.jit
def gauss_newton_step(p, u, z, dt, r):
    """The weighted Gauss-Newton step at `p` for the weights `1/r`, and the
    residuals there."""
    e, jac = linearise(p, u, z, dt)
    w = 1.0 / r
    h = jnp.einsum("nop,no,noq->pq", jac, w[None, :], jac)
    g = jnp.einsum("nop,no,no->p", jac, w[None, :], e)
    return -jnp.linalg.solve(h, g), e


@jax.jit
def residuals(p, u, z, dt):
    return z - simulate(p, u, dt)


def fit(data, rtol=1e-8, max_iter=50):
    dt = float(data["T"][1] - data["T"][0])
    u = jnp.asarray(np.column_stack([data["DELV"], data["THRUST"]]))
    z = jnp.asarray(np.column_stack([data[c] for c in OUTPUTS]))
    p = jnp.asarray(START)
    e = residuals(p, u, z, dt)
    r = jnp.mean(e**2, axis=0)
    cost = float(jnp.prod(r))
    for it in range(1, max_iter + 1):  # noqa: B007 (returned)
        step, e = gauss_newton_step(p, u, z, dt, r)
        j0 = float(jnp.sum(e**2 / r))
        lam = 1.0
        while True:  # halve the step until the weighted cost falls
            trial = p + lam * step
            e_new = residuals(trial, u, z, dt)
            j1 = float(jnp.sum(e_new**2 / r))
            if np.isfinite(j1) and j1 < j0 or lam < 1e-4:
                break
            lam /= 2
        p = trial
        r = jnp.mean(e_new**2, axis=0)  # relaxation: R at the new estimate
        new_cost = float(jnp.prod(r))
        done = abs(cost - new_cost) <= rtol * new_cost
        cost = new_cost
        if done:
            break
    return np.asarray(p), cost, it


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else DEFAULT
    p, cost, iterations = fit(read_asc(path))
    print(
        json.dumps(
            {
                "cost": cost,
                "iterations": iterations,
                "estimates": dict(zip(NAMES, p.tolist(), strict=True)),
                "in_process_s": time.perf_counter() - T_START,
            }
        )
    )


if __name__ == "__main__":
    main()
