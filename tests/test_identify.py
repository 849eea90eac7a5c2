"""The output-error engine on several manoeuvres, against independent references:
an optimiser written here in numpy/scipy on the same likelihood, finite differences
for the Jacobian blocks, diffrax's RK4 for the integrator, the book's HFB-320 optimum.
"""

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.integrate
import scipy.optimize

import diffpegasus as dp
from diffpegasus._estimate import _engine, _score
from diffpegasus._estimate._fit import layout
from diffpegasus._estimate._rk4 import RK4

from .test_oem import _BOOK, _numpy_cost, _require, hfb320


U0, ZQ = 45.0, -1.5
TRUE = {"Zw": -1.2, "Zde": -4.0, "Mw": -0.06, "Mq": -2.5, "Mde": -15.0}
START = {"Zw": -1.0, "Zde": -3.0, "Mw": -0.03, "Mq": -2.0, "Mde": -12.0}


def _rates(t, x, u, p):
    del t
    w, q = x
    return jnp.stack(
        [
            p["Zw"] * w + (U0 + ZQ) * q + p["Zde"] * u[0],
            p["Mw"] * w + p["Mq"] * q + p["Mde"] * u[0],
        ]
    )


def _observe(t, x, u, p):
    del t
    w, q = x
    return jnp.stack([p["Zw"] * w + ZQ * q + p["Zde"] * u[0], w, q])


MODEL = dp.Model(
    states=("w", "q"),
    inputs=("de",),
    outputs=("az", "w", "q"),
    parameters=START,
    rates=_rates,
    observe=_observe,
)


def _matrices(p):
    a = np.array([[p[0], U0 + ZQ], [p[2], p[3]]])
    b = np.array([p[1], p[4]])
    c = np.array([[p[0], ZQ], [1.0, 0.0], [0.0, 1.0]])
    d = np.array([p[1], 0.0, 0.0])
    return a, b, c, d


