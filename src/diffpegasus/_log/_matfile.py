"""MATLAB `.mat` (v5 and v7.3) and HDF5 files as tables of named columns.

Flight-test data most often arrive as MATLAB files: one vector per signal (`t`,
`alpha`, `q`, ...), or one matrix with a signal per column (as the textbook's
`.mat` data files), sometimes inside a struct. This module turns such a file into the
same table of 1-D columns that [`read_table`][diffpegasus._log._columns.read_table]
gives for a CSV file, so column maps, unit conversion and every plausibility check
apply unchanged. Column names:

- a vector `alpha` (N, 1 x N or N x 1) is the column `"alpha"`;
- a matrix `data` with samples in rows (N x k) gives the columns `"data[1]"` ...
  `"data[k]"`, numbered from 1 as MATLAB counts; when the file holds nothing but that
  one matrix its columns are also `"1"` ... `"k"`, as for a bare numeric text table;
- a struct field (`flight.alpha`) or, in a plain HDF5 file, a dataset inside a group
  (`flight/alpha`) is named by its path.

Version 5 files (MATLAB's default up to `-v7`) are read by `scipy.io.loadmat`,
version 7.3 files (HDF5 underneath) and plain HDF5 files (`.h5`, `.hdf5`) by `h5py`;
a v7.3 file's arrays are transposed back to MATLAB's orientation.

The signals of a record share one length: the most common length among the file's
signals (the longer on a tie). A variable of another length, a scalar, text or a cell
array is not a column; naming one in a column map is one error line saying what it is.
"""

import collections
import pathlib

import numpy as np

from .._errors import LogError


SUFFIXES = (".mat", ".h5", ".hdf5", ".he5")


class MatrixTable(dict):
    """Columns by name (1-D float arrays of one length), plus the variables of the
    file that are not columns and why, so that a column map naming one gets a reason
    instead of "no such column"."""

    def __init__(self, path: pathlib.Path, columns: dict, not_columns: dict):
        super().__init__(columns)
        self.path = path
        self.not_columns = not_columns

    def __contains__(self, name) -> bool:
        if name in self.not_columns and not dict.__contains__(self, name):
            raise LogError(f"{self.path}: variable {name!r} {self.not_columns[name]}")
        return dict.__contains__(self, name)


def read_matrix_file(path) -> MatrixTable:
    """The numeric signals of a `.mat` (v5 or v7.3) or HDF5 file as columns.

    **Arguments:**

    - `path`: the file.

    **Returns:** a table from column name to a 1-D float64 array, every array of the
    record's length.

    **Raises:** [`LogError`][diffpegasus._log._format.LogError] with one line when
    the file cannot be read or holds no signal.
    """
    path = pathlib.Path(path)
    if not path.is_file():
        raise LogError(
            f"{path}: no such file" if not path.exists() else f"{path}: not a file"
        )
    import h5py

    try:
        hdf5 = h5py.is_hdf5(path)
    except OSError as e:
        raise LogError(f"{path}: cannot read the file ({e})") from None
    if hdf5:
        variables = _hdf5_variables(path, matlab=path.suffix.lower() == ".mat")
    elif path.suffix.lower() == ".mat":
        variables = _mat5_variables(path)
    else:
        raise LogError(f"{path}: not an HDF5 file")
    return _table(path, variables)


def _mat5_variables(path: pathlib.Path) -> dict:
    import scipy.io

    try:
        raw = scipy.io.loadmat(path, simplify_cells=True)
    except Exception as e:  # scipy's parser fails in many ways on a foreign file
        reason = f" ({type(e).__name__}: {e})" if str(e) else ""
        raise LogError(f"{path}: not a readable MATLAB .mat file{reason}") from None
    out = {}

    def walk(prefix, value):
        if isinstance(value, dict):
            for k, v in value.items():
                walk(f"{prefix}.{k}" if prefix else k, v)
        else:
            out[prefix] = value

    walk("", {k: v for k, v in raw.items() if not k.startswith("__")})
    return out


class NotNumeric(str):
    """An HDF5 dataset that holds no numbers: its MATLAB class or dtype."""


