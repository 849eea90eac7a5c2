"""Equation-error least squares (`dp.equation_error`): the linear lateral model's
regressions against numpy's `lstsq` with the textbook standard errors, the coupled
6-DOF rolling and yawing equations on noise-free data, and the checks."""

import jax.numpy as jnp
import numpy as np
import pytest

import diffpegasus as dp

from .test_lateral import _data, _records


def test_lateral_regressions_match_numpy_lstsq():
    model = dp.lateral_model(manoeuvres=2)
    ee = dp.equation_error(model, _records(model, _data()))
    assert ee.equations == ("pdot", "rdot", "ay")
    est = dict(zip(model.parameters, ee.params, strict=True))
    sd = dict(zip(model.parameters, ee.stderr, strict=True))
    # independent: each equation on [p, r, da, dr, beta, 1] (measured p, r) by
    # numpy's SVD least squares; s^2 = RSS / (N - 6), covariance s^2 (A^T A)^-1
    u = np.concatenate([d[1] for d in _data()])
    y = np.concatenate([d[2] for d in _data()])
    a = np.column_stack([y[:, 3], y[:, 4], u[:, 0], u[:, 1], u[:, 2], np.ones(len(u))])
    for j, (row, bias) in enumerate(
        (("L", "by_pdot"), ("N", "by_rdot"), ("Y", "by_ay"))
    ):
        names = [row + s for s in ("p", "r", "da", "dr", "beta")] + [bias]
        theta, rss, rank, _ = np.linalg.lstsq(a, y[:, j], rcond=None)
        assert rank == 6
        s2 = rss[0] / (len(u) - 6)
        se = np.sqrt(s2 * np.diag(np.linalg.inv(a.T @ a)))
        # measured: estimates to 1e-13, standard errors to 3e-15 (both are
        # rounding of well-conditioned 6-column problems)
        np.testing.assert_allclose([est[n] for n in names], theta, rtol=1e-10)
        np.testing.assert_allclose([sd[n] for n in names], se, rtol=1e-10)
        assert ee.sigma[j] == pytest.approx(np.sqrt(s2), rel=1e-10)
        # the fit's covariance of the named estimates (standard errors times
        # their correlation) against numpy's s^2 (A^T A)^-1, every entry:
        # measured 4e-13 relative at most (rounding, as the standard errors)
        np.testing.assert_allclose(
            ee.covariance_of(names, corrected=False),
            s2 * np.linalg.inv(a.T @ a),
            rtol=1e-10,
        )
    # by default the estimated parameters in the model's order, with the
    # coloured-residual standard errors
    cov = ee.covariance_of()
    estimated = np.flatnonzero(ee.free)
    np.testing.assert_allclose(np.diag(cov), ee.stderr_corrected[estimated] ** 2)
    with pytest.raises(ValueError, match="no parameter 'Lq'"):
        ee.covariance_of(["Lp", "Lq"])
    # the state biases and the p, r output biases enter no regression equation
    for name in ("bx_p_1", "bx_r_2", "by_p", "by_r"):
        i = model.parameters.index(name)
        assert not ee.estimable[i] and np.isnan(ee.stderr[i])
        assert ee.params[i] == model.start[i]
    assert set(ee.start()) == {
        n for n, e in zip(model.parameters, ee.estimable, strict=True) if e
    }


def test_held_parameters_stay_and_leave_the_regression():
    model = dp.lateral_model(start={"Lbeta": -4.0}, fixed=("Lbeta",))
    t, u, y = _data()[0]
    ee = dp.equation_error(model, dp.lateral_record(model, t, u, y))
    i = model.parameters.index("Lbeta")
    assert ee.params[i] == -4.0 and not ee.estimable[i]
    # numpy: pdot + 4 beta on [p, r, da, dr, 1]
    a = np.column_stack([y[:, 3], y[:, 4], u[:, 0], u[:, 1], np.ones(len(u))])
    theta = np.linalg.lstsq(a, y[:, 0] + 4.0 * u[:, 2], rcond=None)[0]
    est = ee.estimates()
    names = ("Lp", "Lr", "Lda", "Ldr", "by_pdot")
    np.testing.assert_allclose([est[n] for n in names], theta, rtol=1e-10)


def test_coupled_sixdof_equations_on_noise_free_data():
    """The 6-DOF model's pdot and rdot both carry every Cl and Cn derivative
    (product of inertia): estimated jointly, from noise-free data they are the
    truth to rounding."""
    aircraft = dp.business_jet()
    start = dp.trim(aircraft, 104.67)
    flights = [
        dp.simulate_sixdof(
            aircraft,
            start,
            aileron=dp.three_two_one_one(0.05, 0.5, start=1.0),
            rudder=dp.doublet(0.05, 1.2, start=8.0),
            t_final=15.0,
            dt=0.04,
        )
    ]
    model = dp.sixdof_lateral_model(
        mass=aircraft.mass,
        inertia=aircraft.inertia,
        s_ref=aircraft.s_ref,
        b_ref=aircraft.b_ref,
        rho=aircraft.rho,
    )
    records, states = [], []
    for f in flights:
        records.append(
            dp.Record(
                f["t"],
                np.column_stack([f[n] for n in dp.SIXDOF_LATERAL_INPUTS]),
                np.column_stack([f[n] for n in dp.SIXDOF_LATERAL_OUTPUTS]),
            )
        )
        states.append(np.column_stack([f[n] for n in dp.SIXDOF_LATERAL_STATES]))
    with pytest.raises(ValueError, match=r"states \['v'\] are not measured"):
        dp.equation_error(model, records)
    ee = dp.equation_error(model, records, states=states)
    assert ee.equations == ("ay", "pdot", "rdot")
    est = ee.estimates()
    # the simulation's channels and the model's outputs are the same equations:
    # measured worst 3e-9 relative (CY_p and CY_da are zero in the truth)
    for name in dp.LATERAL_DERIVATIVE_NAMES:
        truth = float(getattr(aircraft.lateral, name))
        assert est[name] == pytest.approx(truth, rel=1e-7, abs=1e-9), name


def test_a_model_not_linear_in_its_parameters_is_refused():
    model = dp.Model(
        states=("x",),
        inputs=("u",),
        outputs=("x", "y"),
        parameters={"a": 1.0},
        rates=lambda t, x, u, p: -x,
        observe=lambda t, x, u, p: jnp.stack([x[0], p["a"] ** 2 * u[0]]),
    )
    t = np.linspace(0.0, 1.0, 11)
    rec = dp.Record(t, np.sin(t), np.column_stack([np.exp(-t), np.sin(t)]))
    with pytest.raises(ValueError, match="not linear in the parameters"):
        dp.equation_error(model, rec)
    with pytest.raises(ValueError, match="not outputs of the model"):
        dp.equation_error(model, rec, equations=("z",))