def _manoeuvre(seed, duration, rate, x0, bias, noise=1.0):
    """Noisy outputs of the true model (scipy's adaptive solver, exact linear input
    interpolation): a doublet then a 3-2-1-1, with a bias on az; `noise` scales
    the sensors' noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / rate)
    de = np.where((t > 0.5) & (t < 1.0), 0.03, 0.0)
    de = de - np.where((t >= 1.0) & (t < 1.5), 0.03, 0.0)
    de = de + 0.02 * np.sign(np.sin(2.2 * t)) * (t > 2.5)
    a, b, c, d = _matrices([TRUE[k] for k in TRUE])
    sol = scipy.integrate.solve_ivp(
        lambda tt, x: a @ x + b * np.interp(tt, t, de),
        (t[0], t[-1]),
        x0,
        t_eval=t,
        rtol=1e-11,
        atol=1e-12,
        max_step=0.5 / rate,
    )
    y = sol.y.T @ c.T + de[:, None] * d[None, :]
    y[:, 0] += bias
    y += noise * rng.normal(size=y.shape) * np.array([0.05, 0.02, 0.002])
    return dp.Record(t, de[:, None], y, x0=x0, name=f"manoeuvre {seed}")


@pytest.fixture(scope="module")
def two():
    return (
        _manoeuvre(1, 8.0, 25.0, np.array([0.0, 0.0]), 0.10),
        _manoeuvre(2, 5.0, 25.0, np.array([1.0, 0.02]), -0.05),
    )


def _numpy_outputs(rec, p, bias):
    """RK4 at the sample step, the input averaged over the step for the middle
    stages: the discrete model the engine fits, written again in numpy."""
    a, b, c, d = _matrices(p)
    dt = rec.dt
    u = rec.inputs[:, 0]
    x = rec.x0.copy()
    ys = []
    for k in range(len(rec.t)):
        ys.append(c @ x + d * u[k])
        if k + 1 == len(rec.t):
            break
        um = 0.5 * (u[k] + u[k + 1])
        k1 = a @ x + b * u[k]
        k2 = a @ (x + dt / 2 * k1) + b * um
        k3 = a @ (x + dt / 2 * k2) + b * um
        k4 = a @ (x + dt * k3) + b * u[k + 1]
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    y = np.array(ys)
    y[:, 0] += bias
    return y


def _numpy_fit(records, biases):
    """Minimise log det(R) (R diagonal, the residual mean squares over all records)
    directly with BFGS: a different algorithm on the same likelihood."""

    def cost(v):
        p = v[:5]
        e = np.concatenate(
            [
                rec.measured - _numpy_outputs(rec, p, v[5 + i] if biases else 0.0)
                for i, rec in enumerate(records)
            ]
        )
        return float(np.sum(np.log(np.mean(e**2, axis=0))))

    v0 = np.r_[[START[k] for k in START], np.zeros(len(records) if biases else 0)]
    res = scipy.optimize.minimize(cost, v0, method="BFGS", options={"gtol": 1e-9})
    return res.x, float(np.exp(res.fun))


@pytest.mark.parametrize("biases", [False, True])
def test_two_manoeuvres_reach_the_optimum_of_an_independent_implementation(two, biases):
    fit = dp.fit(MODEL, two, biases=("az",) if biases else ())
    assert fit.converged, fit.message
    ref, ref_cost = _numpy_fit(two, biases)
    # BFGS with finite-difference gradients stops at ~1e-9 relative in log det R
    assert fit.cost == pytest.approx(ref_cost, rel=1e-6)
    np.testing.assert_allclose(fit.params, ref[:5], rtol=2e-4)
    if biases:
        np.testing.assert_allclose(fit.biases[:, 0], ref[5:], atol=2e-4)
        # the planted biases, within 3 standard errors
        z = (fit.biases[:, 0] - np.array([0.10, -0.05])) / fit.bias_stderr[:, 0]
        assert np.all(np.abs(z) < 3)
        # and every derivative within 3 (coloured-residual) standard errors
        truth = np.array([TRUE[k] for k in MODEL.parameters])
        assert np.all(np.abs(fit.params - truth) < 3 * fit.stderr_corrected)
    # the outputs it reports are the model's at its estimate
    for i, rec in enumerate(two):
        b = fit.biases[i, 0] if biases else 0.0
        np.testing.assert_allclose(
            fit.outputs[i], _numpy_outputs(rec, fit.params, b), rtol=1e-9, atol=1e-9
        )


def test_no_iterations_evaluates_the_start(two):
    # max_iter=0: the engine's loop makes only its first pass, the start's
    # evaluation; its R must be the start's residual mean squares in the numpy model
    p0 = np.array([START[k] for k in START])
    fit = dp.fit(MODEL, two, max_iter=0, throw=False)
    e = np.concatenate([r.measured - _numpy_outputs(r, p0, 0.0) for r in two])
    r_ref = np.mean(e**2, axis=0)
    assert fit.iterations == 0
    np.testing.assert_array_equal(fit.params, p0)
    # the same RK4 in JAX and numpy: rounding only (measured 1e-15)
    np.testing.assert_allclose(fit.R, r_ref, rtol=1e-10)
    np.testing.assert_allclose(fit.cost, np.prod(r_ref), rtol=1e-10)


def test_two_records_beat_either_alone(two):
    both = dp.fit(MODEL, two, biases=("az",))
    one = dp.fit(MODEL, two[:1], biases=("az",))
    # the second manoeuvre adds information: every standard error falls
    assert np.all(both.stderr < one.stderr)


def test_multiple_shooting_and_estimated_initial_states_reach_the_same_optimum(two):
    single = dp.fit(MODEL, two, biases=("az",))
    # initial states estimated from a wrong guess (the records' x0 are starts only)
    shifted = tuple(
        dp.Record(r.t, r.inputs, r.measured, x0=r.x0 + [0.3, 0.01], name=r.name)
        for r in two
    )
    multi = dp.fit(
        MODEL,
        shifted,
        biases=("az",),
        shooting=dp.MultipleShooting(interval=2.0),
        initial_state="estimated",
    )
    assert multi.converged, multi.message
    # estimating the initial states can only lower the cost, and by little here
    assert multi.cost <= single.cost * (1 + 1e-6)
    assert multi.cost > 0.9 * single.cost
    np.testing.assert_allclose(multi.params, single.params, rtol=0.05)
    assert multi.defect < 1e-3
    # the initial states it finds are near the true ones, not the wrong guesses
    err = np.abs(multi.initial_states - np.array([r.x0 for r in two]))
    assert np.all(err < [0.15, 0.01]), err


def test_multiple_shooting_settles_on_the_single_shooting_optimum():
    # residuals a thousand times smaller than the other tests' against the same
    # state scale: the continuity penalty's own optimum is then off single
    # shooting's (measured 1.1 corrected standard errors; 0.44 at noise 1e-2,
    # 2e-4 at the usual noise); tightening it until the estimates settle lands on
    # it (measured 1.6e-4)
    rec = _manoeuvre(3, 8.0, 25.0, np.array([0.0, 0.0]), 0.0, noise=1e-3)
    single = dp.fit(MODEL, rec)
    penalty = dp.fit(MODEL, rec, shooting=dp.MultipleShooting(1.0, settle=None))
    settled = dp.fit(MODEL, rec, shooting=dp.MultipleShooting(1.0))
    assert penalty.converged and settled.converged

    def z(f):
        return np.max(np.abs(f.params - single.params) / single.stderr_corrected)

    assert z(penalty) > 0.8
    assert z(settled) < 0.01
    # the tolerance it reached is what the defect is measured against
    assert settled.defect < 1e-3 * penalty.defect
    assert settled.iterations > penalty.iterations


def test_segment_jacobian_matches_finite_differences(two):
    lay = layout(MODEL, two, dp.MultipleShooting(2.0), "fixed", ("az",), np.ones(2))
    s, node = 3, jnp.array([0.4, -0.01])
    theta = jnp.asarray([TRUE[k] for k in MODEL.parameters])
    bias = jnp.array([0.1])
    v = jnp.concatenate([node, theta, bias])

    def f(v):
        ys, end = _engine.segment_outputs(MODEL, lay, s, v[:2], v[2:7], v[7:])
        return jnp.concatenate([ys.reshape(-1), end])

    exact = jax.jacfwd(f)(v)
    h = 1e-6 * jnp.maximum(jnp.abs(v), 1.0)
    fd = jnp.stack(
        [(f(v.at[i].add(h[i])) - f(v.at[i].add(-h[i]))) / (2 * h[i]) for i in range(8)],
        axis=1,
    )
    # central differences in float64: truncation ~h^2, rounding ~eps/h
    np.testing.assert_allclose(exact, fd, rtol=1e-6, atol=1e-7)


def test_score_test_reuses_the_fits_linearisation_at_its_estimates(two):
    # the fit ends with the model linearised at its estimates; the score test from
    # that linearisation (a program without the model) must be the one that
    # linearises the model again at the estimates and R: the same numbers up to
    # rounding (measured ~1e-13). At the start of the fit's last step instead the
    # Jacobian differs by that step, far above this tolerance.
    held = MODEL.replace(fixed=("Mq",))
    fit = dp.fit(held, two, biases=("az",))
    assert fit.linearisation is not None
    nx, p = len(MODEL.states), len(MODEL.parameters)
    args = (fit.layout, jnp.asarray(fit.z))
    free, cand = jnp.asarray(fit.free), jnp.array([3])
    again = _score.score(held.structure(), *args, fit.R, free, cand, nx=nx, p=p)
    reused = _score.score_linearised(*args, fit.linearisation, free, cand, nx=nx, p=p)
    for name in ("statistic", "estimate", "stderr", "cost_ratio", "slope"):
        np.testing.assert_allclose(
            getattr(reused, name), getattr(again, name), rtol=1e-9, err_msg=name
        )
    np.testing.assert_allclose(reused.rows, again.rows, rtol=1e-9, atol=1e-12)


def test_scan_rk4_equals_diffrax_rk4(two):
    lay = layout(MODEL, two, dp.SingleShooting(), "fixed", (), np.ones(2))
    theta = jnp.asarray(MODEL.start)
    x0 = jnp.array([0.5, 0.01])
    xs, ts = _engine.segment_solve(MODEL, lay, 0, x0, theta)

    def field(t, x, args):
        del args
        return MODEL.f(t, x, _engine._input_at(lay, 0, t, None), theta)

    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(field),
        RK4(),
        t0=ts[0],
        t1=ts[-1],
        dt0=float(ts[1] - ts[0]),
        y0=x0,
        saveat=diffrax.SaveAt(ts=ts),
        max_steps=len(ts) + 2,
    )
    # the same tableau and steps: equal to rounding
    np.testing.assert_allclose(xs, sol.ys, rtol=1e-12, atol=1e-13)


def test_failed_fit_says_why():
    t = np.arange(0.0, 4.0, 0.05)
    rec = dp.Record(t, np.zeros((len(t), 1)), np.zeros((len(t), 3)), x0=[1.0, 0.0])
    # a violently unstable start diverges to inf within the record
    bad = MODEL.replace(start={"Mw": 50.0, "Mq": 50.0})
    fit = dp.fit(bad, rec, throw=False)
    assert not fit.converged
    assert "non-finite" in fit.message
    with pytest.raises(RuntimeError, match="non-finite"):
        dp.fit(bad, rec)


def test_hfb320_model_reaches_the_book_optimum():
    _require(hfb320.DEFAULT_DATA)
    data = dp.read_asc(hfb320.DEFAULT_DATA)
    from diffpegasus._vehicle._hfb320 import hfb320_model, X0

    rec = dp.Record(
        data["T"],
        np.column_stack([data["DELV"], data["THRUST"]]),
        np.column_stack([data[c] for c in _BOOK.OUTPUTS]),
        x0=X0,
    )
    fit = dp.fit(hfb320_model(), rec)
    # the book's (FVSysID's) optimum, det R = 3.016139e-24; ours agrees to 1e-6
    assert fit.cost == pytest.approx(3.016139e-24, rel=2e-6)
    assert fit.cost == pytest.approx(_numpy_cost(data, fit.params), rel=1e-9)
    assert np.all(fit.stderr > 0)


def _cli(args):
    from typer.testing import CliRunner

    from diffpegasus._cli import app

    return CliRunner().invoke(app, [str(a) for a in args])


def test_cli_fits_the_hfb320_vehicle():
    _require(hfb320.DEFAULT_DATA)
    import json

    res = _cli(["fit", hfb320.DEFAULT_DATA, "--vehicle", "hfb320", "--json"])
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout.strip().splitlines()[-1])
    assert report["converged"]
    assert report["cost"] == pytest.approx(3.016139e-24, rel=2e-6)
    assert len(report["estimates"]) == 11
    assert all(report["stderr"][k] > 0 for k in report["estimates"])
    # per-channel metrics: a good fit (R^2 0.84-0.94) with coloured residuals (the
    # real record's turbulence and model error), which Ljung-Box must flag
    ch = report["channels"]
    assert all(0.8 < ch[o]["r2"] < 1 for o in ch)
    assert all(ch[o]["ljung_box_p"] < 1e-6 for o in ch)


MODEL_FILE = """
import jax.numpy as jnp
import diffpegasus as dp

