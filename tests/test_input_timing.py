"""The input's unknown motion inside a sample interval, a nuisance of the process-noise
decision: its directions against a numpy Kalman filter and simulation, and what it
recovers on a linear short-period flight whose elevator steps between samples
(integrated exactly here by the matrix exponential)."""

import numpy as np
import scipy.linalg as sl

from diffpegasus._diagnose._input_timing import project_out, timing_directions
from diffpegasus._estimate._model import Record

from .helpers import (
    short_period_model,
    SHORT_PERIOD_SPEED,
)


TRUE = {"Za": -1.2, "Zd": -0.15, "Ma": -4.0, "Mq": -1.5, "Md": -6.0}
V = SHORT_PERIOD_SPEED
DT = 0.05
N = 300
NOISE = np.array([2e-4, 4e-4, 0.005])  # alpha, q (rad, rad/s), az (m/s^2)
# the elevator switches this far into its sample interval (the model, reading the
# samples, puts the switch half way)
FRACTION = 0.8
SWITCHES = [(1.0, 0.05), (3.0, -0.1), (4.0, 0.1), (5.0, -0.05)]  # s, rad change


MODEL = short_period_model(TRUE)
A = np.array([[TRUE["Za"], 1.0], [TRUE["Ma"], TRUE["Mq"]]])
B = np.array([TRUE["Zd"], TRUE["Md"]])
C = np.array([[1.0, 0.0], [0.0, 1.0], [V * TRUE["Za"], 0.0]])
D = np.array([0.0, 0.0, V * TRUE["Zd"]])


def _flight():
    """Samples of the short period flown with true steps at `FRACTION` of their
    sample interval: exact (piecewise-constant input, matrix exponential)."""
    t = DT * np.arange(N)
    times = np.array([s + FRACTION * DT for s, _ in SWITCHES])
    steps = np.array([d for _, d in SWITCHES])

    def de(s):
        return float(np.sum(steps[times <= s + 1e-12]))

    def propagate(x, h, u):
        m = np.zeros((3, 3))
        m[:2, :2], m[:2, 2] = A, B
        e = sl.expm(m * h)
        return e[:2, :2] @ x + e[:2, 2] * u

    x = np.zeros((N, 2))
    for k in range(N - 1):
        inside = times[(times > t[k]) & (times < t[k + 1])]
        edges = [t[k], *inside, t[k + 1]]
        xk = x[k]
        for a, b in zip(edges[:-1], edges[1:], strict=True):
            xk = propagate(xk, b - a, de(0.5 * (a + b)))
        x[k + 1] = xk
    u = np.array([de(s) for s in t])
    y = x @ C.T + u[:, None] * D[None, :]
    y = y + np.random.default_rng(5).normal(size=y.shape) * NOISE
    return Record(t, u[:, None], y, x0=np.zeros(2), name="steps")


def _numpy_filter(u, z, k, kick=None):
    """Innovations of the filter the package runs (prediction by RK4 at the
    sample step with the input linear between samples, correction `K nu`), in
    numpy; `k` zero: the simulation's residuals. `kick` `(samples,)`: added to
    the input at the two middle stages of each interval."""
    kick = np.zeros(len(u)) if kick is None else kick
    x = np.zeros(2)
    nu = np.zeros_like(z)
    for i in range(len(u)):
        nu[i] = z[i] - (C @ x + D * u[i])
        if i == len(u) - 1:
            break
        xc = x + k @ nu[i]
        um = 0.5 * (u[i] + u[i + 1]) + kick[i]
        k1 = A @ xc + B * u[i]
        k2 = A @ (xc + DT / 2 * k1) + B * um
        k3 = A @ (xc + DT / 2 * k2) + B * um
        k4 = A @ (xc + DT * k3) + B * u[i + 1]
        x = xc + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return nu


def _steady_gain():
    """A steady-state Kalman gain (scipy's Riccati) for some process noise."""
    phi = sl.expm(A * DT)
    q = np.diag([1e-6, 1e-5])
    r = np.diag(NOISE**2)
    p = sl.solve_discrete_are(phi.T, C.T, q, r)
    return p @ C.T @ np.linalg.inv(C @ p @ C.T + r)


def test_directions_match_numpy_and_recover_the_switch_instants():
    rec = _flight()
    u, z = np.asarray(rec.inputs)[:, 0], np.asarray(rec.measured)
    theta = np.array(MODEL.start)
    zero = np.zeros((1, 2, 3))
    e = _numpy_filter(u, z, np.zeros((2, 3)))
    h, intervals = timing_directions(MODEL, rec, theta, zero, [0], np.zeros(2), e)
    # every switch is chosen (they move the fit by far more than one unit of its
    # weighted sum of squares), nothing else, largest change first
    switch_samples = [int(np.floor(s / DT + 1e-9)) for s, _ in SWITCHES]
    assert sorted(i for _, i in intervals) == switch_samples
    assert intervals[0][1] in (switch_samples[1], switch_samples[2])
    # the directions: numpy's simulation with the input inside the interval (its
    # middle stages) raised, differenced (linear: exact to rounding)
    for j, (_, i) in enumerate(intervals):
        kick = np.zeros(N)
        kick[i] = 1.5 * (u[i + 1] - u[i])  # RK4 weighs the middle stages 2/3
        ref = _numpy_filter(u, z, np.zeros((2, 3)), kick) - e
        assert np.allclose(h[..., j], ref, rtol=1e-8, atol=1e-12 * np.abs(ref).max())
    # closed form: the input's impulse over the interval is du dt (1 - FRACTION)
    # in the flight, du dt / 2 in the model; the direction is the innovations'
    # change for du dt more, so the residual is (FRACTION - 1/2) times it, to
    # first order in the sample step (measured 0.295-0.309)
    w = 1.0 / np.sqrt(np.mean(e**2, axis=0))
    coef = np.linalg.lstsq(
        (h * w[None, :, None]).reshape(-1, h.shape[-1]),
        (e * w).reshape(-1),
        rcond=None,
    )[0]
    assert np.allclose(coef, FRACTION - 0.5, atol=0.02)
    # and what the directions leave is the sensor noise (measured 0.95-1.04 times
    # it, against 3.4-8.0 times before)
    left = project_out(e, h, np.mean(e**2, axis=0))
    assert np.all(np.std(e, axis=0) > 2.0 * NOISE)
    assert np.allclose(np.std(left, axis=0), NOISE, rtol=0.1)


def test_filter_directions_match_a_numpy_kalman_filter():
    rec = _flight()
    u, z = np.asarray(rec.inputs)[:, 0], np.asarray(rec.measured)
    theta = np.array(MODEL.start)
    k = _steady_gain()
    e = _numpy_filter(u, z, k)
    intervals = [(0, int(np.floor(s / DT + 1e-9))) for s, _ in SWITCHES]
    h, same = timing_directions(
        MODEL, rec, theta, k[None], [0], np.zeros(2), e, intervals=intervals
    )
    assert same == intervals
    for j, (_, i) in enumerate(intervals):
        kick = np.zeros(N)
        kick[i] = 1.5 * (u[i + 1] - u[i])
        ref = _numpy_filter(u, z, k, kick) - e
        assert np.allclose(h[..., j], ref, rtol=1e-8, atol=1e-12 * np.abs(ref).max())
