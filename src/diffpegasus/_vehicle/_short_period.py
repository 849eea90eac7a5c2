"""The linear short-period model of the thesis's input-design study (section 3.3).

States alpha and q, elevator input, normal acceleration output, with the dynamic
derivatives Z_q = M_q = 0 as in the thesis:

    alpha' = Z_a / U alpha + q + Z_de / U de
    q'     = M_a alpha + M_de de
    az     = Z_a alpha + Z_de de

with `Z_x = qbar S / m CZ_x` and `M_x = qbar S c / Iyy CM_x`. The flight condition is a
fixed altitude and a Mach number constant or varying linearly in time; CZ_x and CM_x
(about the CG) come from the Pegasus database linearised at a reference alpha, with
the cp-to-CG transfer, so they change with Mach as the vehicle's would.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._custom_types import Scalar, ScalarLike
from .._inputs import AbstractInput
from ._atmosphere import isa
from ._pegasus._aerodynamics import AeroDatabase, load_database


class ShortPeriodModel(eqx.Module):
    """Linear short-period dynamics at a fixed altitude and a linear Mach schedule.

    **Fields:** `mach_start`, `mach_end` (Mach at t = 0 and at `duration`),
    `duration` (s), `altitude` (m), `mass` (kg), `iyy` (kg m^2), `xcg`, `xcp` (m from
    the nose), `alpha_ref` (rad, where the database is linearised), `s_ref`, `c_ref`,
    `aero` (the database).
    """

    mach_start: ScalarLike = 2.0
    mach_end: ScalarLike = 2.0
    duration: float = eqx.field(static=True, default=50.0)
    altitude: ScalarLike = 15_000.0
    mass: ScalarLike = 15_000.0
    iyy: ScalarLike = 2.2e5
    xcg: ScalarLike = 8.2
    xcp: ScalarLike = 10.4
    alpha_ref: ScalarLike = float(np.deg2rad(2.0))
    s_ref: float = eqx.field(static=True, default=13.5)
    c_ref: float = eqx.field(static=True, default=2.48)
    aero: AeroDatabase = eqx.field(default_factory=load_database)

    def mach(self, t: ScalarLike) -> Scalar:
        return self.mach_start + (self.mach_end - self.mach_start) * t / self.duration

    def derivatives(self, t: ScalarLike) -> Float[Array, "4"]:
        """`[CZa, CZde, CMa, CMde]` (1/rad, moment about the CG) at time `t`."""
        d = self.aero.derivatives(self.alpha_ref, self.mach(t))
        cza = -(d.CLa + d.CDa * self.alpha_ref)
        czde = -d.CLde
        arm = (self.xcp - self.xcg) / self.c_ref
        return jnp.stack([cza, czde, d.CMa + arm * cza, d.CMde + arm * czde])

    def dimensional(self, t: ScalarLike) -> tuple[Scalar, ...]:
        """`(U, qbar, Z_a, Z_de, M_a, M_de)` at time `t`."""
        atm = isa(self.altitude)
        u = self.mach(t) * atm.speed_of_sound
        qbar = 0.5 * atm.density * u**2
        cza, czde, cma, cmde = self.derivatives(t)
        zf = qbar * self.s_ref / self.mass
        mf = qbar * self.s_ref * self.c_ref / self.iyy
        return u, qbar, zf * cza, zf * czde, mf * cma, mf * cmde


def _rates(t, y, args):
    model, elevator = args
    u, _, za, zde, ma, mde = model.dimensional(t)
    alpha, q = y
    de = elevator(t)
    return jnp.stack([za / u * alpha + q + zde / u * de, ma * alpha + mde * de])


@eqx.filter_jit
def simulate_short_period(
    model: ShortPeriodModel, elevator: AbstractInput, *, dt: float = 5e-3
) -> dict[str, Float[Array, " n"]]:
    """Simulate the linear model from its steady state for the initial elevator.

    **Arguments:** the model, the elevator input (rad), the fixed step `dt` (s; the
    thesis's 5 ms), which is also the sample interval.

    **Returns:** channels `t, de, alpha, q, qdot, az, qbar, mach` and the truth
    `true_CZa, true_CZde, true_CMa, true_CMde` (1/rad), sampled every `dt`.
    """
    n = int(round(model.duration / dt)) + 1
    ts = jnp.arange(n) * dt
    u, _, za, zde, ma, mde = model.dimensional(0.0)
    de0 = elevator(0.0)
    alpha0 = -mde / ma * de0
    q0 = -(za * alpha0 + zde * de0) / u
    import diffrax  # here, not at the top: commands that never simulate skip it

    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(_rates),
        diffrax.Tsit5(),
        t0=0.0,
        t1=float(model.duration),
        dt0=dt,
        y0=jnp.stack([alpha0, q0]),
        args=(model, elevator),
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.ConstantStepSize(),
        max_steps=n + 16,
    )
    alpha, q = sol.ys[:, 0], sol.ys[:, 1]
    de = jax.vmap(elevator)(ts)
    qdot = jax.vmap(lambda t, y: _rates(t, y, (model, elevator))[1])(ts, sol.ys)
    dims = jax.vmap(model.dimensional)(ts)
    truth = jax.vmap(model.derivatives)(ts)
    az = dims[2] * alpha + dims[3] * de
    out = {
        "t": ts,
        "de": de,
        "alpha": alpha,
        "q": q,
        "qdot": qdot,
        "az": az,
        "qbar": dims[1],
        "mach": jax.vmap(model.mach)(ts),
    }
    for j, name in enumerate(("CZa", "CZde", "CMa", "CMde")):
        out[f"true_{name}"] = truth[:, j]
    return out