U0, ZQ = 45.0, -1.5

def rates(t, x, u, p):
    w, q = x
    return jnp.stack([p["Zw"] * w + (U0 + ZQ) * q + p["Zde"] * u[0],
                      p["Mw"] * w + p["Mq"] * q + p["Mde"] * u[0]])

def observe(t, x, u, p):
    w, q = x
    return jnp.stack([p["Zw"] * w + ZQ * q + p["Zde"] * u[0], w, q])

model = dp.Model(states=("w", "q"), inputs=("de",), outputs=("az", "w", "q"),
                 parameters={"Zw": -1.0, "Zde": -3.0, "Mw": -0.03, "Mq": -2.0,
                             "Mde": -12.0},
                 rates=rates, observe=observe)
biases = ("az",)
"""


def test_model_file_and_column_map_fit_two_files_like_the_library(two, tmp_path):
    import json

    (tmp_path / "model.py").write_text(MODEL_FILE)
    # the files name their columns their own way and log angles in degrees
    (tmp_path / "map.json").write_text(
        json.dumps(
            {
                "t": "TIME",
                "de": {"column": "ELEV", "unit": "deg"},
                "az": "NZ",
                "w": "W",
                "q": {"column": "QB", "unit": "deg/s"},
            }
        )
    )
    files = []
    for i, rec in enumerate(two):
        rows = np.column_stack(
            [
                rec.t,
                np.degrees(rec.inputs[:, 0]),
                rec.measured[:, 0],
                rec.measured[:, 1],
                np.degrees(rec.measured[:, 2]),
            ]
        )
        path = tmp_path / f"m{i}.csv"
        np.savetxt(
            path,
            rows,
            delimiter=",",
            header="TIME,ELEV,NZ,W,QB",
            comments="",
            fmt="%.17g",
        )
        files.append(path)
    res = _cli(
        [
            "fit",
            *files,
            "--model",
            tmp_path / "model.py",
            "--columns",
            tmp_path / "map.json",
            "--json",
        ]
    )
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout.strip().splitlines()[-1])
    # the initial states come from the first samples of w and q (noisy), so the
    # library fit uses the same
    recs = [
        dp.Record(r.t, r.inputs, r.measured, x0=r.measured[0, 1:], name=r.name)
        for r in two
    ]
    lib = dp.fit(MODEL, recs, biases=("az",))
    assert report["cost"] == pytest.approx(lib.cost, rel=1e-8)
    for name, value in zip(MODEL.parameters, lib.params, strict=True):
        assert report["estimates"][name] == pytest.approx(value, rel=1e-6)
    assert set(report["biases"]) == {"m0.csv", "m1.csv"}


def test_headerless_numbered_columns_and_a_read_function_fit_like_the_library(
    two, tmp_path
):
    """FVSysID's own data files are bare numeric tables (no header, no time column,
    degrees, one channel a difference of two columns): both the numbered column map
    (`column: 7`, `t: {step: ...}`) and a model file's `read(path)` reach the
    library's optimum on the same numbers."""
    import json

    files = []
    for i, rec in enumerate(two):
        # columns: 1 junk, 2 az, 3 w, 4 q (deg/s), 5 de_left (deg), 6 de_right (deg)
        de = np.degrees(rec.inputs[:, 0])
        rows = np.column_stack(
            [
                np.full(len(rec.t), 7.0),
                rec.measured[:, 0],
                rec.measured[:, 1],
                np.degrees(rec.measured[:, 2]),
                de + 1.0,
                de - 1.0,
            ]
        )
        path = tmp_path / f"bare{i}.asc"
        np.savetxt(path, rows, fmt="%.17g")
        files.append(path)
    dt = float(two[0].t[1] - two[0].t[0])
    recs = [
        dp.Record(r.t - r.t[0], r.inputs, r.measured, x0=r.measured[0, 1:], name=r.name)
        for r in two
    ]
    lib = dp.fit(MODEL, recs, biases=("az",))

    # the elevator as the mean of two surfaces is beyond a column map: read()
    reader = f"""
import numpy as np
def read(path):
    c = np.loadtxt(path)
    return {{"t": {dt!r} * np.arange(len(c)), "az": c[:, 1], "w": c[:, 2],
            "q": np.radians(c[:, 3]), "de": np.radians(0.5 * (c[:, 4] + c[:, 5]))}}
"""
    (tmp_path / "model.py").write_text(MODEL_FILE + reader)
    res = _cli(["fit", *files, "--model", tmp_path / "model.py", "--json"])
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout.strip().splitlines()[-1])
    assert report["cost"] == pytest.approx(lib.cost, rel=1e-8)

    # numbered columns (from 1, as the book counts) and time from the step, on
    # copies whose column 5 holds the elevator itself
    bare = []
    for i, f in enumerate(files):
        c = np.loadtxt(f)
        c[:, 4] -= 1.0
        path = tmp_path / f"bare_de{i}.txt"
        np.savetxt(path, c, fmt="%.17g")
        bare.append(path)
    cmap = {
        "t": {"step": dt},
        "az": {"column": 2},
        "w": {"column": 3},
        "q": {"column": 4, "unit": "deg/s"},
        "de": {"column": 5, "unit": "deg"},
    }
    (tmp_path / "map.json").write_text(json.dumps(cmap))
    (tmp_path / "plain.py").write_text(MODEL_FILE)
    res = _cli(
        [
            "fit",
            *bare,
            "--model",
            tmp_path / "plain.py",
            "--columns",
            tmp_path / "map.json",
            "--json",
        ]
    )
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout.strip().splitlines()[-1])
    assert report["cost"] == pytest.approx(lib.cost, rel=1e-8)
    for name, value in zip(MODEL.parameters, lib.params, strict=True):
        assert report["estimates"][name] == pytest.approx(value, rel=1e-6)

    # a column beyond the file's width is named with what the file has
    cmap["w"] = {"column": 9}
    (tmp_path / "map.json").write_text(json.dumps(cmap))
    res = _cli(
        [
            "fit",
            bare[0],
            "--model",
            tmp_path / "plain.py",
            "--columns",
            tmp_path / "map.json",
        ]
    )
    assert res.exit_code == 2
    assert "no column '9' for channel 'w' (columns: numbered 1 to 6" in res.output


