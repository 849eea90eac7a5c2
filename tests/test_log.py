"""Flight-log round trip and one clear error line for every kind of bad log."""

import json

import numpy as np
import pytest

import diffpegasus as dp
from diffpegasus._log._format import REQUIRED_CHANNELS


def plausible_channels(
    n=50, rate=100.0, theta0=0.08, theta_amplitude=0.1, acceleration=5.0
) -> dict[str, np.ndarray]:
    """Channels of a smooth pitch-plane flight that obey the kinematics, the standard
    atmosphere and plausible coefficients exactly, so only a planted fault fails the
    plausibility checks."""
    from diffpegasus._log._checks import G, isa_density_and_sound

    t = np.arange(n) / rate
    w1, w2 = 2 * np.pi * 0.5, 2 * np.pi * 0.3
    alpha = 0.05 + 0.03 * np.sin(w1 * t)
    alpha_dot = 0.03 * w1 * np.cos(w1 * t)
    theta = theta0 + theta_amplitude * np.sin(w2 * t)
    q = theta_amplitude * w2 * np.cos(w2 * t)
    qdot = -theta_amplitude * w2**2 * np.sin(w2 * t)
    v = 250.0 + acceleration * t
    gamma = theta - alpha
    along = acceleration + G * np.sin(gamma)
    normal = -v * (q - alpha_dot) - G * np.cos(gamma)
    climb = v * np.sin(gamma)
    h = (
        5000.0
        + np.concatenate([[0.0], np.cumsum(0.5 * (climb[1:] + climb[:-1]))]) / rate
    )
    rho, sound = isa_density_and_sound(h)
    qbar = 0.5 * rho * v**2
    mass = np.full(n, 5000.0)
    ax = along * np.cos(alpha) - normal * np.sin(alpha)
    az = along * np.sin(alpha) + normal * np.cos(alpha)
    return {
        "t": t,
        "de": 0.01 * np.sin(2 * np.pi * t),
        "ax": ax,
        "az": az,
        "q": q,
        "qdot": qdot,
        "alpha": alpha,
        "V": v,
        "theta": theta,
        "h": h,
        "mach": v / sound,
        "qbar": qbar,
        "thrust": mass * ax + 0.02 * qbar * 13.5,
        "mass": mass,
        "Iyy": np.full(n, 1e5),
        "Iyy_dot": np.zeros(n),
        "xcg": np.full(n, 5.0),
        "xcp": np.full(n, 5.5),
    }


def _log(n=50, rate=100.0) -> dp.FlightLog:
    rng = np.random.default_rng(0)
    channels = plausible_channels(n, rate)
    channels["true_CLa"] = rng.normal(size=n)
    return dp.FlightLog(channels=channels, metadata={"seed": 3})


def test_round_trip_is_exact(tmp_path):
    log = _log()
    path = dp.write_log(tmp_path / "f.csv", log)
    back = dp.read_log(path)
    assert set(back.channels) == set(log.channels)
    for c in log.channels:
        np.testing.assert_array_equal(back[c], log[c])
    assert back.metadata["seed"] == 3
    assert back.metadata["S_ref"] == 13.5 and back.metadata["c_ref"] == 2.48
    assert back.sample_rate == pytest.approx(100.0)
    header = path.read_text().splitlines()[0].split(",")
    assert header[: len(REQUIRED_CHANNELS)] == list(REQUIRED_CHANNELS)


def test_no_sidecar_means_pegasus_defaults(tmp_path):
    path = dp.write_log(tmp_path / "f.csv", _log())
    path.with_suffix(".json").unlink()
    back = dp.read_log(path)
    assert back.metadata["S_ref"] == 13.5 and back.metadata["vehicle"] == "pegasus"


def _write_csv(path, channels):
    names = list(channels)
    rows = [",".join(names)]
    n = len(channels["t"])
    for i in range(n):
        rows.append(",".join(str(channels[c][i]) for c in names))
    path.write_text("\n".join(rows) + "\n")
    return path


def _error(tmp_path, mutate, **kwargs) -> str:
    channels = dict(_log().channels)
    mutate(channels)
    path = _write_csv(tmp_path / "bad.csv", channels)
    with pytest.raises(dp.LogError) as info:
        dp.read_log(path, **kwargs)
    message = str(info.value)
    assert "\n" not in message
    assert str(path) in message
    return message


