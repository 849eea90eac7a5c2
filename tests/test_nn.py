"""Neural model plus least squares."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diffpegasus as dp
from diffpegasus._estimate._nn import MinMax

from .helpers import short_config


@pytest.fixture(scope="module")
def logs():
    config = short_config(t_final=12.0, sample_rate=200.0, sensors=dp.SensorModel())
    return [dp.flight_to_log(dp.simulate(config, jax.random.key(i))) for i in range(2)]


@pytest.fixture(scope="module")
def trained(logs):
    return dp.train_network(logs[:1], jax.random.key(0), max_epochs=15, subsample=2)


def test_normalisation_round_trip():
    data = (
        jax.random.normal(jax.random.key(0), (50, 3))
        * jnp.array([1.0, 100.0, 1e-3])[None, :]
    )
    s = MinMax.fit(data)
    z = jax.vmap(s.forward)(data)
    assert float(z.min()) == pytest.approx(0.0, abs=1e-12) and float(
        z.max()
    ) == pytest.approx(1.0)
    np.testing.assert_allclose(
        np.asarray(jax.vmap(s.inverse)(z)), np.asarray(data), rtol=1e-12, atol=1e-15
    )


def test_training_reduces_error_and_reports_three_curves(trained):
    net, hist = trained
    n = int(hist.epochs)
    assert n >= 2
    tr, va, te = (np.asarray(h)[:n] for h in (hist.train, hist.validation, hist.test))
    assert (
        np.all(np.isfinite(tr)) and np.all(np.isfinite(va)) and np.all(np.isfinite(te))
    )
    assert tr[-1] < 0.2 * tr[0]


def test_save_load_round_trip(tmp_path, trained, logs):
    net, _ = trained
    dp.save_network(tmp_path / "net.eqx", net)
    back = dp.load_network(tmp_path / "net.eqx")
    x = net.features(logs[1].channels)[:100]
    np.testing.assert_array_equal(
        np.asarray(jax.vmap(net)(x)), np.asarray(jax.vmap(back)(x))
    )


def test_lse_path_recovers_known_derivatives(logs):
    """Replace the network by the exact linear coefficient function: exact recovery."""
    truth = jnp.array([0.07, 0.012, 0.01, 0.003, -0.002, -0.02]) * 180 / np.pi
    ia, ide = 5, 6

    def exact(x):
        a, d = x[ia], x[ide]
        return jnp.stack(
            [
                truth[0] * a + truth[1] * d,
                truth[2] * a + truth[3] * d,
                truth[4] * a + truth[5] * d,
            ]
        )

    est = dp.estimate_nn(logs[1], exact)
    v = np.asarray(est.values)[np.asarray(est.valid)]
    np.testing.assert_allclose(
        v, np.broadcast_to(np.asarray(truth), v.shape), rtol=1e-9
    )
    central = dp.estimate_nn(logs[1], exact, derivatives="central")
    np.testing.assert_allclose(
        np.asarray(central.values),
        np.broadcast_to(np.asarray(truth), central.values.shape),
        rtol=1e-9,
    )


def test_cli_nn_with_saved_model(tmp_path, trained, logs):
    from typer.testing import CliRunner

    from diffpegasus._cli import app

    net, _ = trained
    dp.save_network(tmp_path / "net.eqx", net)
    path = dp.write_log(tmp_path / "f.csv", logs[1])
    result = CliRunner().invoke(
        app,
        ["estimate", "nn", str(path), "--model", str(tmp_path / "net.eqx"), "--json"],
    )
    assert result.exit_code == 0, result.output
    d = json.loads(result.stdout.strip().splitlines()[-1])
    assert d["method"] == "nn" and len(d["window_start"]) == 24
    assert set(d["estimates"]) == set(dp.DERIVATIVE_NAMES)


def test_default_network_sees_dynamic_pressure(trained, logs):
    """The targets are forces and moments over qbar S: the default network takes the
    measured qbar (the thesis's seven inputs cannot tell it across trajectories),
    and its saved file says which inputs it takes."""
    net, _ = trained
    assert net.names[-1] == "qbar" and net.features(logs[1].channels).shape[1] == 8
    x = net.features(logs[1].channels)[2000]
    g = jax.grad(lambda v: net(v)[2])(x)
    assert float(jnp.abs(g[-1])) > 0.0
