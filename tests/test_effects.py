"""Every planted effect changes the outputs it should, by the right amount, and no
others. All effects sit in one configuration with vmapped parameter values, so the
whole table compiles once."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diffpegasus as dp

from .helpers import short_config


# Realistic sizes, SI units.
PLANTED = {
    "pitch_damping": -300.0,
    "alpha_dot_damping": -150.0,
    "lift_offset": 0.05,
    "drag_offset": 0.1,
    "moment_offset": 0.01,
    "lift_alpha_squared": 1.0,
    "drag_alpha_squared": 0.5,
    "moment_alpha_squared": -0.3,
    "thrust_misalignment": 0.01,
    "accelerometer_offset": 0.5,
    "sensor_bias:az": 0.3,
    "sensor_bias:q": 0.002,
    "actuator_delay": 0.05,
    "vertical_wind": 10.0,
}
NAMES = list(PLANTED)
TIME_ONLY = ("de", "mass", "Iyy", "Iyy_dot", "xcg")
STATES = ("u", "w", "q", "theta", "h")


@pytest.fixture(scope="module")
def runs():
    config = short_config()
    template = tuple(dp.make_effect(n, 0.0) for n in NAMES)
    # row 0: nothing planted; row i + 1: effect i alone
    values = np.zeros((len(NAMES) + 1, len(NAMES)))
    for i, n in enumerate(NAMES):
        values[i + 1, i] = PLANTED[n]

    def run(row):
        effects = tuple(
            eqx.tree_at(lambda e: getattr(e, e.parameter), e, row[i])
            for i, e in enumerate(template)
        )
        c = eqx.tree_at(lambda c: c.effects, config, effects)
        return dp.simulate(c, noise=False).channels

    out = jax.jit(jax.vmap(run))(jnp.asarray(values))
    out = {k: np.asarray(v) for k, v in out.items()}
    t = np.asarray(config.times)
    return {"base": {k: v[0] for k, v in out.items()} | {"t": t}} | {
        n: {k: v[i + 1] for k, v in out.items()} | {"t": t} for i, n in enumerate(NAMES)
    }


def _changed(a, b):
    return {k for k in a if k != "t" and not np.array_equal(a[k], b[k])}


def test_registry_has_every_canonical_name():
    expected = {
        "pitch_damping",
        "alpha_dot_damping",
        "lift_offset",
        "drag_offset",
        "moment_offset",
        "lift_alpha_squared",
        "drag_alpha_squared",
        "moment_alpha_squared",
        "thrust_misalignment",
        "accelerometer_offset",
        "sensor_bias",
        "actuator_delay",
        "vertical_wind",
    }
    assert set(dp.EFFECTS) == expected
    for cls in dp.EFFECTS.values():
        assert cls.description and hasattr(cls, cls.parameter)
        assert float(getattr(cls(), cls.parameter)) == 0.0


def test_parse_assignment_errors():
    with pytest.raises(ValueError, match="unknown effect 'pitch_dampin'"):
        dp.parse_assignment("pitch_dampin=1")
    with pytest.raises(ValueError, match="not a number"):
        dp.parse_assignment("lift_offset=abc")
    with pytest.raises(ValueError, match="NAME=VALUE"):
        dp.parse_assignment("lift_offset")
    with pytest.raises(ValueError, match="needs a channel"):
        dp.parse_assignment("sensor_bias=1")
    e = dp.parse_assignment("sensor_bias:qdot=0.1")
    assert e.channel == "qdot" and float(e.bias) == 0.1


@pytest.mark.parametrize("name", ["sensor_bias:az", "sensor_bias:q"])
def test_sensor_bias_changes_only_its_channel(runs, name):
    channel = name.split(":")[1]
    assert _changed(runs[name], runs["base"]) == {channel}
    np.testing.assert_allclose(
        runs[name][channel] - runs["base"][channel], PLANTED[name], rtol=1e-9
    )


def test_accelerometer_offset_changes_only_accelerometers(runs):
    r, b, dx = (
        runs["accelerometer_offset"],
        runs["base"],
        PLANTED["accelerometer_offset"],
    )
    assert _changed(r, b) == {"ax", "az"}
    np.testing.assert_allclose(r["ax"] - b["ax"], -(b["q"] ** 2) * dx, atol=1e-12)
    np.testing.assert_allclose(r["az"] - b["az"], -b["qdot"] * dx, atol=1e-12)


DYNAMIC = [
    n for n in NAMES if not n.startswith("sensor_bias") and n != "accelerometer_offset"
]


@pytest.mark.parametrize("name", DYNAMIC)
def test_dynamic_effects_change_the_motion_but_not_the_record(runs, name):
    r, b = runs[name], runs["base"]
    changed = _changed(r, b)
    for s in STATES:
        assert s in changed, f"{name} left {s} unchanged"
    for s in TIME_ONLY:
        assert s not in changed, f"{name} changed the time-only channel {s}"
    assert np.max(np.abs(r["q"] - b["q"])) > 1e-4


def _linear(r, channel_prefix, de):
    return (
        r[f"true_{channel_prefix}a"] * r["alpha"] + r[f"true_{channel_prefix}de"] * de
    )


@pytest.mark.parametrize(
    "name,coefficient,increment",
    [
        ("lift_offset", "CL", lambda r, v: v),
        ("drag_offset", "CD", lambda r, v: v),
        ("moment_offset", "CM", lambda r, v: v),
        ("lift_alpha_squared", "CL", lambda r, v: v * r["alpha"] ** 2),
        ("drag_alpha_squared", "CD", lambda r, v: v * r["alpha"] ** 2),
        ("moment_alpha_squared", "CM", lambda r, v: v * r["alpha"] ** 2),
        ("pitch_damping", "CM", lambda r, v: v * r["q"] * 2.48 / (2 * r["V"])),
    ],
)
def test_coefficient_increment(runs, name, coefficient, increment):
    r = runs[name]
    extra = r[f"true_{coefficient}"] - _linear(r, coefficient, r["de"])
    np.testing.assert_allclose(
        extra, increment(r, PLANTED[name]), rtol=1e-9, atol=1e-13
    )


def test_alpha_dot_damping_increment(runs):
    r = runs["alpha_dot_damping"]
    extra = r["true_CM"] - _linear(r, "CM", r["de"])
    alpha_dot = np.gradient(r["alpha"], r["t"])
    expected = PLANTED["alpha_dot_damping"] * alpha_dot * 2.48 / (2 * r["V"])
    # alpha_dot by 100 Hz finite differences: compare where alpha moves smoothly
    smooth = np.abs(np.gradient(alpha_dot, r["t"])) < 0.5
    smooth[[0, -1]] = False  # one-sided differences at the ends
    assert smooth.mean() > 0.5
    np.testing.assert_allclose(extra[smooth], expected[smooth], atol=2e-4)
    assert np.max(np.abs(extra)) > 1e-3


def test_thrust_misalignment_moment_balance(runs):
    r, offset = runs["thrust_misalignment"], PLANTED["thrust_misalignment"]
    lhs = r["Iyy"] * r["qdot"] + r["Iyy_dot"] * r["q"]
    aero = (
        r["qbar"] * 13.5 * 2.48 * r["true_CM"]
        + (r["xcp"] - r["xcg"]) * r["mass"] * r["az"]
    )
    np.testing.assert_allclose(
        lhs - aero, offset * r["thrust"], atol=1e-6 * np.abs(lhs).max()
    )
    assert np.max(offset * r["thrust"]) > 4e3


def test_actuator_delay_acts_on_the_surface_not_the_record(runs):
    r, tau = runs["actuator_delay"], PLANTED["actuator_delay"]
    shift = int(round(tau * 100))
    delayed = np.concatenate([np.full(shift, r["de"][0]), r["de"][:-shift]])
    extra = r["true_CM"] - _linear(r, "CM", delayed)
    np.testing.assert_allclose(extra, 0.0, atol=1e-12)
    np.testing.assert_array_equal(r["de"], runs["base"]["de"])


def test_vertical_wind_changes_air_relative_alpha(runs):
    r, w_up = runs["vertical_wind"], PLANTED["vertical_wind"]
    ua = r["u"] - w_up * np.sin(r["theta"])
    wa = r["w"] + w_up * np.cos(r["theta"])
    np.testing.assert_allclose(r["alpha"], np.arctan2(wa, ua), atol=1e-12)
    np.testing.assert_allclose(r["V"], np.hypot(ua, wa), rtol=1e-12)
    # an updraft raises alpha at the drop, before the motion has changed
    assert r["alpha"][0] - runs["base"]["alpha"][0] == pytest.approx(
        w_up / r["V"][0], rel=0.05
    )


def test_pitch_damping_damps(runs):
    late = runs["base"]["t"] > 8
    assert np.std(runs["pitch_damping"]["q"][late]) < 0.9 * np.std(
        runs["base"]["q"][late]
    )


class MachMoment(dp.AbstractEffect):
    """The README's example of a user-written effect."""

    CMmach: float = 0.0
    name = "mach_moment"
    description = "pitching moment growing with Mach, CMmach (M - 1)"
    parameter = "CMmach"

    def moment_coefficient(self, c):
        return self.CMmach * (c.mach - 1.0)


def test_user_written_effect_plugs_in():
    from .helpers import short_config

    config = short_config(t_final=2.0, effects=(MachMoment(0.01),))
    r = dp.simulate(config, noise=False).channels
    extra = r["true_CM"] - (r["true_CMa"] * r["alpha"] + r["true_CMde"] * r["de"])
    np.testing.assert_allclose(
        np.asarray(extra), 0.01 * (np.asarray(r["mach"]) - 1.0), rtol=1e-9
    )
