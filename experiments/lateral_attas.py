"""Jategaonkar's ATTAS lateral-directional test cases with the public interface.

Test case 1 (one manoeuvre, 22 parameters: 15 derivatives, 2 state biases, 5 output
biases, x0 = 0) and test case 34 (several manoeuvres: per-manoeuvre state biases,
shared output biases) of FVSysID's chapter 4, on the book's flight records
(`fAttasAilRud1.asc`, `fAttasAilRud2.asc`, not shipped here: plain numeric columns,
no header, 0.04 s step). Columns as the book reads them (1-based, degrees where
angular): pdot 17, rdot 19, ay 3 (m/s^2), p 7, r 9; aileron (col 29 - col 28) / 2,
rudder 30, sideslip 14.

Run: `python experiments/lateral_attas.py FILE [FILE ...]`; the last stdout line is
one JSON object (estimates, standard errors, det R, iterations).
"""

import argparse
import json

import numpy as np

import diffpegasus as dp


DT = 0.04  # s


def load(path):
    """`(t, inputs (N, 3), measured (N, 5))` of one book record, radians."""
    data = np.loadtxt(path)
    d2r = np.pi / 180
    col = lambda k: data[:, k - 1]  # noqa: E731 (the book counts from 1)
    measured = np.column_stack(
        [col(17) * d2r, col(19) * d2r, col(3), col(7) * d2r, col(9) * d2r]
    )
    inputs = np.column_stack(
        [(col(29) - col(28)) * 0.5 * d2r, col(30) * d2r, col(14) * d2r]
    )
    return DT * np.arange(len(data)), inputs, measured


def fit_attas(paths):
    """Fit the book's linear model to one record (test case 1) or several (test
    case 34) from the book's start values."""
    model = dp.lateral_model(manoeuvres=len(paths))
    records = [
        dp.lateral_record(model, *load(p), manoeuvre=k + 1, name=str(p))
        for k, p in enumerate(paths)
    ]
    return dp.fit(model, records)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+")
    args = ap.parse_args()
    fit = fit_attas(args.files)
    # the Cramer-Rao bound (what the book prints) and the standard error corrected
    # for coloured residuals
    print(f"{'parameter':>10} {'estimate':>12} {'CRB':>10} {'corrected':>10}")
    for row in fit.table():
        print(
            f"{row['parameter']:>10} {row['estimate']:12.6g} "
            f"{row['stderr_crb']:10.3g} {row['stderr']:10.3g}"
        )
    print(
        f"det R {fit.cost:.6e}, {fit.iterations} iterations, converged {fit.converged}"
    )
    print(f"correlated above 0.9: {fit.high_correlations()}")
    print(
        json.dumps(
            dict(
                estimates=fit.estimates(),
                stderr=dict(
                    zip(fit.model.parameters, fit.stderr.tolist(), strict=True)
                ),
                det_R=fit.cost,
                iterations=fit.iterations,
                converged=fit.converged,
            )
        )
    )


if __name__ == "__main__":
    main()
