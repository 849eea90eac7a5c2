"""The filter-error method's gain strategies on a small model whose flight
condition changes through the record: the short-period model of
`test_filter_error.py` with its derivatives scaled by a dynamic pressure that
grows twentyfold over the record (as a launch vehicle's does), flown through
process noise and simulated here in numpy. A steady-state gain linearised at the
start filters the end of the record with the gain of a vehicle twenty times
slower; the gain scheduled along the trajectory follows it."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffpegasus._estimate._filter_error import (
    choose_gain,
    fit_filter_error,
    innovations,
    problem,
)
from diffpegasus._estimate._filter_gain import ScheduledGain, SteadyStateGain
from diffpegasus._estimate._model import Model, Record


TRUE = {"Za": -0.3, "Zd": -0.05, "Ma": -1.0, "Mq": -0.4, "Md": -1.5}
DT = 0.05
N = 400
GROWTH = 20.0  # dynamic pressure at the end over that at the start
F_TRUE = (0.01, 0.05)
NOISE = (1e-3, 2e-3, 0.02)
V = 50.0


def _scale(t):
    return jnp.exp(jnp.log(GROWTH) * t / (DT * (N - 1)))


def _rates(t, x, u, p):
    a, q = x[0], x[1]
    s = _scale(t)
    return jnp.stack(
        [
            s * (p["Za"] * a + p["Zd"] * u[0]) + q,
            s * (p["Ma"] * a + p["Md"] * u[0]) + jnp.sqrt(s) * p["Mq"] * q,
        ]
    )


def _observe(t, x, u, p):
    return jnp.stack([x[0], x[1], V * _scale(t) * (p["Za"] * x[0] + p["Zd"] * u[0])])


MODEL = Model(("alpha", "q"), ("de",), ("alpha", "q", "az"), TRUE, _rates, _observe)


@functools.cache
def simulate(seed):
    """RK4 at the sample step (the model's own right-hand side, inputs linear
    between samples) plus process noise `F sqrt(dt) w` after each step, plus
    white measurement noise. The right-hand side and the outputs are compiled
    once (called op by op, the 2,000 calls of a record cost ~5 CPU-s); a seed's
    record is made once per process and shared by the tests (nothing mutates it)."""
    rng = np.random.default_rng(seed)
    t = DT * np.arange(N)
    de = np.zeros(N)
    for start in np.arange(1.0, 19.0, 2.0):
        de[(t >= start) & (t < start + 0.5)] = 0.05
        de[(t >= start + 0.5) & (t < start + 1.0)] = -0.05
    p = {k: jnp.asarray(v) for k, v in TRUE.items()}

    rates = jax.jit(_rates)

    def f(tk, x, u):
        return np.asarray(rates(tk, jnp.asarray(x), jnp.asarray([u]), p))

    x = np.zeros((N, 2))
    for k in range(N - 1):
        u0, u1 = de[k], de[k + 1]
        um = 0.5 * (u0 + u1)
        tk, xk = t[k], x[k]
        k1 = f(tk, xk, u0)
        k2 = f(tk + DT / 2, xk + DT / 2 * k1, um)
        k3 = f(tk + DT / 2, xk + DT / 2 * k2, um)
        k4 = f(tk + DT, xk + DT * k3, u1)
        x[k + 1] = xk + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        x[k + 1] += np.asarray(F_TRUE) * np.sqrt(DT) * rng.normal(size=2)
    y = np.asarray(
        jax.jit(jax.vmap(_observe, in_axes=(0, 0, 0, None)))(
            jnp.asarray(t), jnp.asarray(x), jnp.asarray(de[:, None]), p
        )
    )
    y = y + rng.normal(size=y.shape) * np.asarray(NOISE)
    return Record(t, de[:, None], y, x0=np.zeros(2), name=f"seed{seed}")


def test_one_point_schedule_is_the_steady_gain():
    """A schedule's first point is the steady-state gain (same linearisation
    point, same Riccati equation); with a constant flight condition every point
    would be it. Here the later points differ by the growth of the vehicle."""
    rec = simulate(0)
    z = jnp.asarray([*TRUE.values(), *F_TRUE])
    r = jnp.diag(jnp.asarray([2e-6, 1e-5, 1e-3]))
    steady = innovations(MODEL, problem(MODEL, [rec], (0, 1)), z, r)
    sched = innovations(
        MODEL, problem(MODEL, [rec], (0, 1), ScheduledGain(points=4)), z, r
    )
    np.testing.assert_allclose(sched[3][0, 0], steady[3][0, 0], rtol=1e-10)
    # the gain of the alpha measurement on the alpha state falls along the record
    # as the vehicle's own dynamics take over (measured 1.31 at the start, 0.13
    # at the end)
    k = np.asarray(sched[3][0, :, 0, 0])
    assert k[-1] < 0.2 * k[0], k


@pytest.fixture(scope="module")
def fits():
    out = []
    for seed in (1, 2, 3):
        rec = simulate(seed)
        out.append(
            {
                g: fit_filter_error(
                    MODEL,
                    rec,
                    process_noise={"alpha": 0.02, "q": 0.1},
                    gain=gain,
                    full_R=True,
                )
                for g, gain in (
                    ("steady", SteadyStateGain()),
                    ("scheduled", ScheduledGain(points=8)),
                    # the steady gain in the schedule's program (what a diagnosis
                    # runs, one compile for either choice)
                    ("steady8", SteadyStateGain(points=8)),
                )
            }
        )
    return out


def test_scheduled_gain_follows_a_changing_flight_condition(fits):
    truth = np.array(list(TRUE.values()))
    for f in fits:
        steady, sched = f["steady"], f["scheduled"]
        assert sched.converged and steady.converged
        # the schedule's innovations are smaller: det(R) measured 0.45 of the
        # steady gain's (geometric mean over the three seeds)
        assert sched.cost < 0.9 * steady.cost
        # and its estimates are the truth within 3.5 standard errors
        z = (sched.params - truth) / sched.stderr
        assert np.all(np.abs(z) < 3.5), z


def test_the_library_chooses_the_schedule_here_and_steady_at_trim():
    """The choice `fit --method fem` makes from the record: the gains solved
    along this record change (the vehicle speeds up twentyfold); along the
    constant-condition short period of `test_filter_error.py` they do not."""
    from .test_filter_error import MODEL as LTI, simulate as simulate_lti

    for model, rec, kind in (
        (MODEL, simulate(1), ScheduledGain),
        (LTI, simulate_lti(1), SteadyStateGain),
    ):
        theta = np.asarray(model.start, float)
        res = [np.tile(np.asarray(NOISE), (len(rec.t), 1))]
        g = choose_gain(
            model, [rec], (0, 1), np.zeros((1, 2)), theta, np.asarray(F_TRUE), res
        )
        assert isinstance(g, kind)


def test_a_steady_gain_in_the_schedules_program_is_the_steady_fit(fits):
    """`SteadyStateGain(points=8)` solves the one gain eight times (the program a
    `ScheduledGain(8)` compiles): the fit is the steady one, reported with one
    gain."""
    for f in fits:
        one, eight = f["steady"], f["steady8"]
        assert eight.converged and eight.iterations == one.iterations
        assert eight.gain.shape == one.gain.shape and eight.gain_times.shape == (1, 1)
        # the same arithmetic in another program (XLA fuses it differently):
        # measured differences at most 5e-15 relative over the three seeds
        np.testing.assert_allclose(eight.params, one.params, rtol=1e-12)
        np.testing.assert_allclose(eight.F, one.F, rtol=1e-12)
        np.testing.assert_allclose(eight.cost, one.cost, rtol=1e-12)
