"""Classical fourth-order Runge-Kutta: a `lax.scan` for the fits and simulations, and the
same tableau as a diffrax solver (diffrax has none built in), which tests check it against.

Used with a constant step equal to the sample interval, as flight-test output-error
codes do: with inputs interpolated linearly between samples, the two middle stages see
the inputs averaged over the step.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np


def rk4_scan(field, x0, ts, dt, u=None):
    """Classical RK4 with constant step `dt` from `x0` at `ts[0]`: the states at
    `ts`, `(len(ts), states)`. `field(t, x)`, or `field(t, x, u)` given `u`
    `(len(ts), inputs)` the inputs at `ts` (the middle stages then see the mean of a
    step's two: linear interpolation without a lookup per stage). A `lax.scan`
    rather than `diffrax.diffeqsolve`: it compiles in half the time, runs twice as
    fast and, having no host callbacks, lands in JAX's persistent compilation
    cache; tests check it against diffrax's solve with the same tableau. The four
    stages are one loop body, so a program holds one copy of `field`, not four: the
    launch vehicle's first fit compiles in 24 CPU-s instead of 32, and runs as fast
    (`benchmarks/suite_programs.py`)."""
    if u is None:
        stage = lambda t, x, _: field(t, x)  # noqa: E731
        u = jnp.zeros((ts.shape[0], 0))
    else:
        stage = field

    def step(x, inp):
        t, u0, um, u1 = inp
        x1 = rk4_step(stage, t, x, dt, jnp.stack([u0, um, um, u1]))
        return x1, x1

    inputs = (ts[:-1], u[:-1], 0.5 * (u[:-1] + u[1:]), u[1:])
    _, xs = jax.lax.scan(step, x0, inputs)
    return jnp.concatenate([x0[None], xs])


def rk4_step(field, t, x, dt, us=None):
    """One classical RK4 step of `dt` from `x` at `t`: `field(t, x)`, or
    `field(t, x, u)` given `us` `(4, inputs)`, the inputs each stage sees. The four
    stages are one loop body, so a compiled program holds one copy of `field`."""

    def one(i, carry):
        k, acc = carry
        h = jnp.asarray(_C)[i] * dt
        k = field(t + h, x + h * k) if us is None else field(t + h, x + h * k, us[i])
        return k, acc + jnp.asarray(_B)[i] * k

    zero = jnp.zeros_like(x)
    _, acc = jax.lax.fori_loop(0, 4, one, (zero, zero))
    return x + dt / 6 * acc


_C = np.array([0.0, 0.5, 0.5, 1.0])  # the stages' times, in steps
_B = np.array([1.0, 2.0, 2.0, 1.0])  # their weights, times 6


@functools.cache
def _diffrax_rk4() -> type:
    # diffrax costs seconds to import: only the simulator and the tests need the
    # solver class, so it is built on first use, not when a fit imports rk4_scan
    from collections.abc import Callable
    from typing import ClassVar

    import diffrax

    rk4_tableau = diffrax.ButcherTableau(
        a_lower=(np.array([0.5]), np.array([0.0, 0.5]), np.array([0.0, 0.0, 1.0])),
        b_sol=np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
        b_error=np.zeros(4),
        c=np.array([0.5, 0.5, 1.0]),
    )

    class RK4(diffrax.AbstractERK):
        """The classical RK4 method as a diffrax solver (fixed step only: its error
        estimate is zero); the same tableau as [`rk4_scan`][]."""

        tableau: ClassVar[diffrax.ButcherTableau] = rk4_tableau
        interpolation_cls: ClassVar[Callable[..., diffrax.LocalLinearInterpolation]] = (
            diffrax.ThirdOrderHermitePolynomialInterpolation.from_k
        )

        def order(self, terms):
            del terms
            return 4

    RK4.__module__, RK4.__qualname__ = __name__, "RK4"
    return RK4


def __getattr__(name: str):
    if name == "RK4":
        return _diffrax_rk4()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