def test_user_mistakes_in_model_files_and_maps_are_one_line(two, tmp_path):
    """What a user gets wrong in a model file or a column map is one line naming
    the file and what to change, never a traceback or a silently wrong fit."""
    import json

    rec = two[0]
    rows = np.column_stack(
        [
            rec.t,
            np.degrees(rec.inputs[:, 0]),
            rec.measured[:, 0],
            rec.measured[:, 1],
            rec.measured[:, 2],
        ]
    )
    data = tmp_path / "run.csv"
    np.savetxt(
        data, rows, delimiter=",", header="T,DE,AZ,W,Q", comments="", fmt="%.17g"
    )
    good = {
        "t": "T",
        "de": {"column": "DE", "unit": "deg"},
        "az": "AZ",
        "w": "W",
        "q": "Q",
    }

    def run(model_text, cmap, *files):
        (tmp_path / "m.py").write_text(model_text)
        (tmp_path / "map.json").write_text(json.dumps(cmap))
        res = _cli(
            [
                "fit",
                *(files or (data,)),
                "--model",
                tmp_path / "m.py",
                "--columns",
                tmp_path / "map.json",
                "--json",
            ]
        )
        return res

    def one_line(res, *expected):
        assert res.exit_code == 2, res.output
        assert "Traceback" not in res.output
        errors = [line for line in res.output.splitlines() if line.startswith("error:")]
        assert len(errors) == 1, res.output
        for text in expected:
            assert text in errors[0], errors[0]

    # a parameter name mistyped inside rates: named, with the valid names
    typo = MODEL_FILE.replace('p["Mq"] * q', 'p["Mqq"] * q', 1)
    one_line(
        run(typo, good),
        "m.py line",
        "p['Mqq'] is not a model parameter",
        "Zw, Zde, Mw, Mq, Mde",
    )
    # rates of the wrong length
    short = MODEL_FILE.replace(
        '    return jnp.stack([p["Zw"] * w + (U0 + ZQ) * q + p["Zde"] * u[0],\n', "", 1
    ).replace(
        '                      p["Mw"] * w', '    return jnp.stack([p["Mw"] * w', 1
    )
    one_line(run(short, good), "rates(t, x, u, p) returns 1 value(s); the model has 2")
    # NumPy on a traced value
    numpy = "import numpy as np\n" + MODEL_FILE.replace(
        'p["Mq"] * q', 'p["Mq"] * np.tanh(q)', 1
    )
    one_line(run(numpy, good), "m.py line", "write it with jax.numpy")
    # the elevator logged in degrees, mapped without its unit (a 57x wrong Mde
    # otherwise)
    one_line(
        run(MODEL_FILE, {**good, "de": "DE"}),
        "column 'DE' (channel 'de')",
        'looks like degrees (give it "unit": "deg" in the column map)',
    )
    # a typo in the map's channel names
    one_line(run(MODEL_FILE, {**good, "qq": "Q"}), "'qq', not a channel of the model")
    # x0 per data file, and two files of one name in two folders stay two records
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a, b = tmp_path / "a" / "run.csv", tmp_path / "b" / "run.csv"
    a.write_bytes(data.read_bytes())
    # (b one sample shorter: the same numbers twice are refused as one record twice)
    b.write_text("\n".join(data.read_text().splitlines()[:-1]) + "\n")
    res = run(MODEL_FILE + f"x0 = {{str({str(a)!r}): (0.1, 0.0)}}\n", good, a, b)
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout.strip().splitlines()[-1])
    assert report["records"] == [str(a), str(b)]
    assert set(report["biases"]) == {str(a), str(b)}
    # plain column names and numbers both map
    assert run(MODEL_FILE, {**good, "w": 4}).exit_code == 2  # a CSV has no numbers
    # a Record whose arrays disagree in length says which
    with pytest.raises(ValueError, match="inputs has shape .* one row per time sample"):
        dp.Record(rec.t, rec.inputs[:-1], rec.measured)


