"""HFB-320 real flight record: filter error against output error.

The book's filter-error case (Jategaonkar, 2nd ed., ch. 5, test case 4): outputs V,
alpha, theta, q, qdot, ax, az; inputs de, thrust; process noise on the four state
equations. Prints both methods' estimates, the Ljung-Box whiteness of each output's
residuals (innovations for filter error), and the comparison with the values of
FVSysID's files for this record: the start values (SPEC section 7), and the
filter-error estimates, F and R that FVSysID's chapter-7 definition file for the
same record quotes "from ml_fem for test_case=4".

Run: `python experiments/hfb320_fem.py` (about 3 minutes, mostly compilation).
"""

import time

import numpy as np
import scipy.stats as st

import diffpegasus as dp
from diffpegasus._estimate._filter_error import fit_filter_error
from diffpegasus._estimate._fit import fit
from diffpegasus._estimate._model import Record
from diffpegasus._vehicle._hfb320 import BOOK_FEM, hfb320_model, START, X0


DATA = "/work/shared/data/hfb320/hfb320_1_10.asc"
OUTPUTS = ("V", "alpha", "theta", "q", "qdot", "ax", "az")
BOOK_F = (0.358553, 2.42099e-3, 4.47607e-4, 1.73778e-3)
BOOK_R = (
    0.01758668956825,
    0.00000099020743,
    0.00000019774013,
    0.00000033836151,
    0.00003168412236,
    0.00041909760875,
    0.02020310372280,
)


def ljung_box(e, lags=20):
    """Ljung-Box Q over `lags` lags of a residual series and its p-value."""
    e = e - e.mean()
    n = len(e)
    acf = np.array([np.sum(e[k:] * e[: n - k]) for k in range(lags + 1)]) / np.sum(
        e * e
    )
    q = n * (n + 2) * np.sum(acf[1:] ** 2 / (n - np.arange(1, lags + 1)))
    return q, st.chi2.sf(q, lags)


def main():
    d = dp.read_asc(DATA)
    rec = Record(
        d["T"],
        np.column_stack([d["DELV"], d["THRUST"]]),
        np.column_stack(
            [d[c] for c in ("TASCG", "ALFCG", "THE", "Q", "QDOT", "AXCG", "AZCG")]
        ),
        x0=X0,
        name="hfb320_1_10",
    )
    model = hfb320_model()
    noise = {"V": 0.02, "alpha": 0.002, "theta": 0.02, "q": 0.02}  # FVSysID's starts
    fits = {}
    for label, call in (
        ("OEM", lambda: fit(model, rec)),
        ("FEM", lambda: fit_filter_error(model, rec, process_noise=noise)),
        (
            "FEM diag R",
            lambda: fit_filter_error(model, rec, process_noise=noise, full_R=False),
        ),
    ):
        t0 = time.perf_counter()
        fits[label] = call()
        t1 = time.perf_counter()
        call()
        t2 = time.perf_counter()
        f = fits[label]
        print(
            f"{label}: det R {f.cost:.6e}, {f.iterations} iterations, first call "
            f"{t1 - t0:.1f} s, second {t2 - t1:.2f} s"
            + (
                f", constraint active {f.constraint_active}, diag(KC) {np.round(f.kc[0], 4)}"
                if label != "OEM"
                else ""
            )
        )
    oem, fem, femd = fits["OEM"], fits["FEM"], fits["FEM diag R"]

    print(
        "\n| parameter | start (SPEC 7) | OEM | FEM (full R) | FEM (diag R) | FVSysID ml_fem |"
    )
    print("|---|---|---|---|---|---|")
    for i, name in enumerate(model.parameters):
        print(
            f"| {name} | {START[name]:.5g} | {oem.params[i]:.5g} ± {oem.stderr[i]:.2g} "
            f"| {fem.params[i]:.5g} ± {fem.stderr[i]:.2g} "
            f"| {femd.params[i]:.5g} ± {femd.stderr[i]:.2g} | {BOOK_FEM[name]:.5g} |"
        )
    for j, s in enumerate(fem.process_noise):
        print(
            f"| F[{s}] | {noise[s]:.3g} | - | {fem.F[j]:.4g} ± {fem.F_stderr[j]:.2g} "
            f"| {femd.F[j]:.4g} ± {femd.F_stderr[j]:.2g} | {BOOK_F[j]:.4g} |"
        )

    print(
        "\n| output | R OEM | R FEM full (diag) | R FEM diag | FVSysID R | LB Q OEM | LB Q FEM full | LB Q FEM diag |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for k, name in enumerate(OUTPUTS):
        q_o, _ = ljung_box(rec.measured[:, k] - oem.outputs[0][:, k])
        q_f, _ = ljung_box(fem.innovations[0][:, k])
        q_d, _ = ljung_box(femd.innovations[0][:, k])
        print(
            f"| {name} | {oem.R[k]:.3e} | {np.diag(fem.R)[k]:.3e} | {np.diag(femd.R)[k]:.3e} "
            f"| {BOOK_R[k]:.3e} | {q_o:.0f} | {q_f:.0f} | {q_d:.0f} |"
        )
    print(f"\nLjung-Box over 20 lags: 5% critical value {st.chi2.ppf(0.95, 20):.1f}")

    def distance(params, ref):
        ref = np.array([ref[n] for n in model.parameters])
        return np.max(np.abs(params - ref) / fem.stderr)

    print(
        "largest |difference| in FEM standard errors: start values vs OEM "
        f"{distance(oem.params, START):.0f}, start vs FEM {distance(fem.params, START):.0f}, "
        f"FVSysID FEM vs our FEM (diag R) {distance(femd.params, BOOK_FEM):.2f}, "
        f"(full R) {distance(fem.params, BOOK_FEM):.2f}"
    )


if __name__ == "__main__":
    main()
