"""The plausible Pegasus lateral database: the fin terms against an independent
vector computation of the three fins' forces and moments, and what the database
gives (documented in its module)."""

import numpy as np
import pytest

import diffpegasus as dp
from diffpegasus._vehicle._pegasus._lateral import (
    FIN_ARM,
    fin_lift_slope,
    FIN_STATION,
    pegasus_aircraft,
    pegasus_lateral,
    pegasus_speed,
)


def _fins_by_vectors(state, mach, xcg, area, s_ref, b, c):
    """Force and moment coefficients `(CY, Cl, Cm, Cn)` of the three fins, each a flat
    plate at its centroid: incidence = (air velocity relative to the centroid) . normal
    / V plus its deflection, force = lift slope x incidence x area along the normal,
    moment = r x F about the CG. `state`: beta (rad), p, q, r (rad/s), da, dr (rad),
    V (m/s); dynamic pressure 1."""
    beta, p, q, r, da, dr, speed = state
    a = fin_lift_slope(mach)
    arm = FIN_STATION - xcg
    omega = np.array([p, q, r])
    body = np.array([speed, speed * beta, 0.0])  # small sideslip, alpha 0
    fins = [  # position from the CG (x fwd, y right, z down), normal, deflection
        (np.array([-arm, FIN_ARM, 0.0]), np.array([0.0, 0.0, -1.0]), da),
        (np.array([-arm, -FIN_ARM, 0.0]), np.array([0.0, 0.0, -1.0]), -da),
        (np.array([-arm, 0.0, FIN_ARM]), np.array([0.0, 1.0, 0.0]), dr),
    ]
    force, moment = np.zeros(3), np.zeros(3)
    for pos, normal, deflection in fins:
        air = -(body + np.cross(omega, pos))
        f = a * area * (air @ normal / speed + deflection) * normal
        force += f
        moment += np.cross(pos, f)
    return (
        force[1] / s_ref,
        moment[0] / (s_ref * b),
        moment[1] / (s_ref * c),
        moment[2] / (s_ref * b),
    )


@pytest.mark.parametrize("mach", [0.8, 1.05, 2.0, 4.0])
def test_fin_derivatives_match_the_fins_as_vectors(mach):
    v = dp.Vehicle()
    xcg, area = 7.9, 1.6
    with_fins = pegasus_lateral(mach, xcg, 3.0, v, fin_area=area)
    without = pegasus_lateral(mach, xcg, 3.0, v, fin_area=0.0)
    fins = dp.LateralDerivatives(
        **{
            n: getattr(with_fins, n) - getattr(without, n)
            for n in dp.LATERAL_DERIVATIVE_NAMES
        }
    )
    rng = np.random.default_rng(int(10 * mach))
    for _ in range(5):
        beta, p, r, da, dr = rng.normal(size=5) * [0.02, 0.1, 0.05, 0.03, 0.03]
        speed = 300.0
        cy, cl, cn = dp.lateral_coefficients(fins, beta, p, r, da, dr, speed, v.span)
        ref = _fins_by_vectors(
            (beta, p, 0.0, r, da, dr, speed), mach, xcg, area, v.s_ref, v.span, v.c_ref
        )
        # both linear in the state: equal to rounding (measured 7e-18 absolute)
        np.testing.assert_allclose([cy, cl, cn], [ref[0], ref[1], ref[3]], atol=1e-13)


def test_fin_pitch_damping_matches_the_fins_as_vectors():
    t, mach = 20.0, 2.0
    q, speed = 0.1, 300.0
    a = pegasus_aircraft(t, mach, fin_area=1.6)
    b = pegasus_aircraft(t, mach, fin_area=0.0)
    xcg = float(dp.Vehicle().mass.at(t, dp.Vehicle().motor).xcg)
    ref = _fins_by_vectors((0.0, 0.0, q, 0.0, 0.0, 0.0, speed), mach, xcg, 1.6,
                           a.s_ref, a.b_ref, a.c_ref)  # fmt: skip
    # Cmq per q c / 2V
    assert (a.Cmq - b.Cmq) * q * a.c_ref / (2 * speed) == pytest.approx(
        ref[2], rel=1e-12
    )


def test_what_the_database_gives():
    """The numbers the module docstring states (an estimate: directionally unstable,
    a stable roll-yaw oscillation, at the default condition)."""
    aircraft = pegasus_aircraft()
    assert aircraft.lateral.Cn_beta == pytest.approx(-0.068, abs=2e-3)
    drop = pegasus_aircraft(0.0, 0.8, 11_900.0)  # at the drop, Mach 0.8
    assert drop.lateral.Cn_beta == pytest.approx(-0.047, abs=2e-3)
    start = dp.trim(aircraft, pegasus_speed(), altitude=16_000.0)
    assert float(start.y[7]) == pytest.approx(0.145, abs=5e-3)  # 8.3 deg
    jac, _ = dp.linearise(aircraft, start)
    lateral = np.ix_([1, 3, 5, 6], [1, 3, 5, 6])  # v, p, r, phi
    eig = np.linalg.eigvals(np.asarray(jac)[lateral])
    # measured: 0.603 (divergence), -0.877 +/- 0.631j, 0.001 (spiral, neutral)
    assert max(eig.real) == pytest.approx(0.603, abs=5e-3)
    osc = eig[np.abs(eig.imag) > 1e-6]
    np.testing.assert_allclose(osc.real, -0.877, atol=5e-3)
    np.testing.assert_allclose(np.abs(osc.imag), 0.631, atol=5e-3)
