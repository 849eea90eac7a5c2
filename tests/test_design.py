"""Input design: Fisher information, limits, and the optimiser on the short-period
model."""

import jax.numpy as jnp
import numpy as np
import pytest

import diffpegasus as dp
import diffpegasus._design._optimal as design_mod


U0 = 50.0
TRUE = jnp.array([-1.2, -1.5, -5.0, -0.1, -2.5, -12.0])
NOISE = jnp.array([0.2, 0.05, 0.005]) ** 2


def _rates(t, x, u, p):
    zw, zq, zde, mw, mq, mde = p
    return jnp.stack(
        [zw * x[0] + (U0 + zq) * x[1] + zde * u[0], mw * x[0] + mq * x[1] + mde * u[0]]
    )


def _outputs(t, x, u, p):
    return jnp.stack([p[0] * x[0] + p[1] * x[1] + p[2] * u[0], x[0], x[1]])


@pytest.fixture(scope="module")
def design():
    problem = dp.OEMProblem(
        rates=_rates,
        outputs=_outputs,
        t0=0.0,
        dt=0.05,
        inputs=jnp.zeros((120, 1)),
        measured=jnp.zeros((120, 3)),
        free=(True, False, True, True, True, True),
    )
    return design_mod.DesignProblem(
        problem=problem,
        theta=TRUE,
        x0=jnp.zeros(2),
        noise=NOISE,
        column=0,
        excursion_output=1,
    )


START = dp.Multisine(
    amplitudes=jnp.full(4, 1.0),
    frequencies=jnp.array([0.2, 0.4, 0.8, 1.6]),
    phases=jnp.zeros(4),
    start=0.0,
)
LIMITS = design_mod.Limits(
    max_deflection=float(np.deg2rad(2.0)),
    max_rate=float(np.deg2rad(15.0)),
    max_excursion=1.0,
)


def test_fisher_information_matches_finite_difference_sensitivities(design):
    m = np.asarray(design_mod.fisher_information(design, START))
    h = 1e-6
    cols = []
    for i in range(6):
        up = design_mod.simulate_outputs(design, START, TRUE.at[i].add(h))
        down = design_mod.simulate_outputs(design, START, TRUE.at[i].add(-h))
        cols.append(np.asarray(up - down) / (2 * h))
    s = np.stack(cols, axis=-1)  # (t, outputs, params)
    s[..., 1] = 0.0  # Zq is fixed
    ref = np.einsum("toa,o,tob->ab", s, 1 / np.asarray(NOISE), s) + np.diag(
        [0, 1, 0, 0, 0, 0]
    )
    np.testing.assert_allclose(m, ref, rtol=1e-6, atol=1e-6 * np.abs(ref).max())


def test_optimiser_improves_the_criterion_within_limits(design):
    spec = dp.Multisine(
        amplitudes=True, frequencies=False, phases=True, start=False, stop=False
    )
    best, hist = design_mod.optimise_input(
        design, START, LIMITS, kind="D", filter_spec=spec, steps=60, learning_rate=0.1
    )
    assert hist["end"] < hist["start"] - 0.5, hist
    p = design_mod.peaks(design, best)
    assert float(p["deflection"]) <= LIMITS.max_deflection * (1 + 1e-9)
    assert float(p["rate"]) <= LIMITS.max_rate * (1 + 1e-9)
    assert float(p["excursion"]) <= LIMITS.max_excursion * (1 + 1e-9)
    # the D criterion is the log-determinant of the relative CRB covariance
    sd = np.asarray(design_mod.predicted_stderr(design, best))[[0, 2, 3, 4, 5]]
    sd0 = np.asarray(
        design_mod.predicted_stderr(
            design, design_mod.within_limits(design, START, LIMITS)
        )
    )[[0, 2, 3, 4, 5]]
    assert np.sum(np.log(sd)) < np.sum(np.log(sd0))


def test_design_input_command_on_the_pegasus_model(tmp_path):
    """The command end to end on a short segment with a few optimiser steps: the
    report's shape, every input within the limits, the optimised criterion no worse
    than its start."""
    import json

    from typer.testing import CliRunner

    from diffpegasus._cli import app

    result = CliRunner().invoke(
        app,
        ["design-input", "--length", "1.0", "--steps", "3", "--out", str(tmp_path)],
    )
    assert result.exit_code == 0, result.output
    d = json.loads((tmp_path / "design.json").read_text())
    assert set(d["inputs"]) == {"pulse", "sine", "3211", "multisine", "optimised"}
    for row in d["inputs"].values():
        assert row["peak_deflection_deg"] <= 2.0 * (1 + 1e-9)
        assert row["peak_rate_deg_s"] <= 40.0 * (1 + 1e-9)
        assert row["peak_alpha_excursion_deg"] <= 2.0 * (1 + 1e-9)
        assert all(v > 0 for v in row["stderr_per_deg"].values())
    assert d["criterion_end"] <= d["criterion_start"] + 1e-9
    assert (tmp_path / "design_stderr.png").exists()
