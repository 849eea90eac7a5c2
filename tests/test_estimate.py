"""The one entry `dp.estimate(model, records, method)`: each method's numbers are
those of its own function; the optimistix solver reaches the engine's optimum (and
optimistix's own entry runs it); a fit that stops short says why (crafted cases:
an input that never moves, a non-finite start, a budget too small, shooting
defects left open); the command line reads `--method` from the registry."""

import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest

import diffpegasus as dp
from diffpegasus._estimate._methods import ESTIMATORS

from .test_identify import _cli, _manoeuvre, MODEL, two  # noqa: F401


def test_output_error_through_the_entry_is_fit(two):  # noqa: F811
    method = dp.OutputError(biases=("az",), estimate_initial_state=True)
    new = dp.estimate(MODEL, two, method)
    old = dp.fit(MODEL, two, biases=("az",), initial_state="estimated")
    assert isinstance(new, dp.AbstractFit) and new.converged
    # the same program on the same data: equal to rounding
    np.testing.assert_allclose(new.params, old.params, rtol=1e-12)
    np.testing.assert_allclose(new.stderr_corrected, old.stderr_corrected, rtol=1e-10)
    assert new.cost == pytest.approx(old.cost, rel=1e-12)
    assert new.estimates() == old.estimates()
    assert set(new.standard_errors()) == set(MODEL.parameters)


def test_equation_error_through_the_entry_matches_numpy_lstsq(two):  # noqa: F811
    fit = dp.estimate(MODEL, two, dp.EquationError(equations=("az",)))
    # az - ZQ q = Zw w + Zde de: ordinary least squares written here
    zq = -1.5
    a = np.concatenate(
        [np.column_stack([r.measured[:, 1], r.inputs[:, 0]]) for r in two]
    )
    b = np.concatenate([r.measured[:, 0] - zq * r.measured[:, 2] for r in two])
    ref = np.linalg.lstsq(a, b, rcond=None)[0]
    est = fit.estimates()
    assert [est["Zw"], est["Zde"]] == pytest.approx(ref, rel=1e-10)
    assert fit.converged and fit.message == ""
    ok = ~np.isnan(fit.stderr)
    assert np.all(fit.stderr_corrected[ok] >= fit.stderr[ok])


def test_filter_error_through_the_entry_is_fit_filter_error(two):  # noqa: F811
    new = dp.estimate(MODEL, two, dp.FilterError(process_noise=("w", "q")))
    old = dp.fit_filter_error(MODEL, two, process_noise=("w", "q"))
    assert new.converged, new.message
    np.testing.assert_allclose(new.params, old.params, rtol=1e-12)
    np.testing.assert_allclose(new.F, old.F, rtol=1e-12)
    # noise-free states (the data's only process is the sensors' noise): the
    # intensities start small and stay small against the states' size
    assert np.all(new.F < 0.05 * np.array([1.0, 0.02]))


def test_optimistix_solver_reaches_the_engines_optimum(two):  # noqa: F811
    shooting = dp.MultipleShooting(interval=1.0)
    engine = dp.estimate(MODEL, two, dp.OutputError(shooting=shooting))
    solver = dp.BlockLevenbergMarquardt()
    viaoptx = dp.estimate(MODEL, two, dp.OutputError(shooting=shooting, solver=solver))
    assert viaoptx.converged, viaoptx.message
    # the same steps through optimistix's loop: the same iterates to rounding
    assert viaoptx.iterations == engine.iterations
    np.testing.assert_allclose(viaoptx.params, engine.params, rtol=1e-9)
    assert viaoptx.cost == pytest.approx(engine.cost, rel=1e-9)
    # optimistix's own entry at the optimum's R, from the start: the weighted least
    # squares whose minimum the relaxation's fixed point is
    from diffpegasus._estimate._fit import output_error

    start = output_error(MODEL, two, shooting=shooting, max_iter=0, throw=False)
    nx, p = len(MODEL.states), len(MODEL.parameters)
    lay = engine.layout
    prob = dp.OutputErrorProblem(
        model=MODEL.structure(),
        layout=lay,
        r=jnp.asarray(engine.R),
        free=lay.free_columns(jnp.asarray(MODEL.free), nx, p),
        nx=nx,
        p=p,
    )
    sol = optx.least_squares(
        dp.output_error_residuals,
        solver,
        jnp.asarray(start.z),
        args=prob,
        max_steps=100,
    )
    np.testing.assert_allclose(
        np.asarray(sol.value)[len(start.nodes.reshape(-1)) :][:p],
        engine.params,
        rtol=1e-6,
    )


def test_a_constant_input_names_the_parameters_it_does_not_excite():
    rec = _manoeuvre(3, 6.0, 25.0, np.array([1.0, 0.02]), 0.0)
    still = dp.Record(rec.t, np.zeros_like(rec.inputs), rec.measured, x0=rec.x0)
    fit = dp.estimate(MODEL, still, throw=False)
    assert not fit.converged
    assert fit.result == dp.RESULTS.no_excitation
    assert "Zde" in fit.message and "Mde" in fit.message
    assert "Mq" not in fit.message
    with pytest.raises(RuntimeError, match="do not excite"):
        dp.estimate(MODEL, still)


def test_a_non_finite_start_and_a_short_budget_say_why(two):  # noqa: F811
    nan = MODEL.replace(start={"Mq": float("nan")})
    fit = dp.estimate(nan, two, throw=False)
    assert fit.result == dp.RESULTS.nonfinite and "non-finite" in fit.message
    short = dp.estimate(MODEL, two, max_iter=1, throw=False)
    assert short.result == dp.RESULTS.slow_progress
    assert short.iterations == 1 and "max_iter" in short.message
    # multiple shooting from node guesses off the data: one step leaves the
    # defects far above their tolerance
    shooting = dp.MultipleShooting(interval=0.5, continuity_tol=1e-8)
    ms = dp.estimate(
        MODEL, two, dp.OutputError(shooting=shooting), max_iter=1, throw=False
    )
    assert ms.result == dp.RESULTS.defects, ms.message
    assert "shooting interval" in ms.message


def test_the_registry_and_its_contract():
    assert ESTIMATORS["oem"] is dp.OutputError
    assert ESTIMATORS["fem"] is dp.FilterError
    assert ESTIMATORS["eqe"] is dp.EquationError
    for cls in ESTIMATORS.values():
        assert issubclass(cls, dp.AbstractEstimator)
        cls()  # every registered estimator has default settings (the CLI's)
    with pytest.raises(TypeError, match="estimator"):
        dp.estimate(MODEL, _manoeuvre(1, 2.0, 25.0, np.zeros(2), 0.0), "oem")


def test_cli_method_is_read_from_the_registry(tmp_path):
    res = _cli(["fit", "x.csv", "--vehicle", "hfb320", "--method", "nope"])
    assert res.exit_code != 0
    assert "oem, fem, eqe" in res.output
