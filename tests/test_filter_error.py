"""The filter-error method: Riccati solvers against scipy, exact derivatives through
the filter against finite differences, and a small Monte Carlo on a linear
short-period model flown through process noise (simulated here in numpy)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg as sl
import scipy.signal
import scipy.stats

from diffpegasus._estimate._filter_error import (
    fit_filter_error,
    innovations,
    problem,
)
from diffpegasus._estimate._fit import fit
from diffpegasus._estimate._model import Record
from diffpegasus._estimate._riccati import (
    discretise,
    solve_dare,
    solve_filter_riccati,
)

from .helpers import (
    short_period_model,
    SHORT_PERIOD_SPEED,
)


TRUE = {"Za": -1.2, "Zd": -0.15, "Ma": -4.0, "Mq": -1.5, "Md": -6.0}
V = SHORT_PERIOD_SPEED
DT = 0.05
N = 400
F_TRUE = (0.01, 0.05)  # alpha (rad/sqrt(s)), q (rad/s/sqrt(s)): turbulence-like
NOISE = (2e-3, 4e-3, 0.05)  # measurement noise std of alpha, q, az


MODEL = short_period_model(TRUE)


def _matrices(p):
    a = np.array([[p["Za"], 1.0], [p["Ma"], p["Mq"]]])
    b = np.array([p["Zd"], p["Md"]])
    c = np.array([[1.0, 0.0], [0.0, 1.0], [V * p["Za"], 0.0]])
    d = np.array([0.0, 0.0, V * p["Zd"]])
    return a, b, c, d


def _input():
    """A 3-2-1-1 of 0.05 rad with 1 s unit, then a doublet."""
    t = DT * np.arange(N)
    de = np.zeros(N)
    for start, width, sign in [
        (1, 3, 1),
        (4, 2, -1),
        (6, 1, 1),
        (7, 1, -1),
        (12, 1, 1),
        (13, 1, -1),
    ]:
        de[(t >= start) & (t < start + width)] = 0.05 * sign
    return t, de


def simulate(seed, f=F_TRUE):
    """The model integrated by RK4 at the sample step (inputs linear between
    samples, as the filter predicts) plus discrete process noise of covariance
    `Q = int expm(A s) F F^T expm(A s)^T ds` after each step, plus white
    measurement noise."""
    rng = np.random.default_rng(seed)
    a, b, c, d = _matrices(TRUE)
    t, de = _input()
    fm = np.diag(f)
    _, q = discretise(jnp.asarray(a), jnp.asarray(fm), DT)
    q = np.asarray(q)
    lq = np.linalg.cholesky(q + 1e-300 * np.eye(2)) if np.any(q) else np.zeros((2, 2))
    x = np.zeros((N, 2))
    for k in range(N - 1):
        u0, u1 = de[k], de[k + 1]
        um = 0.5 * (u0 + u1)
        xk = x[k]
        k1 = a @ xk + b * u0
        k2 = a @ (xk + DT / 2 * k1) + b * um
        k3 = a @ (xk + DT / 2 * k2) + b * um
        k4 = a @ (xk + DT * k3) + b * u1
        x[k + 1] = xk + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4) + lq @ rng.normal(size=2)
    y = x @ c.T + de[:, None] * d[None, :]
    y = y + rng.normal(size=y.shape) * np.asarray(NOISE)[None, :]
    return Record(t, de[:, None], y, x0=np.zeros(2), name=f"seed{seed}")


def test_dare_matches_scipy():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(4, 4)) - 1.5 * np.eye(4)
    a[0, 1] = 3.0  # unstable-ish coupling is fine: the DARE only needs detectability
    c = rng.normal(size=(3, 4))
    f = np.diag([0.3, 0.1, 0.2, 0.5])
    phi, q = jax.jit(discretise)(jnp.asarray(a), jnp.asarray(f), 0.1)
    np.testing.assert_allclose(phi, sl.expm(0.1 * a), rtol=1e-13, atol=1e-15)
    s = np.linspace(0.0, 0.1, 4001)
    integrand = np.stack([sl.expm(a * v) @ f @ f.T @ sl.expm(a * v).T for v in s])
    # trapezoid with 4000 panels: error ~1e-8 of the integral
    np.testing.assert_allclose(
        q, np.trapezoid(integrand, s, axis=0), rtol=1e-7, atol=1e-10
    )
    rm = np.diag([0.01, 0.04, 0.02])
    p = jax.jit(solve_dare)(phi, jnp.asarray(c), q, jnp.asarray(rm))
    ps = sl.solve_discrete_are(np.asarray(phi).T, c.T, np.asarray(q), rm)
    np.testing.assert_allclose(p, ps, rtol=1e-11, atol=1e-14)
    # The innovation form: given R = C P C^T + Rm it returns scipy's P again.
    pf = jax.jit(solve_filter_riccati)(
        phi, jnp.asarray(c), q, jnp.asarray(c @ ps @ c.T + rm)
    )
    np.testing.assert_allclose(pf, ps, rtol=1e-11, atol=1e-14)


def test_riccati_derivative_matches_finite_differences():
    rng = np.random.default_rng(4)
    a = rng.normal(size=(3, 3)) - 2 * np.eye(3)
    c = jnp.asarray(rng.normal(size=(2, 3)))
    r = jnp.diag(jnp.array([0.5, 0.3]))

    @jax.jit
    def fn(s):
        phi, q = discretise(
            jnp.asarray(a) * (1 + s),
            jnp.diag(jnp.array([0.4, 0.2, 0.3])) * (1 + 2 * s),
            0.1,
        )
        return solve_filter_riccati(phi, c * (1 - s), q, r * (1 + s))

    _, tangent = jax.jit(lambda s: jax.jvp(fn, (s,), (1.0,)))(0.0)
    h = 1e-5
    fd = (fn(h) - fn(-h)) / (2 * h)
    # central differences at h = 1e-5: truncation ~h^2 = 1e-10 relative
    np.testing.assert_allclose(
        tangent, fd, rtol=1e-7, atol=1e-9 * float(jnp.abs(fd).max())
    )


@pytest.mark.slow  # ~45 s of compilation on a loaded 2-core machine
def test_innovation_jacobian_matches_finite_differences():
    rec = simulate(0)
    prob = problem(MODEL, [rec], (0, 1))
    z = jnp.asarray([*(0.9 * v for v in TRUE.values()), 0.02, 0.1])
    # an innovation covariance the filter can have at these F (diag(K C) < 1)
    r = jnp.diag(jnp.asarray([2e-4, 1e-3, 0.1]))
    assert np.all(innovations(MODEL, prob, z, r)[2] < 1.0)

    @jax.jit
    def nu(v):
        return innovations(MODEL, prob, v, r)[0][0, :N]

    jac = jax.jit(jax.jacfwd(nu))(z)
    for i in range(len(z)):
        h = 1e-6 * max(abs(float(z[i])), 1e-3)
        fd = (nu(z.at[i].add(h)) - nu(z.at[i].add(-h))) / (2 * h)
        # central differences, relative step 1e-6: measured agreement 1e-10 to 1e-7
        # of the column's largest entry (rounding over 400 filter steps)
        scale = float(jnp.abs(fd).max())
        np.testing.assert_allclose(jac[..., i], fd, rtol=0, atol=5e-7 * scale)


SEEDS = range(10)  # after the first compile, a fit of each kind takes ~0.2 s


@pytest.fixture(scope="module")
def monte_carlo():
    fem, oem = [], []
    for seed in SEEDS:
        rec = simulate(seed)
        # full R: the gusts correlate the alpha and az innovations, and with a
        # diagonal R F[alpha] came out 25% low (the derivatives were unbiased too)
        fem.append(
            fit_filter_error(MODEL, rec, process_noise=("alpha", "q"), full_R=True)
        )
        oem.append(fit(MODEL, rec))
    return fem, oem


def test_filter_error_unbiased_where_output_error_is_not(monte_carlo):
    fem, oem = monte_carlo
    truth = np.array(list(TRUE.values()))
    n = len(fem)
    p_fem = np.array([f.params for f in fem])
    p_oem = np.array([f.params for f in oem])
    sd_fem = np.array([f.stderr for f in fem]).mean(0)
    sd_oem = np.array([f.stderr for f in oem]).mean(0)
    # Filter error's Cramer-Rao bounds describe its scatter (measured: spread / CRB
    # 0.56 to 1.37 over 10 draws) ...
    spread = p_fem.std(0, ddof=1)
    assert np.all(spread < 2.0 * sd_fem) and np.all(spread > 0.4 * sd_fem)
    # ... and its mean is the truth within 3.5 standard errors of the mean
    # (measured at most 2.6, Za)
    bias_fem = p_fem.mean(0) - truth
    assert np.all(np.abs(bias_fem) < 3.5 * sd_fem / np.sqrt(n)), bias_fem / sd_fem
    # Output error's bounds are optimistic under process noise: its scatter is
    # several times its CRB (measured 4.0 to 5.0 in the moment derivatives).
    assert np.max(p_oem.std(0, ddof=1) / sd_oem) > 3.0
    # Mean squared error: filter error better overall and in at least 4 of 5
    # (measured OEM / FEM ratios 7.9, 57, 0.98, 3.0, 5.4: Ma is a tie)
    mse_fem = np.mean((p_fem - truth) ** 2, axis=0)
    mse_oem = np.mean((p_oem - truth) ** 2, axis=0)
    assert np.sum(mse_fem < mse_oem) >= 4
    assert np.sum(mse_fem / truth**2) < 0.5 * np.sum(mse_oem / truth**2)
    # the process-noise intensities are found too (within 3 mean standard errors)
    f_est = np.array([f.F for f in fem])
    f_sd = np.array([f.F_stderr for f in fem]).mean(0)
    assert np.all(np.abs(f_est.mean(0) - np.array(F_TRUE)) < 3 * f_sd / np.sqrt(n))


def test_without_process_noise_both_methods_agree():
    rec = simulate(11, f=(0.0, 0.0))
    # full R as in the Monte Carlo: shares its compiled solver (the diagonal-R
    # variant would compile for another 25 s; measured with it: differences up to
    # 1.0 standard error, det R 0.3% above output error's)
    fem = fit_filter_error(MODEL, rec, process_noise=("alpha", "q"), full_R=True)
    oem = fit(MODEL, rec)
    # The gain nearly collapses (the F estimates fit a little of the measurement
    # noise) and the estimates agree within the statistical accuracy (measured
    # differences 0.2 to 1.3 standard errors) at nearly the same det R (measured
    # 0.3% below output error's).
    assert np.all(np.abs(fem.params - oem.params) < 1.5 * oem.stderr)
    assert np.all(fem.kc < 0.05)
    np.testing.assert_allclose(fem.cost, oem.cost, rtol=0.01)


def test_innovation_check_white_coloured_and_predictable():
    """The process-noise candidate's check of a filter's innovations
    (`innovation_check`: N R^2 of each innovation on its own lags and on signals
    known before it) against closed forms: chi-square with `lags + regressors`
    degrees of freedom on white noise; on an AR(1) of coefficient rho, N rho^2
    more; with a share c of a regressor of unit variance mixed in, about
    N c^2 / (1 + c^2) more."""
    from diffpegasus._diagnose._process_noise import innovation_check

    rng = np.random.default_rng(0)
    n, lags = 1000, 10
    t = np.arange(n)
    z = np.column_stack([np.sin(t / 50.0), np.cos(t / 37.0)]) * np.sqrt(2.0)
    white = np.concatenate(
        [innovation_check(rng.normal(size=(n, 2)), z, lags)[0] for _ in range(150)]
    )
    dof = innovation_check(rng.normal(size=(n, 2)), z, lags)[1]
    assert dof == 12
    # chi-square(12): mean 12, sd of the mean of 300 draws 0.28 (measured 12.0)
    assert abs(white.mean() - 12.0) < 1.0
    # false alarms at 0.01: 3 expected of 300 (measured 1)
    assert np.sum(white > scipy.stats.chi2.isf(0.01, 12)) <= 8
    # coloured: an AR(1), rho 0.3, N rho^2 = 90 above the chi-square's mean
    u = rng.normal(size=(n + 1, 1))
    ar = u[1:] + 0.3 * scipy.signal.lfilter([1.0], [1.0, -0.3], u[:-1], axis=0)
    s_ar = innovation_check(ar, z, lags)[0][0]
    assert 0.7 * 102 < s_ar < 1.3 * 102, s_ar  # measured 81
    # predictable from a regressor: c = 0.3 gives N 0.09 / 1.09 = 83 above
    mixed = rng.normal(size=(n, 1)) + 0.3 * z[:, :1]
    s_mix = innovation_check(mixed, z, lags)[0][0]
    assert 0.7 * 95 < s_mix < 1.3 * 95, s_mix  # measured 105


def test_survivor_threshold_from_white_innovations():
    """The threshold a finding must pass at the filter-error fit comes from the
    fit's own innovations (sieve bootstrap, `survivor_threshold`): on white
    innovations and one candidate it is near the chi-square point (6.6 at 0.01;
    the studentised statistic's tails are a little heavier), and the statistic it
    judges is the score test's (`score_at_filter_error`) to rounding."""
    import types

    from diffpegasus._diagnose._calibration import statistics
    from diffpegasus._diagnose._process_noise import (
        _filter_error_parts,
        ProcessNoiseRule,
        score_at_filter_error,
        survivor_threshold,
    )

    rng = np.random.default_rng(3)
    n, outputs, unknowns = 600, 2, 4  # 2 free parameters, 1 held, 1 intensity
    jac = rng.normal(size=(1, n, outputs, unknowns))
    e = rng.normal(size=(1, n, outputs))
    model = types.SimpleNamespace(parameters=("a", "b", "c"))
    fem = types.SimpleNamespace(
        model=model,
        records=(types.SimpleNamespace(t=np.arange(n)),),
        free=np.array([True, True, False]),
        F=np.array([0.1]),
        params=np.array([1.0, 2.0, 0.0]),
        jacobian=jac,
        whitened=e,
    )
    cal = survivor_threshold(fem, ["c"], ProcessNoiseRule(replicates=500, seed=1))
    # measured 6.8 (500 replicates at level 0.01)
    assert 5.0 < cal.threshold < 10.0, cal.threshold
    rows, res, s, g, basis, _ = _filter_error_parts(fem, ["c"])
    # the basis is orthonormal over the free unknowns' sensitivities
    flat = basis.reshape(-1, basis.shape[-1])
    np.testing.assert_allclose(flat.T @ flat, np.eye(3), atol=1e-12)
    stat = score_at_filter_error(fem, ["c"])[0]["statistic"]
    np.testing.assert_allclose(statistics(rows, res, s, g)[0], stat, rtol=1e-9)


def test_coloured_correction_counts_samples_not_padding_rows():
    """Records are padded to a length bucket (400 samples to 416 rows, zero
    innovations and Jacobian rows there): the coloured-innovation correction is
    the sum over lags of the valid samples' autocovariance (divided by 400, not
    416), equal on the padded and unpadded layouts and to a direct lag sum in
    numpy (Morelli and Klein's formula)."""
    from diffpegasus._estimate._filter_error import _corrected_stderr

    rng = np.random.default_rng(3)
    n, pad, no, k = 400, 16, 3, 4
    jac = rng.normal(size=(1, n, no, k))
    white = rng.normal(size=(1, n, no))
    innov = np.zeros_like(white)  # coloured: a first-order autoregression
    for t in range(1, n):
        innov[:, t] = 0.8 * innov[:, t - 1] + white[:, t]
    a = rng.normal(size=(k, k))
    cov = a @ a.T / k + np.eye(k)
    padded = _corrected_stderr(
        np.concatenate([jac, np.zeros((1, pad, no, k))], axis=1),
        np.concatenate([innov, np.zeros((1, pad, no))], axis=1),
        cov,
        [n],
    )
    unpadded = _corrected_stderr(jac, innov, cov, [n])
    kk = np.einsum("tok,kn->ton", jac[0], cov)
    total = np.zeros((k, k))
    idx = np.arange(n)
    for o in range(no):
        e = innov[0, :, o]
        r = np.array([e[: n - d] @ e[d:] / n for d in range(n)])
        lagged = r[np.abs(idx[:, None] - idx[None, :])]  # r(i - j)
        total += kk[:, o].T @ lagged @ kk[:, o]
    reference = np.sqrt(np.diag(total))
    # measured: 1e-14 relative (FFT against the direct sum); the padded layout
    # was sqrt(400 / 416) = 0.981 of the unpadded one when it divided by the rows
    np.testing.assert_allclose(unpadded, reference, rtol=1e-10)
    np.testing.assert_allclose(padded, unpadded, rtol=1e-10)


def _bump_model():
    """Two states, one output `x1 + x2 / 2`, input gains `b1`, `b2` estimated;
    the dynamics stable except in a 0.1 s bump at t = 2 s, where they are those
    of a strongly unstable pair (eigenvalues 8.8 and 16.7 1/s)."""
    from diffpegasus._model import Model

    a_stable = np.array([[-1.0, 1.0], [-2.0, -1.0]])
    a_bump = np.array([[18.734, -14.443], [1.399, 6.791]])
    c = np.array([1.0, 0.5])

    def a_of(t):
        w = jnp.exp(-(((t - 2.0) / 0.1) ** 2))
        return jnp.asarray(a_stable) + w * jnp.asarray(a_bump - a_stable)

    def rates(t, x, u, p):
        return a_of(t) @ x + jnp.stack([p["b1"], p["b2"]]) * u[0]

    def observe(t, x, u, p):
        return (jnp.asarray(c) @ x) * jnp.ones(1)

    model = Model(("x1", "x2"), ("u",), ("y",), ("b1", "b2"), rates, observe)
    return model, a_of, c


def test_scheduled_fit_moves_a_start_without_a_gain_to_one_with_it():
    """A scheduled gain (5 points) whose start intensities, scaled to the
    residuals, give no steady-state gain at the schedule point inside the
    unstable bump (`gain_variation` infinite there; a tenth of them: finite):
    given those intensities as the start the fit cannot take a step (non-finite
    det R); from the residuals the start is divided by 10 until every point has
    a gain (once here), and the fit converges where the fit given that start
    does. Without the division the fit ends non-finite."""
    from diffpegasus._estimate._filter_error import gain_variation, residual_intensities
    from diffpegasus._estimate._filter_gain import ScheduledGain

    model, a_of, c = _bump_model()
    dt, n = 0.05, 81
    t = dt * np.arange(n)
    u = ((t >= 0.5) & (t < 1.0)).astype(float) - ((t >= 1.0) & (t < 1.5))
    b = np.array([1.0, -2.0])
    rng = np.random.default_rng(0)
    x = np.zeros((n, 2))
    for k in range(n - 1):  # RK4 at the sample step plus discrete process noise

        def f(tt, xx, uu):
            return np.asarray(a_of(tt)) @ xx + b * uu

        tk, xk, um = t[k], x[k], 0.5 * (u[k] + u[k + 1])
        k1 = f(tk, xk, u[k])
        k2 = f(tk + dt / 2, xk + dt / 2 * k1, um)
        k3 = f(tk + dt / 2, xk + dt / 2 * k2, um)
        k4 = f(tk + dt, xk + dt * k3, u[k + 1])
        _, q = discretise(a_of(tk + dt / 2), jnp.diag(jnp.array([0.005, 0.01])), dt)
        x[k + 1] = xk + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        x[k + 1] += np.linalg.cholesky(np.asarray(q)) @ rng.normal(size=2)
    y = (x @ c)[:, None] + 0.1 * rng.normal(size=(n, 1))
    rec = Record(t, u[:, None], y, x0=np.zeros(2), name="bump")
    residuals = [y - (x @ c)[:, None]]  # the measurement noise
    sched = ScheduledGain(points=5)
    f0 = residual_intensities(model, [rec], residuals, b, (0, 1))
    prob = problem(model, [rec], (0, 1), sched)
    assert gain_variation(model, prob, b, f0, residuals) == np.inf
    assert np.isfinite(gain_variation(model, prob, b, f0 / 10, residuals))
    start = np.array([1.2, -1.5])
    common = dict(start=start, gain=sched, throw=False, rtol=1e-10)
    given = fit_filter_error(
        model, rec, process_noise=dict(zip(("x1", "x2"), f0, strict=True)), **common
    )
    assert not np.isfinite(given.cost)
    moved = fit_filter_error(
        model, rec, process_noise=("x1", "x2"), residuals=residuals, **common
    )
    # the fit given the solvable start f0 / 10 (where one division lands);
    # measured: the optimum here is not unique (from f0 / 3, f0 / 5, f0 / 20 the
    # fits converge to det R 0.01355, 0.01348, 0.01497 at other estimates), so
    # the reference is the same start, not another one
    solvable = fit_filter_error(
        model,
        rec,
        process_noise=dict(zip(("x1", "x2"), f0 / 10, strict=True)),
        **common,
    )
    assert moved.converged and solvable.converged
    # it moved: measured b (0.815, -1.856) from the start (1.2, -1.5)
    assert np.max(np.abs(moved.params - start)) > 0.3
    # measured: identical (one program, one start)
    np.testing.assert_allclose(moved.params, solvable.params, rtol=1e-8)
    np.testing.assert_allclose(moved.F, solvable.F, rtol=1e-8)
    np.testing.assert_allclose(moved.cost, solvable.cost, rtol=1e-8)