def _hdf5_variables(path: pathlib.Path, matlab: bool) -> dict:
    import h5py

    out = {}
    sep = "." if matlab else "/"
    try:
        with h5py.File(path, "r") as f:

            def visit(name, obj):
                if not isinstance(obj, h5py.Dataset):
                    return
                if matlab and name.startswith("#refs#"):
                    return
                key = name.replace("/", sep)
                cls = obj.attrs.get("MATLAB_class", b"")
                cls = cls.decode() if isinstance(cls, bytes) else str(cls)
                if cls in ("char", "cell") or obj.dtype.kind not in "biuf":
                    text = cls == "char" or obj.dtype.kind in "SUO"
                    out[key] = NotNumeric("text" if text else cls or str(obj.dtype))
                    return
                value = obj[()]
                # MATLAB writes column-major: an N x k matrix is stored k x N
                out[key] = np.transpose(value) if matlab else value

            f.visititems(visit)
    except OSError as e:
        raise LogError(f"{path}: cannot read the HDF5 file ({e})") from None
    return out


def _table(path: pathlib.Path, variables: dict) -> MatrixTable:
    signals: dict[str, np.ndarray] = {}  # name -> (N,) or (N, k)
    not_columns: dict[str, str] = {}
    for name, value in variables.items():
        if isinstance(value, NotNumeric) and value != "text":
            # complex numbers (a compound type), a cell array
            not_columns[name] = f"is not a numeric array (it holds {value})"
            continue
        if isinstance(value, str):
            not_columns[name] = "is text, not a signal"
            continue
        try:
            a = np.asarray(value)
        except Exception:  # a cell array of mixed things
            not_columns[name] = "is not a numeric array"
            continue
        if a.dtype.kind not in "biuf" or a.dtype == object:
            not_columns[name] = f"is not a numeric array (it holds {a.dtype})"
            continue
        a = a.astype(float)
        if a.ndim == 2 and 1 in a.shape:
            a = a.reshape(-1)
        if a.ndim == 0 or a.size == 1:
            not_columns[name] = (
                f"is a single number ({a.reshape(-1)[0]:g}), not a signal"
            )
        elif a.ndim > 2:
            not_columns[name] = (
                f"has {a.ndim} dimensions {a.shape}; a signal is a vector"
            )
        else:
            signals[name] = a
    if not signals:
        raise LogError(
            f"{path}: no numeric signal in the file (variables: "
            f"{', '.join(variables) or 'none'})"
        )
    lengths = collections.Counter(len(a) for a in signals.values())
    n = max(lengths, key=lambda k: (lengths[k], k))
    columns: dict[str, np.ndarray] = {}
    for name, a in signals.items():
        if len(a) != n:
            not_columns[name] = (
                f"has {len(a)} samples, the record's other signals {n} "
                "(samples in rows: one signal per column)"
                if a.ndim == 2
                else f"has {len(a)} samples, the record's other signals {n}"
            )
        elif a.ndim == 1:
            columns[name] = a
        else:
            for k in range(a.shape[1]):
                columns[f"{name}[{k + 1}]"] = a[:, k]
    matrices = [name for name, a in signals.items() if a.ndim == 2 and len(a) == n]
    if len(signals) == 1 and len(matrices) == 1:
        for k in range(signals[matrices[0]].shape[1]):
            columns[str(k + 1)] = columns[f"{matrices[0]}[{k + 1}]"]
    return MatrixTable(path, columns, not_columns)


class MatrixFileTable:
    """A `.mat` or HDF5 file with the interface of a text table's layout
    (`path`, `names`, `listing()`, `read(columns)`), so column maps read it with the
    same resolution, unit and plausibility checks as a CSV file."""

    kind = "matrix"
    numbered = False

    def __init__(self, path: pathlib.Path, data: MatrixTable):
        self.path = path
        # variables that are no column are listed too: asked for, they say why
        self.names = (
            *data,
            *(n for n in data.not_columns if not dict.__contains__(data, n)),
        )
        self._data = data

    @classmethod
    def open(cls, path) -> "MatrixFileTable":
        path = pathlib.Path(path)
        return cls(path, read_matrix_file(path))

    def listing(self) -> str:
        return ", ".join(self.names)

    def read(self, columns=None) -> dict[str, np.ndarray]:
        """The named columns (default: every column) as float64 arrays."""
        if columns is None:
            return {n: self._data[n] for n in self._data}
        out = {}
        for name in dict.fromkeys(columns):
            if name not in self._data:  # a variable that is no column says why
                raise LogError(f"{self.path}: no variable {name!r}")
            out[name] = self._data[name]
        return out