def test_cli_holds_a_parameter_and_names_bad_input(tmp_path):
    _require(hfb320.DEFAULT_DATA)
    import json

    res = _cli(
        ["fit", hfb320.DEFAULT_DATA, "--vehicle", "hfb320", "--fix", "CMq=0", "--json"]
    )
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout.strip().splitlines()[-1])
    assert report["estimates"]["CMq"] == 0.0 and report["stderr"]["CMq"] is None
    assert "CMq" in report["fixed"]
    # without pitch damping the real record is fitted clearly worse
    assert report["cost"] > 1.5 * 3.016139e-24
    res = _cli(["fit", hfb320.DEFAULT_DATA, "--vehicle", "hfb320", "--fix", "Cmq=0"])
    assert res.exit_code == 2 and "'Cmq' is not a parameter" in res.output
    bad = tmp_path / "bad.py"
    bad.write_text("import diffpegasus as dp\nmodel = dp.Model(states=('a',))\n")
    res = _cli(["fit", hfb320.DEFAULT_DATA, "--model", bad])
    assert res.exit_code == 2 and "bad.py: line 2: TypeError" in res.output
    res = _cli(["fit", hfb320.DEFAULT_DATA, "--vehicle", "nonesuch"])
    assert res.exit_code == 2 and "unknown vehicle 'nonesuch'" in res.output


