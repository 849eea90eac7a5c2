"""MATLAB `.mat` (v5, v7.3) and HDF5 files read through column maps give the records
the same numbers written as CSV give, with the same checks and one-line errors.

The reference is the CSV reader: every file here holds the same short-period
manoeuvre, written by scipy.io.savemat (v5) or h5py (v7.3's layout: HDF5 with a
512-byte user block, `MATLAB_class` attributes, arrays stored column-major), and the
record read from it must equal the CSV's to the last bit.
"""

import numpy as np
import pytest
import scipy.io
from typer.testing import CliRunner

import diffpegasus as dp
from diffpegasus._cli import app


h5py = pytest.importorskip("h5py")
runner = CliRunner()

MODEL = dp.Model(
    states=("w", "q"),
    inputs=("de",),
    outputs=("az", "w", "q"),
    parameters={"Zw": -1.2, "Mq": -2.5},
    rates=lambda t, x, u, p: x,
    observe=lambda t, x, u, p: x,
)
MAP = {
    "t": "T",
    "de": {"column": "DE", "unit": "deg"},
    "az": {"column": "AZ", "unit": "g", "scale": -1},
    "w": "W",
    "q": {"column": "Q", "unit": "deg/s"},
}


def _signals(n=120):
    t = np.arange(n) * 0.05
    rng = np.random.default_rng(0)
    return {
        "T": t,
        "DE": 2.0 * np.sin(1.3 * t),  # deg
        "AZ": 0.1 * np.cos(0.7 * t) + 1e-3 * rng.standard_normal(n),  # g, up
        "W": 0.5 * np.sin(0.9 * t),  # m/s
        "Q": 3.0 * np.cos(1.1 * t),  # deg/s
    }


def _csv(path, s):
    names = list(s)
    rows = [",".join(names)]
    rows += [",".join(repr(float(s[k][i])) for k in names) for i in range(len(s["T"]))]
    path.write_text("\n".join(rows) + "\n")
    return path


def _mat73(path, variables):
    """A file in MATLAB's -v7.3 layout (HDF5 with a 512-byte user block; arrays
    stored transposed, as MATLAB's column-major order appears to HDF5)."""
    with h5py.File(path, "w", userblock_size=512) as f:
        for name, value in variables.items():
            parts = name.split(".")
            group = f
            for p in parts[:-1]:
                group = group.require_group(p)
                group.attrs["MATLAB_class"] = np.bytes_("struct")
            if isinstance(value, str):
                d = group.create_dataset(
                    parts[-1],
                    data=np.frombuffer(value.encode(), np.uint8)[None, :].T.astype(
                        np.uint16
                    ),
                )
                d.attrs["MATLAB_class"] = np.bytes_("char")
            else:
                a = np.atleast_2d(np.asarray(value, float))
                if a.shape[0] == 1:
                    a = a.T  # a MATLAB column vector, N x 1
                d = group.create_dataset(parts[-1], data=a.T)
                d.attrs["MATLAB_class"] = np.bytes_("double")
    with open(path, "r+b") as f:
        f.write(b"MATLAB 7.3 MAT-file, written to test diffpegasus".ljust(116))
    return path


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    s = _signals()
    return s, dp.load_record(
        MODEL, _csv(tmp_path_factory.mktemp("csv") / "m.csv", s), MAP
    )


def _same(record, reference):
    np.testing.assert_array_equal(record.t, reference.t)
    np.testing.assert_array_equal(record.inputs, reference.inputs)
    np.testing.assert_array_equal(record.measured, reference.measured)
    np.testing.assert_array_equal(record.x0, reference.x0)


def test_mat_v5_vectors_and_struct(tmp_path, reference):
    s, ref = reference
    scipy.io.savemat(tmp_path / "a.mat", s | {"note": "flight 12", "rate": 20.0})
    _same(dp.load_record(MODEL, tmp_path / "a.mat", MAP), ref)
    # row vectors (MATLAB's 1 x N) and a struct `flight.T`, ...
    scipy.io.savemat(
        tmp_path / "b.mat", {"flight": {k: v[None, :] for k, v in s.items()}}
    )
    mapped = {k: (v if isinstance(v, dict) else {"column": v}) for k, v in MAP.items()}
    mapped = {k: v | {"column": "flight." + v["column"]} for k, v in mapped.items()}
    _same(dp.load_record(MODEL, tmp_path / "b.mat", mapped), ref)


