"""The discrepancy workflow of the launch vehicle on the one path: its registry
entry's model (a `dp.Model` of Mach-spline aerodynamics, the log's thrust and mass,
the library effects as held candidates), the one engine and the one diagnosis, on
simulated flights with hidden effects.

All flights here are 30 s (drop, ignition, pull-up to Mach ~2) logged at 50 Hz, and
every fit uses the entry's defaults, so the compiled fit and score test are shared.
"""

import functools
import json
import pathlib
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

import diffpegasus as dp
from diffpegasus._cli import app
from diffpegasus._diagnose._metrics import channel_metrics, ljung_box
from diffpegasus._registry._pegasus import OUTPUTS
from diffpegasus._vehicle._mach_spline import bspline_basis
from diffpegasus.discrepancy import diagnose, fit_log, vehicle_entry


sys.path.insert(0, str(pathlib.Path(__file__).parents[1] / "experiments"))


ENTRY = vehicle_entry("pegasus")


def fit(log, add=(), start=None):
    return fit_log(ENTRY, log, add, start=start)


@functools.cache
def flight(hidden: tuple[str, ...] = (), seed: int = 5) -> dp.FlightLog:
    effects = tuple(dp.parse_assignment(h) for h in hidden)
    config = dp.pegasus.PegasusConfig(t_final=30.0, sample_rate=50.0, effects=effects)
    return dp.pegasus.flight_to_log(dp.pegasus.simulate(config, jax.random.key(seed)))


@functools.cache
def baseline(hidden: tuple[str, ...] = (), seed: int = 5):
    base = fit(flight(hidden, seed))
    return base, diagnose(base)


def test_bspline_basis_matches_scipy():
    from scipy.interpolate import BSpline

    breaks = np.array([0.8, 1.1, 1.7, 2.5, 4.0])
    x = np.linspace(0.8, 4.0, 57)
    ours = bspline_basis(x, breaks)
    knots = np.concatenate([[breaks[0]] * 3, breaks, [breaks[-1]] * 3])
    ref = BSpline.design_matrix(x, knots, 3, extrapolate=False).toarray()
    np.testing.assert_allclose(ours, ref, atol=1e-12)
    np.testing.assert_allclose(ours.sum(axis=1), 1.0, atol=1e-12)
    # the part's breakpoints are traced parameters: the JAX evaluation is the same
    traced = jax.jit(bspline_basis)(jnp.asarray(x), jnp.asarray(breaks))
    np.testing.assert_allclose(np.asarray(traced), ref, atol=1e-12)


def test_mach_breakpoints_blend_record_share_and_mach_range():
    from diffpegasus._vehicle._mach_spline import mach_breakpoints

    # a drop: 5 s dwell near Mach 0.8, then a climb at a steady 0.09 /s to Mach 3
    t = np.arange(0.0, 30.0, 0.02)
    mach = np.where(t < 5.0, 0.797 + 0.0026 * t, 0.81 + 0.088 * (t - 5.0))
    quantile = mach_breakpoints(mach, 7)
    blend = mach_breakpoints(mach, 7, "blend")
    for b in (quantile, blend):
        assert b[0] == pytest.approx(mach.min()) and b[-1] == pytest.approx(mach.max())
    # quantiles spend an interval on the dwell and none inside Mach 0.81-1.2
    assert quantile[1] < 0.82 and quantile[2] > 1.2
    # the blend: every interval gets at least half a step of Mach range
    assert np.all(np.diff(blend) >= 0.5 * (mach.max() - mach.min()) / 6 - 1e-12)
    assert np.any((blend > 0.85) & (blend < 1.2))
    with pytest.raises(ValueError, match="placement"):
        mach_breakpoints(mach, 7, "uniform")