def test_hfb320_diagnosis_finds_the_missing_pitch_damping_with_library_effects():
    """The real record with the vehicle's own CMq held at zero: the library's pitch
    damping (or alpha-dot damping, which this record cannot tell from it) ranks
    first, and adding it back recovers most of the fit."""
    _require(hfb320.DEFAULT_DATA)
    import json

    res = _cli(
        [
            "diagnose",
            hfb320.DEFAULT_DATA,
            "--vehicle",
            "hfb320",
            "--fix",
            "CMq=0",
            "--json",
        ]
    )
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout.strip().splitlines()[-1])
    top = report["ranking"][0]
    assert top["effect"] in ("pitch_damping", "alpha_dot_damping")
    assert top["significant"] and top["cost_reduction"] > 0.5
    assert {"pitch_damping", "alpha_dot_damping"} <= set(report["significant"])
    res = _cli(
        [
            "fit",
            hfb320.DEFAULT_DATA,
            "--vehicle",
            "hfb320",
            "--fix",
            "CMq=0",
            "--add",
            "pitch_damping",
            "--json",
        ]
    )
    assert res.exit_code == 0, res.output
    refit = json.loads(res.stdout.strip().splitlines()[-1])
    # the held fit is 16x worse than the book's; the library term brings it back to
    # within 2% (its q c / 2V form differs from the book's q c / V0 by V / V0)
    assert report["fit"]["cost"] > 10 * 3.016139e-24
    assert refit["cost"] < 1.02 * 3.016139e-24
    assert refit["estimates"]["pitch_damping.Cmq"] < 0