def test_mat_v5_one_matrix_by_column_number(tmp_path, reference):
    s, ref = reference
    scipy.io.savemat(tmp_path / "c.mat", {"data": np.column_stack(list(s.values()))})
    numbered = {
        "t": 1,
        "de": {"column": 2, "unit": "deg"},
        "az": {"column": 3, "unit": "g", "scale": -1},
        "w": 4,
        "q": {"column": 5, "unit": "deg/s"},
    }
    _same(dp.load_record(MODEL, tmp_path / "c.mat", numbered), ref)
    named = {
        k: (
            v | {"column": f"data[{v['column']}]"}
            if isinstance(v, dict)
            else f"data[{v}]"
        )
        for k, v in numbered.items()
    }
    _same(dp.load_record(MODEL, tmp_path / "c.mat", named), ref)


def test_mat_v73_and_hdf5(tmp_path, reference):
    s, ref = reference
    path = _mat73(tmp_path / "d.mat", s | {"pilot": "ab"})
    assert h5py.is_hdf5(path)
    _same(dp.load_record(MODEL, path, MAP), ref)
    path = _mat73(tmp_path / "e.mat", {"data": np.column_stack(list(s.values()))})
    numbered = {
        "t": 1,
        "de": {"column": 2, "unit": "deg"},
        "az": {"column": 3, "unit": "g", "scale": -1},
        "w": 4,
        "q": {"column": 5, "unit": "deg/s"},
    }
    _same(dp.load_record(MODEL, path, numbered), ref)
    with h5py.File(tmp_path / "f.h5", "w") as f:
        for k, v in s.items():
            f.create_dataset(f"run1/{k}", data=v)
    slashed = {
        k: (
            v | {"column": "run1/" + v["column"]}
            if isinstance(v, dict)
            else "run1/" + v
        )
        for k, v in MAP.items()
    }
    _same(dp.load_record(MODEL, tmp_path / "f.h5", slashed), ref)


@pytest.mark.parametrize(
    "make, columns, fragment",
    [
        # the same unit mistake the CSV path catches: de in degrees, no unit given
        (lambda s: s | {"DE": 20 * s["DE"]}, {**MAP, "de": "DE"}, "column 'DE'"),
        (
            lambda s: s | {"W": np.where(np.arange(len(s["W"])) == 7, np.nan, s["W"])},
            MAP,
            "row 8",
        ),
        (
            lambda s: s | {"Q": s["Q"][:50]},
            MAP,
            "variable 'Q' has 50 samples, the record's other signals 120",
        ),
        (lambda s: s | {"Q": 3.0}, MAP, "variable 'Q' is a single number"),
        (
            lambda s: {k: v for k, v in s.items() if k != "Q"},
            MAP,
            "no column 'Q' for channel 'q'",
        ),
    ],
)
def test_mat_errors_are_one_line(tmp_path, make, columns, fragment):
    path = tmp_path / "bad.mat"
    scipy.io.savemat(path, make(_signals()))
    with pytest.raises(dp.LogError, match=".*") as e:
        dp.load_record(MODEL, path, columns)
    message = str(e.value)
    assert fragment in message and "\n" not in message and str(path) in message


def test_not_a_mat_file_through_the_command_line(tmp_path):
    bad = tmp_path / "notes.mat"
    bad.write_text("these are my notes, not a MATLAB file\n")
    model = tmp_path / "m.py"
    model.write_text(
        "import diffpegasus as dp\n"
        "model = dp.Model(states=('w',), inputs=('de',), outputs=('w',),\n"
        "    parameters={'a': -1.0}, rates=lambda t, x, u, p: p['a'] * x,\n"
        "    observe=lambda t, x, u, p: x)\n"
    )
    out = runner.invoke(app, ["fit", str(bad), "--model", str(model)])
    assert out.exit_code == 2, out.output
    lines = [s for s in out.output.splitlines() if s.strip()]
    assert (
        lines[-1].startswith("error: ")
        and "not a readable MATLAB .mat file" in lines[-1]
    )
    assert "Traceback" not in out.output


def test_hdf5_complex_numbers_are_not_called_text(tmp_path):
    """A complex dataset (h5py's compound type) mapped as a column: before, `is
    text, not a signal`."""
    import h5py

    path = tmp_path / "x.h5"
    with h5py.File(path, "w") as f:
        f["t"] = np.arange(10.0)
        f["QC"] = np.ones(10) * (1 + 2j)
        f["TXT"] = np.array([b"a"] * 10)
    from diffpegasus._log._matfile import read_matrix_file

    table = read_matrix_file(path)
    with pytest.raises(dp.LogError, match="'QC' is not a numeric array .*complex128"):
        assert "QC" in table
    with pytest.raises(dp.LogError, match="'TXT' is text, not a signal"):
        assert "TXT" in table