def test_model_jacobian_matches_finite_differences():
    """The engine's Jacobians are forward mode through the model's rates and
    outputs: checked against central differences in float64 at a flight sample,
    with effects away from zero so their hooks (wind, delay, damping) and the
    spline's breakpoints (traced parameters) are exercised."""
    spec, (record,) = ENTRY.problem([flight()], candidates=True)
    model = spec.model
    theta = np.array(model.start)
    names = list(model.parameters)
    for name, value in (
        ("vertical_wind.w_up", 3.0),
        ("pitch_damping.Cmq", -5.0),
        ("moment_offset.CM0", 0.01),
    ):
        theta[names.index(name)] = value
    i = 700  # powered flight, transonic
    x = record.measured_states(model, [i])[0]
    u = record.inputs[i]
    t = float(record.t[i])

    def both(z):
        return jnp.concatenate(
            [model.f(t, z[:5], u, z[5:]), model.g(t, z[:5], u, z[5:])]
        )

    z = jnp.concatenate([jnp.asarray(x), jnp.asarray(theta)])
    jac = np.asarray(jax.jit(jax.jacfwd(both))(z))
    f = jax.jit(both)
    for k in [0, 1, 4] + [
        5 + names.index(n)
        for n in (
            "CL.a1[2]",
            "CM.de[3]",
            "mach_break[1]",
            "vertical_wind.w_up",
            "pitch_damping.Cmq",
            "thrust_misalignment.offset",
        )
    ]:
        h = 1e-6 * max(1.0, abs(float(z[k])))
        fd = (np.asarray(f(z.at[k].add(h))) - np.asarray(f(z.at[k].add(-h)))) / (2 * h)
        scale = np.abs(fd) + 1e-6 * np.max(np.abs(fd)) + 1e-12
        # central differences are good to about 1e-7 relative here
        assert np.max(np.abs(fd - jac[:, k]) / scale) < 1e-4, k


# Validation tests (`-m validation`): a clean launch-vehicle flight flagging nothing
# is checked by default on the independent generator's calm flight
# (tests/test_fem_pegasus.py) and, on this simulator, by the last diagnosis of
# test_two_effects_diagnose_add_diagnose_again (nothing significant once the planted
# effects are in the model). Seed 6 is the hard one, a known failure; the
# false-alarm rate over many clean flights is measured by
# experiments/decision_rule.py (independent generator)
@pytest.mark.parametrize(
    "seed",
    [
        pytest.param(3, marks=pytest.mark.validation),
        pytest.param(6, marks=pytest.mark.validation),
    ],
)
def test_clean_flights_flag_nothing(seed):
    base, result = baseline((), seed)
    assert base.converged
    assert result["significant"] == [], result["ranking"][:3]
    assert "no candidate effect is significant" in result["message"]
    # every statistic below the threshold the log's own residuals give
    physical = [r for r in result["ranking"] if not r["resolution_limit"]]
    assert max(r["statistic"] for r in physical) < result["rule"]["threshold"]


# Effects the default channels reveal, at realistic sizes (SI units). Where the
# data cannot tell two effects apart, the planted one must be in the top group and
# reported as hard to tell from the first.
# One case of each kind of effect (dynamics, aerodynamic offset, thrust, timing,
# air data, sensor bias on a measured and on a derived channel); the other
# sensor biases and offsets share these code paths and are scored in the
# decision-rule experiments, which keeps this file inside the suite's time budget.
# The timing case (actuator_delay=0.02) and the az bias (sensor_bias:az=0.2) are
# diagnosed, added and recovered on this same flight by
# test_two_effects_diagnose_add_diagnose_again, and the az bias alone through the
# command line by test_cli_diagnose_and_fit_json_on_a_log_without_sidecar.
# One planted effect, the vertical wind (air data), is the default test that a
# single planted effect is named first and recovered; the others are validation
# tests (`-m validation`), repeats of that path with another effect. Their terms
# (pitch damping, moment offset, thrust misalignment) are differentiated against
# finite differences by test_model_jacobian_matches_finite_differences.
PLANTED = [
    pytest.param("pitch_damping", -10.0, marks=pytest.mark.validation),
    pytest.param("drag_offset", 0.05, marks=pytest.mark.validation),
    pytest.param("moment_offset", 0.01, marks=pytest.mark.validation),
    pytest.param("thrust_misalignment", 0.03, marks=pytest.mark.validation),
    # far above the rule's threshold: on a 15 s flight of this kind (half the
    # data) its statistic was 723 against the threshold 10.8, the refit 4.97 +/- 0.05
    ("vertical_wind", 5.0),
    pytest.param("sensor_bias:q", 0.002, marks=pytest.mark.validation),
]
# the baseline's own structural error (its cubic in alpha against the database's
# tables) leaves a zero-alpha drag of about +0.008 on clean flights, which this
# estimate carries (README, "What the tool can and cannot tell")
BIASED_BY_BASELINE = {"drag_offset"}