def test_hfb320_simulates_and_identifies_a_planted_sensor_bias(tmp_path):
    """simulate --vehicle hfb320 (RK4 at a tenth of the log step, so the fit's
    discrete model is not the generator's) with a bias on az: diagnose names it,
    the refit recovers it and every derivative within 3 standard errors."""
    import json

    from diffpegasus._vehicle._hfb320 import IDENTIFIED

    log = tmp_path / "h.csv"
    res = _cli(
        [
            "simulate",
            "--vehicle",
            "hfb320",
            "--out",
            log,
            "--hidden",
            "sensor_bias:az=0.3",
            "--seed",
            "3",
        ]
    )
    assert res.exit_code == 0, res.output
    meta = json.loads(log.with_suffix(".json").read_text())
    assert meta["vehicle"] == "hfb320" and meta["S_ref"] == pytest.approx(30.097, 1e-4)
    # the output-error diagnosis: process noise (two filter-error fits) on a calm
    # flight of this simulator is the subject of
    # test_fem_cli.py::test_process_noise_is_not_flagged_on_clean_flights
    res = _cli(
        ["diagnose", log, "--vehicle", "hfb320", "--process-noise", "none", "--json"]
    )
    report = json.loads(res.stdout.strip().splitlines()[-1])
    assert report["ranking"][0]["effect"] == "sensor_bias:az"
    assert report["significant"] == ["sensor_bias:az"]
    res = _cli(["fit", log, "--vehicle", "hfb320", "--add", "sensor_bias:az", "--json"])
    fit = json.loads(res.stdout.strip().splitlines()[-1])
    est, sd = fit["estimates"], fit["stderr"]
    assert abs(est["sensor_bias:az.bias"] - 0.3) < 3 * sd["sensor_bias:az.bias"]
    for name, truth in IDENTIFIED.items():
        assert abs(est[name] - truth) < 3 * sd[name], name


def test_a_users_vehicle_file_from_parts_composes_library_effects():
    """examples/my_jet.py builds the HFB-320 from the library's parts as a user
    would: --add composes a library effect with it, with the built-in's result."""
    _require(hfb320.DEFAULT_DATA)
    import json
    import pathlib

    jet = pathlib.Path(__file__).resolve().parents[1] / "examples" / "my_jet.py"
    res = _cli(
        [
            "fit",
            hfb320.DEFAULT_DATA,
            "--vehicle",
            jet,
            "--fix",
            "CMq=0",
            "--add",
            "pitch_damping",
            "--json",
        ]
    )
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout.strip().splitlines()[-1])
    # the built-in vehicle's number for the same fit (README): the same parts
    assert report["cost"] == pytest.approx(3.059681e-24, rel=1e-6)
    assert report["estimates"]["pitch_damping.Cmq"] < 0
    assert "alpha_dot_damping.Cmad" not in report["estimates"]  # held candidates
