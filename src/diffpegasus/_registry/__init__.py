"""Vehicles by name: each built-in vehicle is one registry entry, a value whose
methods the command line calls; a vehicle file (`.py`) is one more entry.

An entry ([`AbstractVehicleEntry`][]) says everything the commands need of a
vehicle, and nothing else asks which vehicle it is:

- `description`: one line for `diffpegasus vehicles`;
- `problem(files, ...)`: the model builder, its columns and initial state, its
  candidates and process noise: a [`ModelSpec`][] (a `dp.Model` with what is
  known about its data) and one [`Record`][] per data file. A vehicle whose
  model depends on the data (a spline scheduled over the record's Mach range,
  start values regressed from the log) builds it here;
- `simulate(...)`: a simulated flight log of the vehicle (its own simulator);
- `geometry()`: the reference area and length (m^2, m) of the vehicle: the
  reference area belongs to the vehicle, not to a log's metadata.

Adding a built-in vehicle is one entry class (in the vehicle's own module) and one
line in `_entries()`.
"""

import abc
import dataclasses
import pathlib
from collections.abc import Sequence

import equinox as eqx
from equinox import AbstractVar

from .._errors import LogError
from .._estimate._modelfile import load_model_file, ModelSpec
from .._log._format import FlightLog
from .._model import Record


class Simulation(eqx.Module):
    """A simulated flight asked of a vehicle (`AbstractVehicleEntry`'s
    `simulate`): `hidden` effects `NAME=VALUE` (SI units) planted, sensor noise
    (`noise`) and any random effect drawn from `seed`; `duration` (s) and
    `sample_rate` (Hz), `None` for the vehicle's own; `input` the excitation's
    name; `perturb` a Monte Carlo perturbation of the vehicle where it has one."""

    seed: int = 0
    hidden: tuple[str, ...] = ()
    duration: float | None = None
    sample_rate: float | None = None
    noise: bool = True
    input: str = "pulse"
    perturb: bool = False

    def timing(self, duration: float, sample_rate: float) -> tuple[float, float]:
        """`(duration, sample_rate)` asked for, each defaulting to the vehicle's own
        (s, Hz)."""
        return (
            duration if self.duration is None else self.duration,
            sample_rate if self.sample_rate is None else self.sample_rate,
        )


class AbstractVehicleEntry(eqx.Module):
    """What the command line needs of a vehicle (see the module).

    Tuning fields of a concrete entry (e.g. a spline's knots) are keyword
    arguments of [`vehicle_entry`][]; an entry without such a field refuses the
    option in one line.
    """

    description: AbstractVar[str]

    @abc.abstractmethod
    def problem(
        self,
        files: Sequence[pathlib.Path | str],
        *,
        columns=None,
        add: tuple[str, ...] = (),
        candidates: bool = False,
    ) -> tuple[ModelSpec, list[Record]]:
        """The model and one record per data file.

        **Arguments:** `files` (one manoeuvre each); `columns`: a user's column map
        (file or dict) over the entry's own; `add`: library effects estimated with
        the model; `candidates`: also compose every effect the vehicle supports,
        held at zero, listed in the spec's `candidates` (what `diagnose` tests).

        **Returns:** `(spec, records)`; errors in the data are one `LogError`.
        """

    def simulate(
        self,
        *,
        seed: int = 0,
        hidden: Sequence[str] = (),
        duration: float | None = None,
        sample_rate: float | None = None,
        noise: bool = True,
        input: str = "pulse",
        perturb: bool = False,
    ) -> FlightLog:
        """A simulated flight of the vehicle (the arguments are those of a
        `Simulation`) by its own simulator (`fly`); a request it cannot fly
        is one `LogError`."""
        request = Simulation(
            seed=seed,
            hidden=tuple(hidden),
            duration=duration,
            sample_rate=sample_rate,
            noise=noise,
            input=input,
            perturb=perturb,
        )
        try:
            return self.fly(request)
        except ValueError as e:
            raise LogError(str(e)) from None

    @abc.abstractmethod
    def fly(self, request: Simulation) -> FlightLog:
        """The flight `request` asks for; what the vehicle cannot fly raises
        `LogError` (or `ValueError`) with one line saying why."""

    @abc.abstractmethod
    def geometry(self) -> tuple[float, float] | None:
        """Reference area (m^2) and length (m), or `None` for a bare model."""


def records_of(
    spec: ModelSpec, files: Sequence[pathlib.Path | str], columns=None
) -> list[Record]:
    """One record per file through `spec`'s column map (updated by `columns`): the
    `problem` of an entry whose model does not depend on the data."""
    from ._records import load_records

    try:
        return load_records(spec, list(files), columns)
    except ValueError as e:
        raise LogError(str(e)) from None


def hold_candidates(spec: ModelSpec) -> ModelSpec:
    """`spec` with its candidates held (at their start values): a candidate is a
    term the diagnosis tests, so it is never estimated with the model."""
    missing = [c for c in spec.candidates if c not in spec.model.parameters]
    if missing:
        raise LogError(
            f"{spec.name}: candidates {missing} are not model parameters "
            f"({', '.join(spec.model.parameters)})"
        )
    fixed = tuple(dict.fromkeys(spec.model.fixed + spec.candidates))
    return dataclasses.replace(spec, model=spec.model.replace(fixed=fixed))


