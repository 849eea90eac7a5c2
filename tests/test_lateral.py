"""The linear lateral-directional model (Jategaonkar's ATTAS test cases 1 and 34):
recovery of planted derivatives, a two-manoeuvre fit against an independent numpy /
scipy implementation of the same likelihood, and the equivalence of the book's
lumped biases with per-record initial states and output biases."""

import functools

import numpy as np
import pytest
import scipy.optimize

import diffpegasus as dp


DT = 0.04  # s, the ATTAS records' sample step
V, G = 100.0, 9.80665  # m/s, m/s^2: only for the beta row of the data generator
TRUE = {
    "Lp": -2.0, "Lr": 0.6, "Lda": -5.0, "Ldr": 0.7, "Lbeta": -4.0,
    "Np": -0.1, "Nr": -0.25, "Nda": -0.2, "Ndr": -1.2, "Nbeta": 2.5,
    "Yp": 0.1, "Yr": 0.5, "Yda": 0.05, "Ydr": 2.0, "Ybeta": -10.0,
    "bx_p_1": 0.004, "bx_r_1": -0.002, "bx_p_2": -0.003, "bx_r_2": 0.0015,
    "by_pdot": 0.003, "by_rdot": -0.002, "by_ay": 0.05, "by_p": 0.002,
    "by_r": -0.001,
}  # fmt: skip
NOISE = np.array([0.01, 0.004, 0.03, 0.002, 0.001])  # pdot, rdot, ay, p, r


def _steps(t, start, levels, unit):
    """Held levels (rad) of `unit` s each from `start`, as sampled by a recorder."""
    edges = start + unit * np.concatenate([[0.0], np.cumsum([n for n, _ in levels])])
    out = np.zeros_like(t)
    for (_, level), a, b in zip(levels, edges[:-1], edges[1:], strict=True):
        out[(t >= a) & (t < b)] = level
    return out


def _manoeuvre(k):
    """Aileron and rudder of manoeuvre `k` (1 or 2), sampled at DT."""
    d2 = np.deg2rad(2.0)
    if k == 1:
        t = DT * np.arange(500)
        da = _steps(t, 1.0, [(3, d2), (2, -d2), (1, d2), (1, -d2)], 0.5)
        dr = _steps(t, 8.0, [(1, d2), (1, -d2)], 1.2)
    else:
        t = DT * np.arange(600)
        dr = _steps(t, 1.0, [(3, d2), (2, -d2), (1, d2), (1, -d2)], 0.6)
        da = _steps(t, 11.0, [(1, d2), (1, -d2)], 1.0)
    return t, da, dr


def _truth(k):
    """Noise-free `(t, inputs (N, 3), outputs (N, 5), phi (N,))` of manoeuvre `k`: a four-state
    linear lateral motion (beta, p, r, phi) integrated by RK4 at DT / 10 with the
    controls linear between samples; the p and r rows are the identified model's,
    beta follows from the side force. Recorded beta is the input of the model."""
    t, da, dr = _manoeuvre(k)
    p = TRUE
    bx = np.array([p[f"bx_p_{k}"], p[f"bx_r_{k}"]])

    def rates(x, u):
        beta, roll, yaw, phi = x
        ay = (
            p["Yp"] * roll + p["Yr"] * yaw + p["Yda"] * u[0] + p["Ydr"] * u[1]
            + p["Ybeta"] * beta
        )  # fmt: skip
        pdot = (
            p["Lp"] * roll + p["Lr"] * yaw + p["Lda"] * u[0] + p["Ldr"] * u[1]
            + p["Lbeta"] * beta + bx[0]
        )  # fmt: skip
        rdot = (
            p["Np"] * roll + p["Nr"] * yaw + p["Nda"] * u[0] + p["Ndr"] * u[1]
            + p["Nbeta"] * beta + bx[1]
        )  # fmt: skip
        betadot = (ay + G * phi) / V - yaw
        return np.array([betadot, pdot, rdot, roll]), np.array([pdot, rdot, ay])

    sub = 10
    h = DT / sub
    x = np.zeros(4)
    xs = [x]
    for i in range(len(t) - 1):
        for j in range(sub):
            a, b = j / sub, (j + 1) / sub
            c0 = np.array([da[i], dr[i]])
            c1 = np.array([da[i + 1], dr[i + 1]])
            u0, um, u1 = (c0 + s * (c1 - c0) for s in (a, (a + b) / 2, b))
            k1 = rates(x, u0)[0]
            k2 = rates(x + h / 2 * k1, um)[0]
            k3 = rates(x + h / 2 * k2, um)[0]
            k4 = rates(x + h * k3, u1)[0]
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        xs.append(x)
    xs = np.array(xs)
    acc = np.array(
        [rates(xi, np.array([a, r]))[1] for xi, a, r in zip(xs, da, dr, strict=True)]
    )
    # the measured accelerations carry output biases, not the state biases
    acc[:, 0] -= bx[0]
    acc[:, 1] -= bx[1]
    outputs = np.column_stack([acc, xs[:, 1], xs[:, 2]])
    outputs += np.array([p["by_" + n] for n in dp.LATERAL_OUTPUTS])
    return t, np.column_stack([da, dr, xs[:, 0]]), outputs, xs[:, 3]


