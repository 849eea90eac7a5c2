"""Steady-state Riccati equations of the discrete Kalman filter, differentiable.

Two solvers:

- [`solve_dare`][]: the standard filter DARE
  `P = Phi P Phi^T - Phi P C^T (C P C^T + Rm)^-1 C P Phi^T + Q` for a measurement-noise
  covariance `Rm`, by the structured doubling algorithm (Chu, Fan and Lin 2005). A
  fixed number of doublings in a `fori_loop`, so forward and reverse mode both
  differentiate through it; each doubling squares the closed-loop transition, so 40
  reach far below float64 resolution for any stabilisable problem.
- [`solve_filter_riccati`][]: the same equation written, as the filter-error method
  needs it (Maine and Iliff; Jategaonkar eq. 5.27), in terms of the *innovation*
  covariance `R = C P C^T + Rm`:
  `P = Phi (P - P C^T R^-1 C P) Phi^T + Q`. With `R` held (it is estimated in closed
  form from the innovations) this is not a standard DARE; it is solved by Newton's
  method started from the DARE with `Rm = R`, which lies above the solution, and is
  differentiated implicitly (one linear solve of the same Newton operator per
  tangent), so the Jacobian costs no iteration.

FVSysID solves the continuous-time limit `A P + P A^T - P C^T R^-1 C P / dt + F F^T = 0`;
the discrete equation is exact at the sample step.
"""

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float


_NEWTON_ITERATIONS = 30


def solve_dare(
    phi: Float[Array, "n n"],
    c: Float[Array, "m n"],
    q: Float[Array, "n n"],
    rm: Float[Array, "m m"],
    doublings: int = 40,
) -> Float[Array, "n n"]:
    """The a-priori error covariance `P` `(n, n)` of the steady-state Kalman filter
    for `x+ = phi x + w` (`cov w = q`), `y = c x + v` (`cov v = rm`): the stabilising
    solution of the filter DARE (`scipy.linalg.solve_discrete_are(phi.T, c.T, q, rm)`).
    """
    n = phi.shape[0]
    eye = jnp.eye(n)
    g = c.T @ jnp.linalg.solve(rm, c)

    def doubling(_, carry):
        a, gk, h = carry
        w = eye + gk @ h
        wa = jnp.linalg.solve(w, a)
        wg = jnp.linalg.solve(w, gk)
        a1 = a @ wa
        g1 = gk + a @ wg @ a.T
        h1 = h + a.T @ h @ wa
        return a1, 0.5 * (g1 + g1.T), 0.5 * (h1 + h1.T)

    # SDA in the control form X = A^T X (I + G X)^-1 A + H, with A = phi^T
    _, _, h = jax.lax.fori_loop(0, doublings, doubling, (phi.T, g, q))
    return h


def filter_residual(p, phi, c, q, r):
    """`Phi (P - P C^T R^-1 C P) Phi^T + Q - P`, zero at the solution."""
    s = c.T @ jnp.linalg.solve(r, c)
    return phi @ (p - p @ s @ p) @ phi.T + q - p


def _newton_operator(p, phi, c, r):
    """The derivative of [`filter_residual`][] in `P` as an `(n^2, n^2)` matrix on
    row-major `vec(P)`."""
    n = p.shape[0]
    s = c.T @ jnp.linalg.solve(r, c)
    eye = jnp.eye(n)
    ps = p @ s
    # d(P - P S P) = dP - dP (S P) - (P S) dP; row-major vec(A X B) = (A kron B^T) vec X
    inner = jnp.eye(n * n) - jnp.kron(eye, ps) - jnp.kron(ps, eye)
    return jnp.kron(phi, phi) @ inner - jnp.eye(n * n)


@jax.custom_jvp
def solve_filter_riccati(phi, c, q, r):
    """The a-priori error covariance `P` `(n, n)` of the steady-state filter whose
    innovation covariance is `r` `(m, m)`: `P = phi (P - P c^T r^-1 c P) phi^T + q`.
    The Kalman gain is `P c^T r^-1`; the measurement-noise covariance it implies is
    `r - c P c^T`, physical only while that stays positive (the filter-error
    method's gain constraint).

    Newton's method from the DARE solution with measurement noise `r` (an upper
    bound: the map is concave in `P`, so the iterates decrease monotonically to the
    maximal solution); stops when the residual is at rounding level. NaN when no
    solution is found (the constraint is badly violated).
    """
    n = phi.shape[0]
    p0 = solve_dare(phi, c, q, r)
    scale = jnp.maximum(jnp.max(jnp.abs(p0)), 1e-300)

    def cond(carry):
        _, k, res = carry
        return (k < _NEWTON_ITERATIONS) & (res > 1e-13)

    def body(carry):
        p, k, _ = carry
        g = filter_residual(p, phi, c, q, r)
        step = jnp.linalg.solve(_newton_operator(p, phi, c, r), -g.reshape(-1))
        p = p + step.reshape(n, n)
        p = 0.5 * (p + p.T)
        res = jnp.max(jnp.abs(filter_residual(p, phi, c, q, r))) / scale
        return p, k + 1, res

    p, _, res = jax.lax.while_loop(cond, body, (p0, 0, jnp.array(jnp.inf)))
    ok = (res < 1e-8) & jnp.all(jnp.isfinite(p))
    return jnp.where(ok, p, jnp.nan)


@solve_filter_riccati.defjvp
def _solve_filter_riccati_jvp(primals, tangents):
    phi, c, q, r = primals
    p = solve_filter_riccati(phi, c, q, r)
    # implicit function theorem: L dP = -(dG/d inputs) . tangents
    _, dg = jax.jvp(
        lambda a, b, d, e: filter_residual(p, a, b, d, e), primals, tangents
    )
    n = p.shape[0]
    dp = jnp.linalg.solve(_newton_operator(p, phi, c, r), -dg.reshape(-1))
    dp = dp.reshape(n, n)
    return p, 0.5 * (dp + dp.T)


def discretise(a, f, dt):
    """Transition `expm(a dt)` and process-noise covariance
    `Q = int_0^dt expm(a s) f f^T expm(a s)^T ds` (Van Loan) of `x' = a x + f w`,
    `w` unit-intensity white noise; `a` `(n, n)`, `f` `(n, k)`, `dt` s."""
    n = a.shape[0]
    block = jnp.block([[-a, f @ f.T], [jnp.zeros((n, n)), a.T]]) * dt
    e = jax.scipy.linalg.expm(block)
    phi = e[n:, n:].T
    return phi, phi @ e[:n, n:]
