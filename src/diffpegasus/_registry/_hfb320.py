"""The HFB-320 vehicles as registry entries: the longitudinal business jet and
the lateral-directional textbook model (see [`AbstractVehicleEntry`][])."""

from .._errors import LogError
from .._estimate._modelfile import ModelSpec
from .._log._format import FlightLog
from . import AbstractModelEntry, hold_candidates


def _planted(hidden, allowed, vehicle: str):
    """`NAME=VALUE` texts as `({name: value}, turbulence sigma)`."""
    from .._vehicle._effects import parse_assignment, Turbulence

    planted, turbulence = {}, 0.0
    for text in hidden:
        try:
            effect = parse_assignment(text)
        except ValueError as e:
            raise LogError(f"--hidden {text}: {e}") from None
        name = text.partition("=")[0].strip()
        if isinstance(effect, Turbulence):
            turbulence = float(effect.sigma)
            continue
        if name not in allowed:
            raise LogError(
                f"{name} does not compose with {vehicle}; it takes "
                f"{', '.join(allowed)} and turbulence"
            )
        planted[name] = float(effect.value())
    return planted, turbulence


class HFB320Entry(AbstractModelEntry):
    """The HFB-320 business jet, longitudinal (the published model, thrust from
    the log)."""

    description: str = (
        "HFB-320 business jet, longitudinal (Jategaonkar test case 4: 11 "
        "aerodynamic derivatives, thrust from the log, real DLR flight record): "
        "simulate, fit, compare, diagnose"
    )

    def spec(self, add=(), candidates=False, manoeuvres=1) -> ModelSpec:
        del manoeuvres
        from .._vehicle._hfb320 import (
            CANDIDATES,
            COLUMNS,
            effect_parameter,
            HFB320,
            hfb320_model,
            PROCESS_NOISE,
            X0,
        )

        unknown = [a for a in add if a not in CANDIDATES]
        if unknown:
            raise LogError(
                f"effects {unknown} do not compose with hfb320; it takes "
                f"{', '.join(CANDIDATES)}"
            )
        # one order for every call, so diagnose and each --add share a program
        effects = tuple(dict.fromkeys((CANDIDATES if candidates else ()) + add))
        return hold_candidates(
            ModelSpec(
                model=hfb320_model(effects=effects, free=add),
                name="hfb320",
                columns=COLUMNS,
                x0=X0,
                candidates=tuple(effect_parameter(e) for e in effects if e not in add),
                process_noise=dict(PROCESS_NOISE),
                gust=("V", "alpha"),
                vehicle=HFB320,
            )
        )

    def fly(self, request) -> FlightLog:
        from .._vehicle._hfb320 import CANDIDATES
        from ._hfb320_simulator import simulate_log

        if request.perturb:
            raise LogError("--perturb: the HFB-320 has no Monte Carlo model")
        if request.input not in ("pulse", "3211"):
            raise LogError(
                f"--input {request.input}: the HFB-320 flies the book's 3-2-1-1"
            )
        planted, turbulence = _planted(request.hidden, CANDIDATES, "hfb320")
        duration, rate = request.timing(30.0, 10.0)
        channels, meta = simulate_log(
            duration=duration,
            rate=rate,
            seed=request.seed,
            noise=request.noise,
            hidden=planted,
            turbulence=turbulence,
        )
        return FlightLog(channels=channels, metadata=meta)

    def geometry(self):
        from .._vehicle._hfb320 import CBAR, S_REF

        return float(S_REF), float(CBAR)


class HFB320LateralEntry(AbstractModelEntry):
    """The lateral-directional textbook model; several logs are several
    manoeuvres, each with its own state biases."""

    description: str = (
        "lateral-directional motion, the textbooks' linear model "
        "(Jategaonkar test cases 1 and 34: 15 derivatives, state and output "
        "biases, 22 parameters; several logs are several manoeuvres, each with "
        "its own state biases), the HFB-320 record's lateral columns mapped: fit, "
        "diagnose (aileron and rudder delay); simulate flies the 6-DOF business jet"
    )

    def spec(self, add=(), candidates=False, manoeuvres=1) -> ModelSpec:
        from .._vehicle._lateral import LATERAL_COLUMNS, LATERAL_EFFECTS, lateral_model

        unknown = [a for a in add if a not in LATERAL_EFFECTS]
        if unknown:
            raise LogError(
                f"effects {unknown} do not compose with hfb320-lateral; it takes "
                f"{', '.join(LATERAL_EFFECTS)}"
            )
        effects = tuple(
            dict.fromkeys((tuple(LATERAL_EFFECTS) if candidates else ()) + add)
        )
        return hold_candidates(
            ModelSpec(
                model=lateral_model(manoeuvres=manoeuvres, effects=effects, free=add),
                name="hfb320-lateral",
                columns={ch: {"column": col} for ch, col in LATERAL_COLUMNS.items()},
                # the book's x0 = 0, held: the lumped biases absorb the initial rates
                x0=(0.0, 0.0),
                candidates=tuple(f"{e}.tau" for e in effects if e not in add),
            )
        )

    def fly(self, request) -> FlightLog:
        from .._vehicle._lateral_sixdof import simulate_lateral_log

        if request.perturb:
            raise LogError("--perturb: the business jet has no Monte Carlo model")
        planted = {}
        for text in request.hidden:
            spec, _, value = text.partition("=")
            try:
                planted[spec.strip()] = float(value)
            except ValueError:
                raise LogError(
                    f"--hidden {text}: expected sensor_bias:CHANNEL=VALUE"
                ) from None
        first = {"pulse": "aileron", "aileron": "aileron", "rudder": "rudder"}.get(
            request.input
        )
        if first is None:
            raise LogError(
                f"--input {request.input}: a lateral manoeuvre starts with aileron (an "
                "aileron 3-2-1-1, then a rudder doublet) or rudder (the other way "
                "round)"
            )
        duration, rate = request.timing(25.0, 25.0)
        channels, meta = simulate_lateral_log(
            duration=duration,
            rate=rate,
            seed=request.seed,
            noise=request.noise,
            first=first,
            hidden=planted,
        )
        return FlightLog(channels=channels, metadata=meta)

    def geometry(self):
        from .._vehicle._hfb320 import CBAR, S_REF

        return float(S_REF), float(CBAR)