@functools.cache
def _data(noise=True):
    rng = np.random.default_rng(17)
    out = []
    for k in (1, 2):
        t, u, y, _ = _truth(k)
        if noise:
            y = y + rng.normal(size=y.shape) * NOISE
        out.append((t, u, y))
    return out


def _records(model, data):
    return [
        dp.lateral_record(model, t, u, y, manoeuvre=k + 1, name=f"m{k + 1}")
        for k, (t, u, y) in enumerate(data)
    ]


@functools.cache
def _two_manoeuvre_fit():
    model = dp.lateral_model(manoeuvres=2)
    return dp.fit(model, _records(model, _data()), rtol=1e-10)


# --- an independent implementation: numpy RK4 of the model, scipy least squares ---


def _np_outputs(theta, names, data):
    """Model outputs of every record for a batch of parameter vectors `theta` `(B,
    P)`: RK4 at the sample step with the inputs averaged over it in the middle
    stages (the flight-test convention), `x0 = 0`."""
    theta = np.atleast_2d(theta)
    p = {n: theta[:, i] for i, n in enumerate(names)}
    a = np.stack(
        [np.stack([p["Lp"], p["Lr"]], -1), np.stack([p["Np"], p["Nr"]], -1)], 1
    )
    b = np.stack(
        [
            np.stack([p["Lda"], p["Ldr"], p["Lbeta"]], -1),
            np.stack([p["Nda"], p["Ndr"], p["Nbeta"]], -1),
        ],
        1,
    )
    cy = np.stack([p["Yp"], p["Yr"]], -1)
    dy = np.stack([p["Yda"], p["Ydr"], p["Ybeta"]], -1)
    by = np.stack([p["by_" + n] for n in dp.LATERAL_OUTPUTS], -1)
    outs = []
    for k, (t, u, _) in enumerate(data):
        bx = np.stack([p[f"bx_p_{k + 1}"], p[f"bx_r_{k + 1}"]], -1)

        def f(x, uu, bx=bx):
            return np.einsum("bij,bj->bi", a, x) + np.einsum("bij,j->bi", b, uu) + bx

        x = np.zeros((theta.shape[0], 2))
        xs = [x]
        for i in range(len(t) - 1):
            um = 0.5 * (u[i] + u[i + 1])
            k1 = f(x, u[i])
            k2 = f(x + DT / 2 * k1, um)
            k3 = f(x + DT / 2 * k2, um)
            k4 = f(x + DT * k3, u[i + 1])
            x = x + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            xs.append(x)
        xs = np.stack(xs, 1)  # (B, N, 2)
        acc = np.einsum("bij,bnj->bni", a, xs) + np.einsum("bij,nj->bni", b, u)
        ay = np.einsum("bj,bnj->bn", cy, xs) + np.einsum("bj,nj->bn", dy, u)
        y = np.concatenate([acc, ay[..., None], xs], -1) + by[:, None, :]
        outs.append(y)
    return outs


def _independent_fit(names, start, data):
    """Maximum likelihood by relaxation: weighted least squares with R fixed
    (scipy's trust-region reflective solver, forward-difference Jacobian in one
    batched simulation), then R from the residuals, until det(R) settles."""
    measured = np.concatenate([y for _, _, y in data])
    theta = np.array(start, float)

    def resid_batch(th):
        return np.concatenate(_np_outputs(th, names, data), axis=1)

    r = np.var(measured - resid_batch(theta)[0], axis=0)
    cost = np.inf
    for _ in range(50):
        w = 1.0 / np.sqrt(r)

        def fun(th, w=w):
            return ((measured - resid_batch(th)[0]) * w).ravel()

        def jac(th, w=w):
            h = 1e-7 * np.maximum(np.abs(th), 1e-2)
            batch = np.vstack([th, th + np.diag(h)])
            ys = resid_batch(batch) * w
            return -((ys[1:] - ys[0]) / h[:, None, None]).reshape(len(th), -1).T

        theta = scipy.optimize.least_squares(
            fun, theta, jac=jac, xtol=1e-14, ftol=1e-15, gtol=1e-15
        ).x
        e = measured - resid_batch(theta)[0]
        r = np.mean(e**2, axis=0)
        new = float(np.prod(r))
        if abs(cost - new) <= 1e-13 * new:
            break
        cost = new
    return theta, float(np.prod(r))


def test_two_manoeuvres_reach_the_independent_optimum():
    fit = _two_manoeuvre_fit()
    assert fit.converged
    model = fit.model
    theta, cost = _independent_fit(model.parameters, model.start, _data())
    # measured: det R agrees to 2e-15 and the parameters to 2e-7 relative (1e-6 of
    # their standard errors); the bounds leave room for both stopping rules
    assert fit.cost == pytest.approx(cost, rel=1e-6)
    gap = np.abs(np.asarray(fit.params) - theta)
    # biases near zero: relative to the larger of the value and its standard error
    assert np.all(gap <= 1e-4 * np.maximum(np.abs(theta), fit.stderr)), gap
    # the same likelihood: our outputs are the independent simulation's at our optimum
    ours = _np_outputs(np.asarray(fit.params), model.parameters, _data())
    for y, ys in zip(fit.outputs, ours, strict=True):
        np.testing.assert_allclose(y, ys[0], atol=1e-10)