@pytest.mark.parametrize("name,value", PLANTED)
def test_planted_effect_is_diagnosed_and_recovered(name, value):
    hidden = (f"{name}={value}",)
    base, result = baseline(hidden)
    ranking = result["ranking"]
    top = ranking[0]
    if top["effect"] != name:
        close = [c["effect"] for c in top["hard_to_tell_from"]]
        assert name in close, ranking[:3]
    # the first finding is the planted effect, or one the diagnosis says the data
    # cannot tell from it (on these 30 s flights a moment offset and a thrust
    # misalignment are both constant moments once the motor burns: the rule
    # declares whichever scores higher)
    assert top["significant"], ranking[:3]
    after = fit(flight(hidden), (name,), start=base)
    assert after.cost < 0.75 * base.cost
    est = after.effect_estimates()[name]
    error = abs(est["estimate"] - value)
    if name in BIASED_BY_BASELINE:
        assert error < 0.25 * abs(value)
    else:
        assert error < 3 * est["stderr"], est


def test_two_effects_diagnose_add_diagnose_again():
    hidden = ("sensor_bias:az=0.2", "actuator_delay=0.02")
    planted = {"sensor_bias:az", "actuator_delay"}
    log = flight(hidden)
    base, first = baseline(hidden)
    top = first["ranking"][0]["effect"]
    assert top in planted and top in first["significant"]
    one = fit(log, (top,), start=base)
    second = diagnose(one)
    other = (planted - {top}).pop()
    assert second["ranking"][0]["effect"] == other
    assert other in second["significant"]
    both = fit(log, tuple(planted), start=one)
    assert both.cost < 0.1 * base.cost
    # both planted values recovered together, each within 3 standard errors
    estimates = both.effect_estimates()
    for name, value in (("sensor_bias:az", 0.2), ("actuator_delay", 0.02)):
        est = estimates[name]
        assert abs(est["estimate"] - value) < 3 * est["stderr"], (name, est)
    assert diagnose(both)["significant"] == []


def test_metrics_against_closed_form():
    rng = np.random.default_rng(0)
    white = rng.normal(size=4000)
    assert ljung_box(white)[1] > 0.01
    ar = np.zeros(4000)
    for i in range(1, 4000):
        ar[i] = 0.8 * ar[i - 1] + white[i]
    assert ljung_box(ar)[1] < 1e-6
    y = np.sin(np.linspace(0, 20, 4000))
    m = channel_metrics(y + 0.01 * white, y, white)
    assert m["tic"] < 0.02 and m["r2"] > 0.999
    assert m["bias_ci95"][0] < 0 < m["bias_ci95"][1]
    assert abs(m["noise"] - 0.01) < 0.001  # second differences see the white part
    assert abs(m["misfit_ratio"] - 1.0) < 0.1
    perfect = channel_metrics(y, y)
    assert perfect["rms"] == 0 and perfect["tic"] == 0


