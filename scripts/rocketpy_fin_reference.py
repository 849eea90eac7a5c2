"""RocketPy's normal-force slopes and centres of pressure for fins of every planform,
the reference numbers of tests/test_rocket_fins.py (which must not need RocketPy).

Run with a Python that has RocketPy (1.x):
    python scripts/rocketpy_fin_reference.py tests/data/rocketpy_fins.json

Per case: the fin set's `clalpha` (per radian, on the rocket's reference area,
interference and fin count included) at Mach 0, 0.6, 0.8 and its `cpz` (m behind
the root's leading edge), and for the whole Hedy-like rocket RocketPy's
`total_lift_coeff_der` and `cp_position`.
"""

import importlib.metadata
import json
import sys

from rocketpy import Rocket
from rocketpy.rocket.aero_surface import EllipticalFins, FreeFormFins, TrapezoidalFins


MACHS = (0.0, 0.6, 0.8)
HEDY_FINS = [[0, 0], [0.25, -0.012], [0.25, 0.108], [0.195, 0.108], [0, 0]]
# a clipped delta with a rounded tip: not a trapezoid, no closed form
ROUNDED = [[0, 0], [0.08, 0.06], [0.11, 0.085], [0.14, 0.095], [0.17, 0.09], [0.2, 0]]


def fins_row(fins):
    return {
        "clalpha": [float(fins.clalpha(m)) for m in MACHS],
        "cpz": float(fins.cpz),
    }


def cases():
    out = {}
    r = 0.05
    out["trapezoid"] = dict(
        kind="trapezoidal",
        n=4,
        root=0.2,
        tip=0.07,
        span=0.1,
        sweep=0.09,
        radius=r,
        **fins_row(TrapezoidalFins(4, 0.2, 0.07, 0.1, r, sweep_length=0.09)),
    )
    out["trapezoid_as_polygon"] = dict(
        kind="free-form",
        n=4,
        points=[[0, 0], [0.09, 0.1], [0.16, 0.1], [0.2, 0]],
        radius=r,
        **fins_row(FreeFormFins(4, [(0, 0), (0.09, 0.1), (0.16, 0.1), (0.2, 0)], r)),
    )
    for n in (3, 4, 6):
        out[f"elliptical_{n}"] = dict(
            kind="elliptical",
            n=n,
            root=0.15,
            span=0.08,
            radius=r,
            **fins_row(EllipticalFins(n, 0.15, 0.08, r)),
        )
    out["rounded_polygon"] = dict(
        kind="free-form",
        n=4,
        points=ROUNDED,
        radius=r,
        **fins_row(FreeFormFins(4, [tuple(p) for p in ROUNDED], r)),
    )
    out["hedy_fins"] = dict(
        kind="free-form",
        n=4,
        points=HEDY_FINS,
        radius=0.0664,
        **fins_row(FreeFormFins(4, [tuple(p) for p in HEDY_FINS], 0.0664)),
    )
    # Hedy's aerodynamic surfaces as its rocket.toml states them (masses irrelevant)
    rocket = Rocket(
        radius=0.0664,
        mass=17.2,
        inertia=(16.8, 16.8, 0.0255),
        power_off_drag=0.4,
        power_on_drag=0.4,
        center_of_mass_without_motor=1.813,
        coordinate_system_orientation="tail_to_nose",
    )
    rocket.add_nose(length=0.461, kind="lvhaack", position=3.707)
    rocket.add_free_form_fins(
        n=4, shape_points=[tuple(p) for p in HEDY_FINS], position=0.25
    )
    rocket.add_tail(
        top_radius=0.0664, bottom_radius=0.054, length=0.245, position=0.245
    )
    out["hedy_rocket"] = dict(
        total_lift_coeff_der=[float(rocket.total_lift_coeff_der(m)) for m in MACHS],
        cp_position=[float(rocket.cp_position(m)) for m in MACHS],
    )
    return out


if __name__ == "__main__":
    res = {"rocketpy": importlib.metadata.version("rocketpy"), "mach": MACHS}
    res.update(cases())
    text = json.dumps(res, default=float)
    if len(sys.argv) > 1:
        open(sys.argv[1], "w").write(text + "\n")
    print(text)