def test_missing_channel(tmp_path):
    msg = _error(tmp_path, lambda c: c.pop("az"))
    assert "missing channel(s) 'az'" in msg


def test_nan_names_column_and_row(tmp_path):
    def mutate(c):
        c["q"] = c["q"].copy()
        c["q"][16] = np.nan

    msg = _error(tmp_path, mutate)
    assert "column 'q', row 17" in msg and "nan" in msg


def test_inf(tmp_path):
    def mutate(c):
        c["qbar"] = c["qbar"].copy()
        c["qbar"][3] = np.inf

    assert "column 'qbar', row 4: value inf" in _error(tmp_path, mutate)


def test_non_numeric_cell(tmp_path):
    channels = dict(_log().channels)
    path = _write_csv(tmp_path / "bad.csv", channels)
    lines = path.read_text().splitlines()
    cells = lines[5].split(",")
    cells[2] = "oops"
    lines[5] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(
        dp.LogError, match=r"column 'ax', row 5: 'oops' is not a number"
    ):
        dp.read_log(path)


def test_time_not_increasing(tmp_path):
    def mutate(c):
        c["t"] = c["t"].copy()
        c["t"][10] = c["t"][9]

    msg = _error(tmp_path, mutate)
    assert "column 't', row 11" in msg and "increase strictly" in msg


def test_non_uniform_time_is_an_error_or_resampled(tmp_path):
    def mutate(c):
        c["t"] = c["t"].copy()
        c["t"][20:] += 0.003

    msg = _error(tmp_path, mutate)
    assert "column 't', row 21" in msg and "non-uniform" in msg
    path = tmp_path / "bad.csv"
    with pytest.warns(UserWarning, match="resampled"):
        log = dp.read_log(path, resample=True)
    assert np.allclose(np.diff(log.t), np.diff(log.t)[0])


def test_alpha_in_degrees(tmp_path):
    def mutate(c):
        c["alpha"] = np.rad2deg(c["alpha"])

    msg = _error(tmp_path, mutate)
    assert "column 'alpha'" in msg and "degrees" in msg


def test_too_few_samples(tmp_path):
    path = dp.write_log(tmp_path / "f.csv", _log(n=30))
    with pytest.raises(dp.LogError, match="only 30 samples; at least 50"):
        dp.read_log(path, min_samples=50)


def test_non_positive_mass(tmp_path):
    def mutate(c):
        c["mass"] = c["mass"].copy()
        c["mass"][7] = -1.0

    assert "column 'mass', row 8: value -1.0 must be positive" in _error(
        tmp_path, mutate
    )


def test_bad_sidecar(tmp_path):
    path = dp.write_log(tmp_path / "f.csv", _log())
    path.with_suffix(".json").write_text("{not json")
    with pytest.raises(dp.LogError, match="not valid JSON"):
        dp.read_log(path)
    path.with_suffix(".json").write_text(json.dumps({"sample_rate_hz": 50}))
    with pytest.raises(dp.LogError, match="disagrees with the time column"):
        dp.read_log(path)
    path.with_suffix(".json").write_text(json.dumps({"S_ref": -2}))
    with pytest.raises(dp.LogError, match="S_ref must be a positive number"):
        dp.read_log(path)


def test_missing_and_empty_files(tmp_path):
    with pytest.raises(dp.LogError, match="no such file"):
        dp.read_log(tmp_path / "nope.csv")
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(dp.LogError, match="empty"):
        dp.read_log(tmp_path / "empty.csv")


def test_ragged_row(tmp_path):
    path = dp.write_log(tmp_path / "f.csv", _log())
    lines = path.read_text().splitlines()
    lines[3] = lines[3] + ",1.0"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(dp.LogError, match="row 3 has"):
        dp.read_log(path)


def test_simulated_flight_round_trip(tmp_path):
    from .helpers import short_config

    flight = dp.simulate(short_config(t_final=3.0))
    log = dp.flight_to_log(flight, {"seed": 0})
    path = dp.write_log(tmp_path / "sim.csv", log)
    back = dp.read_log(path)
    assert back.has_truth
    np.testing.assert_array_equal(back["az"], np.asarray(flight.channels["az"]))