def test_cli_diagnose_and_fit_json_on_a_log_without_sidecar(tmp_path):
    runner = CliRunner()
    path = dp.write_log(tmp_path / "f.csv", flight(("sensor_bias:az=0.2",)))
    path.with_suffix(".json").unlink()  # any source: no sidecar, Pegasus defaults
    res = runner.invoke(
        app,
        # process noise (two filter-error fits) is the subject of test_fem_pegasus
        ["diagnose", str(path), "--json", "--out", str(tmp_path / "d")]
        + ["--process-noise", "none"],
    )
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert out["ranking"][0]["effect"] == "sensor_bias:az"
    assert out["significant"][0] == "sensor_bias:az"
    for key in (
        "effect",
        "cost_reduction",
        "statistic",
        "p_value",
        "estimate",
        "stderr",
        "resolution_limit",
    ):
        assert key in out["ranking"][0]
    # the verdict says which number decided (significance) and which is the share
    assert "statistic" in out["rule"]["text"] and "share" in out["rule"]["text"]
    assert out["ranking"][0]["statistic"] > out["rule"]["threshold"]
    assert 0 < out["rule"]["false_alarm_level"] < 1
    assert (tmp_path / "d" / "diagnose.md").exists() and (
        tmp_path / "d" / "diagnose.png"
    ).exists()
    res = runner.invoke(
        app,
        [
            "fit",
            str(path),
            "--add",
            "sensor_bias:az",
            "--json",
            "--out",
            str(tmp_path / "f"),
        ],
    )
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert out["added"] == ["sensor_bias:az"]
    assert out["after"]["cost"] < 0.5 * out["before"]["cost"]
    assert (
        out["after"]["channels"]["az"]["rms"] < out["before"]["channels"]["az"]["rms"]
    )
    assert {"rms", "tic"} <= set(out["before"]["channels"]["az"])
    assert (
        abs(out["effects"]["sensor_bias:az"]["estimate"] - 0.2)
        < 3 * out["effects"]["sensor_bias:az"]["stderr"]
    )
    assert (tmp_path / "f" / "fit.png").exists()
    res = runner.invoke(
        app, ["compare", str(path), "--json", "--out", str(tmp_path / "c")]
    )
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert set(out["channels"]) == set(OUTPUTS)
    for key in (
        "rms",
        "nrms",
        "bias_ci95",
        "tic",
        "r2",
        "ljung_box_p",
        "xcorr_input_max",
    ):
        assert key in out["channels"]["az"]
    # the bias leaves structure somewhere: some channel's residual is not white
    assert min(m["ljung_box_p"] for m in out["channels"].values()) < 1e-3
    assert out["localise"]["worst"] and len(out["derivatives"]) == 5
    for name in ("compare.md", "compare.png", "regimes.png"):
        assert (tmp_path / "c" / name).exists()


def test_cli_rejects_unknown_effect(tmp_path):
    path = dp.write_log(tmp_path / "f.csv", flight())
    res = CliRunner().invoke(app, ["fit", str(path), "--add", "warp_drive"])
    assert res.exit_code == 2
    assert "unknown effect 'warp_drive'" in res.output


def test_demo_runs_the_workflow_end_to_end(tmp_path):
    # at this file's log shape (30 s at 50 Hz; the demo's default rate is 100 Hz),
    # so the demo's fits and diagnosis run the programs the tests above compiled
    res = CliRunner().invoke(
        app,
        ["demo", "--out", str(tmp_path), "--duration", "30", "--sample-rate", "50"],
    )
    assert res.exit_code == 0, res.output
    # the planted delay is what the diagnosis ranks first and what the demo adds
    assert "| 1 | actuator_delay |" in (tmp_path / "diagnose.md").read_text()
    assert "fit --add actuator_delay" in res.output and "lower" in res.output
    for name in (
        "flight.csv",
        "compare.md",
        "compare.png",
        "regimes.png",
        "diagnose.md",
        "diagnose.png",
        "fit.md",
        "fit.png",
    ):
        assert (tmp_path / name).exists(), name


def test_adding_an_effect_the_baseline_contains_is_refused(tmp_path):
    path = dp.write_log(tmp_path / "f.csv", flight())
    res = CliRunner().invoke(app, ["fit", str(path), "--add", "lift_alpha_squared"])
    assert res.exit_code == 2
    assert "already in the baseline" in res.output
