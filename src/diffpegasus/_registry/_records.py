"""A model file's or vehicle's records from data files: one record per file through
the model's column map (updated by the user's), with the checks that catch data
that would give wrong numbers (one file twice, too little data, map keys that
name nothing)."""

import pathlib

import numpy as np

from .._errors import LogError
from .._estimate._modelfile import ModelSpec
from .._log._columns import load_columns, load_record
from .._model import Record


def load_records(spec: ModelSpec, files, columns=None):
    """One record per file, through the model's column map updated by `columns`
    (or the model file's `read` function when it has one and no `columns` given)."""
    _check_distinct(files)
    user = dict(load_columns(columns))
    where = f"{spec.name}: columns" if spec.name.endswith(".py") else spec.name
    own = dict(load_columns(spec.columns, where)) if spec.columns else {}
    if spec.name.endswith(".py") and spec.columns:
        _check_map_keys(spec.model, own, spec.name)
    _check_map_keys(spec.model, user, "--columns")
    cmap = own
    cmap.update(user)
    reader = spec.read if columns is None else None
    model = spec.model
    records = _load(spec, model, files, cmap, reader)
    _check_distinct_records(records, files)
    _check_enough_data(spec.model, records, files)
    # two files of one name (run1/data.csv, run2/data.csv) keep apart in reports
    names = [r.name for r in records]
    if len(set(names)) < len(names):
        records = [
            Record(r.t, r.inputs, r.measured, x0=r.x0, name=str(f))
            for r, f in zip(records, files, strict=True)
        ]
    return records


def _check_distinct(files) -> None:
    """One file given twice (two spellings of its path) would count its data twice
    and shrink every standard error by sqrt(2)."""
    import os

    seen = {}
    for f in files:
        try:
            key = os.path.realpath(f)
        except OSError:
            continue
        if key in seen:
            raise LogError(
                f"{f}: the same file as {seen[key]} (given twice); each record once, "
                "or its data count twice and the standard errors shrink by sqrt(2)"
            )
        seen[key] = f


def _check_distinct_records(records, files) -> None:
    """Two files holding the same numbers are one record given twice."""
    for i in range(len(records)):
        for j in range(i):
            a, b = records[i], records[j]
            if (
                a.t.shape == b.t.shape
                and np.array_equal(a.measured, b.measured)
                and np.array_equal(a.inputs, b.inputs)
            ):
                raise LogError(
                    f"{files[i]}: the same inputs and outputs as {files[j]} (a copy?); "
                    "each record once, or its data count twice and the standard "
                    "errors shrink by sqrt(2)"
                )


def _check_enough_data(model, records, files) -> None:
    """More measured values than unknowns (the free parameters and one noise
    variance per output), or the fit cannot tell them apart."""
    values = sum(r.measured.size for r in records)
    unknowns = int(np.sum(model.free)) + len(model.outputs)
    if values <= unknowns:
        raise LogError(
            f"{', '.join(map(str, files))}: {values} measured values for {unknowns} "
            f"unknowns ({int(np.sum(model.free))} free parameters and "
            f"{len(model.outputs)} output noise variances); a fit needs more data than "
            "unknowns: longer records"
        )


def _check_map_keys(model, cmap: dict, where: str) -> None:
    """A column-map key that is no channel of the model is a typo, not a no-op."""
    known = {"t", *model.states, *model.inputs, *model.outputs}
    unknown = sorted(k for k in cmap if k not in known)
    if unknown:
        raise LogError(
            f"{where}: column map names {', '.join(map(repr, unknown))}, not a "
            f"channel of the model (t, {', '.join(sorted(known - {'t'}))})"
        )


def _x0(spec: ModelSpec, path):
    """The model file's initial state for `path`: one for every record, or a dict
    by file name."""
    if not isinstance(spec.x0, dict):
        return spec.x0
    path = pathlib.Path(path)
    for key in (str(path), path.name, path.stem):
        if key in spec.x0:
            return spec.x0[key]
    return None


def _load(spec, model, files, cmap, reader):
    # inputs `manoeuvre_k` select per-manoeuvre parameters (e.g. the state biases
    # of `dp.lateral_model(manoeuvres=n)`): 1 on the k-th file, 0 on the others
    selectors = [n for n in model.inputs if n.startswith("manoeuvre_")]
    if not selectors:
        return [
            load_record(model, f, cmap, x0=_x0(spec, f), reader=reader) for f in files
        ]
    if len(selectors) != len(files):
        raise LogError(
            f"{spec.name} selects {len(selectors)} manoeuvres (inputs "
            f"{', '.join(selectors)}), but {len(files)} files were given"
        )
    base = model.replace(inputs=tuple(n for n in model.inputs if n not in selectors))
    records = []
    for k, f in enumerate(files):
        rec = load_record(base, f, cmap, x0=_x0(spec, f), reader=reader)
        inputs = np.column_stack(
            [
                rec.inputs[:, base.inputs.index(n)]
                if n in base.inputs
                else np.full(len(rec.t), float(n == selectors[k]))
                for n in model.inputs
            ]
        )
        records.append(Record(rec.t, inputs, rec.measured, x0=rec.x0, name=rec.name))
    return records