class AbstractModelEntry(AbstractVehicleEntry):
    """An entry whose model does not depend on the data: `spec(...)` builds it,
    and `problem` reads the files through its column map."""

    @abc.abstractmethod
    def spec(
        self, add: tuple[str, ...] = (), candidates: bool = False, manoeuvres: int = 1
    ) -> ModelSpec:
        """The model with the library effects `add` estimated (and every candidate
        held at zero when `candidates`); `manoeuvres`: how many logs are fitted
        together (a model with per-manoeuvre parameters needs it)."""

    def problem(self, files, *, columns=None, add=(), candidates=False):
        spec = self.spec(tuple(add), candidates, manoeuvres=len(files))
        return spec, records_of(spec, files, columns)


class ModelFileEntry(AbstractModelEntry):
    """A vehicle or model file (`FILE.py`, see [`load_model_file`][]): a bare
    `model`, or a `vehicle = dp.FlightVehicle(...)` with which library effects
    compose."""

    path: str
    description: str = "a vehicle or model file"

    def spec(self, add=(), candidates=False, manoeuvres=1) -> ModelSpec:
        del manoeuvres
        from .._vehicle._parts import (
            effect_parameter,
            PITCH_PLANE_EFFECTS,
            vehicle_model,
        )

        spec = load_model_file(self.path)
        if spec.vehicle is None:
            if add:
                raise LogError(
                    f"{self.path}: --add composes library effects with a vehicle "
                    "(`vehicle = dp.FlightVehicle(...)` in the file); with a bare "
                    "`model`, write the term into it (held terms to test go in "
                    "`candidates`)"
                )
            return hold_candidates(spec)
        unknown = [a for a in add if a not in PITCH_PLANE_EFFECTS]
        if unknown:
            raise LogError(
                f"effects {unknown} do not compose with {self.path}; it takes "
                f"{', '.join(PITCH_PLANE_EFFECTS)}"
            )
        effects = tuple(
            dict.fromkeys((PITCH_PLANE_EFFECTS if candidates else ()) + tuple(add))
        )
        spec = dataclasses.replace(
            spec,
            model=vehicle_model(spec.vehicle, effects=effects, free=add),
            candidates=spec.candidates
            + tuple(effect_parameter(e) for e in effects if e not in add),
        )
        return hold_candidates(spec)

    def fly(self, request):
        from ._simulate_file import simulate_model_file

        if request.perturb:
            raise LogError(
                f"{self.path}: --perturb needs a vehicle's Monte Carlo model"
            )
        return simulate_model_file(
            self.spec(add=tuple(h.partition("=")[0].strip() for h in request.hidden)),
            seed=request.seed,
            hidden=request.hidden,
            duration=request.duration,
            sample_rate=request.sample_rate,
            noise=request.noise,
            input=request.input,
        )

    def geometry(self):
        vehicle = load_model_file(self.path).vehicle
        if vehicle is None:
            return None
        return float(vehicle.geometry.s_ref), float(vehicle.geometry.c_ref)


def _entries() -> dict[str, type[AbstractVehicleEntry]]:
    from ._hfb320 import HFB320Entry, HFB320LateralEntry
    from ._pegasus import PegasusEntry

    # one line per built-in vehicle
    return {
        "pegasus": PegasusEntry,
        "hfb320": HFB320Entry,
        "hfb320-lateral": HFB320LateralEntry,
    }


def vehicle_entry(name_or_file: str, **tuning) -> AbstractVehicleEntry:
    """The entry of a built-in vehicle, or of a vehicle/model file (`FILE.py`).

    **Arguments:** `name_or_file`; `tuning`: values of the entry's tuning fields
    (`None` values are left at the entry's defaults); a field the entry does not
    have is one `LogError`.
    """
    tuning = {k: v for k, v in tuning.items() if v is not None}
    entries = _entries()
    if name_or_file in entries:
        cls = entries[name_or_file]
    elif name_or_file.endswith(".py") or pathlib.Path(name_or_file).is_file():
        cls = ModelFileEntry
        tuning = {"path": str(name_or_file), **tuning}
    else:
        raise LogError(
            f"unknown vehicle {name_or_file!r}; built in: {', '.join(entries)} "
            "(or give a model file, FILE.py)"
        )
    fields = {f.name for f in dataclasses.fields(cls)} - {"description"}
    unknown = sorted(k for k in tuning if k not in fields)
    if unknown:
        options = ", ".join("--" + k.replace("_", "-") for k in unknown)
        takes = sorted(fields - {"path"})
        raise LogError(
            f"{options} do(es) not apply to {name_or_file}"
            + (
                f" (it takes {', '.join('--' + k.replace('_', '-') for k in takes)})"
                if takes
                else ""
            )
        )
    return cls(**tuning)


def vehicle_descriptions() -> dict[str, str]:
    """Name -> one line, for `diffpegasus vehicles`."""
    return {name: cls().description for name, cls in _entries().items()}


def vehicle_spec(
    name_or_file: str,
    add: tuple[str, ...] = (),
    candidates: bool = False,
    manoeuvres: int = 1,
) -> ModelSpec:
    """The model of a vehicle whose model does not depend on the data (the
    HFB-320s, vehicle and model files), as its entry builds it; `manoeuvres`: how
    many logs are fitted together (`hfb320-lateral` gives each its own state
    biases)."""
    entry = vehicle_entry(name_or_file)
    if not isinstance(entry, AbstractModelEntry):
        raise LogError(
            f"{name_or_file}: its model is built from the data; use "
            "vehicle_entry(...).problem(files)"
        )
    return entry.spec(tuple(add), candidates, manoeuvres)