def test_planted_derivatives_recovered_within_standard_errors():
    fit = _two_manoeuvre_fit()
    est = fit.estimates()
    sd = dict(zip(fit.model.parameters, fit.stderr, strict=True))
    z = {n: (est[n] - TRUE[n]) / sd[n] for n in TRUE}
    # white noise and an exact model: the Cramér-Rao bounds hold; 3.5 sigma over 24
    # parameters fails by chance with probability about 1%
    assert max(abs(v) for v in z.values()) < 3.5, z
    # the rolling and yawing derivatives are well determined (measured: below 5%);
    # the side-force rate and aileron terms are not, with this noise on ay
    for name in dp.LATERAL_DERIVATIVES[:10]:
        assert sd[name] < 0.05 * abs(TRUE[name]), (name, sd[name])


def test_noise_free_data_give_the_planted_derivatives():
    model = dp.lateral_model(manoeuvres=2)
    fit = dp.fit(model, _records(model, _data(noise=False)), rtol=1e-12)
    est = fit.estimates()
    # the data come from RK4 at DT / 10 with a continuous sideslip, the model sees
    # the sampled one linearly interpolated (1e-5 rad/s residual in p): measured
    # worst errors 2.2e-3 relative (Lr, correlated with the sideslip rate), 1e-4
    # or less for the rest, 2e-6 absolute for the biases
    for name in TRUE:
        assert est[name] == pytest.approx(TRUE[name], rel=3e-3, abs=5e-6), name


@pytest.mark.slow
def test_sideslip_as_a_state_gives_the_planted_derivatives():
    """The variant with sideslip and bank angle as states (the data generator's
    own equations at alpha = theta = 0): noise-free records give the planted
    derivatives to the integration error, now without the sampled-sideslip error."""
    model = dp.lateral_model(manoeuvres=2, sideslip="state", flight=(V, 0.0, 0.0))
    records = []
    for k in (1, 2):
        t, u, y, phi = _truth(k)
        measured = np.column_stack([y, u[:, 2], phi])
        records.append(dp.lateral_record(model, t, u[:, :2], measured, manoeuvre=k))
    fit = dp.fit(model, records, rtol=1e-12)
    est = fit.estimates()
    # RK4 at DT against RK4 at DT / 10: measured worst 5e-6 relative (Yda, the
    # least excited), 1.3e-6 for the rest, 2e-9 absolute for the biases
    for name in TRUE:
        assert est[name] == pytest.approx(TRUE[name], rel=2e-5, abs=1e-8), name
    assert est["by_beta"] == pytest.approx(0.0, abs=1e-8)
    assert est["by_phi"] == pytest.approx(0.0, abs=1e-8)


@pytest.mark.slow
def test_lumped_biases_equal_initial_states_and_output_biases():
    """For one manoeuvre the book's 22-parameter model (state and output biases,
    x0 = 0) is an exact reparametrisation of the 15-derivative model with an
    estimated initial state and a bias on every output: same optimum."""
    t, u, y = _data()[0]
    book = dp.lateral_model()
    assert len(book.parameters) == 22
    a = dp.fit(book, dp.lateral_record(book, t, u, y), rtol=1e-10)
    plain = dp.lateral_model(state_biases=False, output_biases=False)
    b = dp.fit(
        plain,
        dp.lateral_record(plain, t, u, y),
        initial_state="estimated",
        biases=dp.LATERAL_OUTPUTS,
        rtol=1e-10,
    )
    assert a.cost == pytest.approx(b.cost, rel=1e-6)
    np.testing.assert_allclose(a.params[:15], b.params, rtol=1e-5)
    # the state biases map to the initial state: x0 = A^-1 bx
    ea = a.estimates()
    mat = np.array([[ea["Lp"], ea["Lr"]], [ea["Np"], ea["Nr"]]])
    x0 = np.linalg.solve(mat, [ea["bx_p"], ea["bx_r"]])
    np.testing.assert_allclose(b.initial_states[0], x0, rtol=1e-4, atol=1e-7)


def test_record_helper_checks_manoeuvre_numbers():
    model = dp.lateral_model(manoeuvres=2)
    t, u, y = _data()[0]
    with pytest.raises(ValueError, match="manoeuvre must be 1..2"):
        dp.lateral_record(model, t, u, y, manoeuvre=3)
    rec = dp.lateral_record(model, t, u, y, manoeuvre=2)
    assert rec.inputs.shape == (len(t), 5)
    np.testing.assert_array_equal(rec.inputs[:, 3:], [[0.0, 1.0]] * len(t))
    np.testing.assert_array_equal(rec.x0, [0.0, 0.0])
