"""The weathercocking mode of the rocket's attitude against its closed form: the
eigenvalues of the model's linearisation in straight coasting flight against the
short-period-like system of the body's pitch, its rate and the flight path, with
the normal-force slope and pitch damping scaled as the fit scales them."""

import pathlib

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diffpegasus.rocket as dr
from diffpegasus._vehicle._rocket._model import rates


SIM = pathlib.Path(__file__).parent / "data" / "rocket_sim"


@pytest.fixture(scope="module")
def coasting():
    """The fixture rocket's flight and one compiled `(Jacobian of the rates, air
    data)` at a state, for any parameters."""
    rocket = dr.read_rocket(SIM / "clean" / "rocket.toml", attitude=True)
    flight = dr.Flight(rocket, dr.DragKnots((0.1, 0.5, 0.9)), 101325.0)
    u = jnp.zeros(3)

    @jax.jit
    def linearised(x, p):
        jac = jax.jacfwd(lambda x: rates(flight, 0.0, x, u, p))(x)
        return jac, flight.forces(0.0, x, u, p)[2]

    return rocket, flight, linearised


@pytest.mark.parametrize("cn_scale, damping_scale", [(1.0, 1.0), (1.3, 0.6)])
def test_weathercocking_mode_against_its_closed_form(coasting, cn_scale, damping_scale):
    """Coasting straight up at 150 m/s (burned out, no wind), the lateral motion
    linearised by hand in the axis's tilt `theta`, its rate `w` and the lateral
    velocity `v_x`: with `l_i` each station's distance ahead of the centre of mass,
    `k` the `CN_alpha` scale and `c` the damping scale, each station's normal force
    is `-(rho V S / 2) CNa_i (k (v_x - V theta) + c l_i w)`, so

        I w'   = sum_i l_i (that force),   theta' = w,
        m v_x' = sum_i (that force) - D theta

    (`D` the drag along the tilted axis). Its complex pair is the weathercocking
    mode; the model's 12-state Jacobian has it twice (pitch and yaw, apart by 7e-7
    relative: the Earth's rotation). Measured: equal to 1e-6 relative; for this
    rocket at 1000 m, a natural frequency of 1.581 Hz and a damping ratio of 0.109
    unscaled (the restoring term alone, `sqrt(-q S sum(CNa_i l_i) / I)`: 1.575
    Hz)."""
    rocket, flight, linearised = coasting
    frame, knots = rocket.airframe, flight.knots
    p = dict.fromkeys(dr.EFFECTS, 0.0)
    p.update(dict(zip(knots.names, (0.5, 0.5, 0.5), strict=True)))
    p.update(
        cd_scale=1.0,
        power_on_ratio=1.0,
        thrust_scale=1.0,
        burn_scale=1.0,
        motor_time=-100.0,  # long burned out
        temperature=288.15,
        lapse_rate=-6.5,
        accel_scale=1.0,
        cn_alpha_scale=cn_scale,
        pitch_damping_scale=damping_scale,
    )
    p = {k: jnp.asarray(v) for k, v in p.items()}
    v = 150.0
    x = np.zeros(12)
    x[:3] = [0.0, 0.0, 1000.0]
    x[3:6] = [0.0, 0.0, v]
    x[6:9] = [0.0, 0.0, 1.0]
    jac, air = linearised(jnp.asarray(x), p)
    model_eig = np.linalg.eigvals(np.asarray(jac))
    model_eig = model_eig[np.abs(model_eig.imag) > 1.0]

    q, rho, g, mach = (float(air[i]) for i in range(4))
    cna = np.asarray(frame.cn_alpha(mach))
    mass = rocket.dry_mass  # burned out
    m_r, m_m = rocket.dry_mass - rocket.motor.dry_mass, rocket.motor.dry_mass
    cg = (m_r * frame.cg_rocket + m_m * frame.motor_cg) / (m_r + m_m)
    inertia = (
        frame.inertia
        + m_r * (frame.cg_rocket - cg) ** 2
        + frame.motor_inertia
        + m_m * (frame.motor_cg - cg) ** 2
    )
    arm = np.asarray(frame.stations) - cg
    s = rocket.area
    drag = q * s * 0.5
    half = 0.5 * rho * v * s
    # states (theta, w, v_x)
    m_theta = q * s * cn_scale * np.sum(cna * arm) / inertia
    m_w = -half * damping_scale * np.sum(cna * arm**2) / inertia
    m_v = -half * cn_scale * np.sum(cna * arm) / inertia
    z_theta = (q * s * cn_scale * np.sum(cna) - drag) / mass
    z_w = -half * damping_scale * np.sum(cna * arm) / mass
    z_v = -half * cn_scale * np.sum(cna) / mass
    a = np.array([[0.0, 1.0, 0.0], [m_theta, m_w, m_v], [z_theta, z_w, z_v]])
    closed = np.linalg.eigvals(a)
    closed = closed[np.abs(closed.imag) > 1.0]
    assert len(model_eig) == 4 and len(closed) == 2
    for lam in closed:
        near = model_eig[np.argsort(np.abs(model_eig - lam))[:2]]
        np.testing.assert_allclose(near, [lam, lam], rtol=1e-6)
    if cn_scale == 1.0:
        lam = closed[closed.imag > 0][0]
        # the numbers the docstring quotes, to their printed digits
        np.testing.assert_allclose(abs(lam) / (2 * np.pi), 1.581, atol=0.0005)
        np.testing.assert_allclose(-lam.real / abs(lam), 0.109, atol=0.0005)
        stiff = np.sqrt(-m_theta) / (2 * np.pi)
        np.testing.assert_allclose(stiff, 1.575, atol=0.0005)
