"""What the experiments and the tests share: where the validation data of
`shared/data/` lives (the repository is checked out beside a `shared/` folder;
`DIFFPEGASUS_SHARED`, the path of that folder, overrides the search), and the
simulated flights both use.
"""

import os
import pathlib

import numpy as np
import scipy.linalg
import scipy.signal


def shared_data(relative: str) -> pathlib.Path:
    """Path of `shared/data/<relative>`; the first candidate that exists, else the
    conventional location (so the error message names it)."""
    here = pathlib.Path(__file__).resolve()
    candidates = []
    if os.environ.get("DIFFPEGASUS_SHARED"):
        candidates.append(
            pathlib.Path(os.environ["DIFFPEGASUS_SHARED"]) / "data" / relative
        )
    candidates += [p / "shared" / "data" / relative for p in here.parents]
    for c in candidates:
        if c.exists():
            return c
    return here.parents[2] / "shared" / "data" / relative


# ATTAS-like lateral manoeuvres: the book's derivatives (1/s, 1/rad), simulated
# independently of the package (matrix exponential, inputs linear between samples)
ATTAS = dict(
    Lp=-2.5, Lr=0.6, Lda=-8.0, Ldr=0.6, Lbeta=-6.0,
    Np=-0.1, Nr=-0.4, Nda=-0.3, Ndr=-2.0, Nbeta=2.2,
    Yp=0.4, Yr=1.5, Yda=-0.5, Ydr=4.0, Ybeta=-20.0,
)  # fmt: skip
ATTAS_NOISE = np.array([0.02, 0.01, 0.05, 0.002, 0.002])  # pdot, rdot, ay, p, r


def attas_like(seed=3, duration=25.0, rate=25.0):
    """Aileron and rudder doublets; the sideslip a first-order (1.2 s) response to
    the rudder; outputs pdot, rdot, ay, p, r with white noise ([`ATTAS_NOISE`][]).

    **Returns:** `t` `(n,)` s, inputs `(n, 3)` (aileron, rudder, sideslip; rad),
    outputs `(n, 5)`.
    """
    dt = 1.0 / rate
    t = np.arange(0.0, duration + 0.5 * dt, dt)

    def doublet(start, width, amp):
        return amp * (((t >= start) & (t < start + width)) * 1.0
                      - ((t >= start + width) & (t < start + 2 * width)))  # fmt: skip

    da = doublet(1.0, 1.0, 0.03) + doublet(12.0, 0.6, -0.02)
    dr = doublet(5.0, 1.5, 0.03) + doublet(17.0, 0.8, 0.02)
    beta = scipy.signal.lfilter([dt / 1.2], [1, dt / 1.2 - 1], -0.5 * dr)
    u = np.column_stack([da, dr, beta])
    p = ATTAS
    a = np.array([[p["Lp"], p["Lr"]], [p["Np"], p["Nr"]]])
    b = np.array([[p["Lda"], p["Ldr"], p["Lbeta"]], [p["Nda"], p["Ndr"], p["Nbeta"]]])
    f = np.zeros((8, 8))
    f[:2, :2], f[:2, 2:5], f[2:5, 5:8] = a, b, np.eye(3)
    e = scipy.linalg.expm(f * dt)
    phi, g1, g2 = e[:2, :2], e[:2, 2:5], e[:2, 5:8] / dt
    x = np.zeros((len(t), 2))
    for k in range(len(t) - 1):
        x[k + 1] = phi @ x[k] + (g1 - g2) @ u[k] + g2 @ u[k + 1]
    c = np.array([[p["Yp"], p["Yr"]]])
    dy = np.array([[p["Yda"], p["Ydr"], p["Ybeta"]]])
    y = np.column_stack([x @ a.T + u @ b.T, x @ c.T + u @ dy.T, x])
    y = y + np.random.default_rng(seed).normal(size=y.shape) * ATTAS_NOISE
    return t, u, y


def segment_projection(n: int, outputs: int, segments: int = 10):
    """A linear problem shaped like a multiple-shooting fit's free unknowns: a
    constant and a slope on each of `segments` equal segments of each output, over
    `n` samples. Returns `(t, basis, refit)`: `t` `(n,)` on [0, 1]; `basis` `(n,
    outputs, unknowns)` orthonormal (as a score test's refit operator); `refit(v)`
    the residual `(n, outputs)` a least-squares fit of those unknowns leaves of
    `v`."""
    t = np.linspace(0.0, 1.0, n)
    cols = []
    for c in range(outputs):
        for s in range(segments):
            sel = (t >= s / segments) & (t < (s + 1) / segments + (s == segments - 1))
            for f in (np.ones(n), t - (s + 0.5) / segments):
                x = np.zeros((n, outputs))
                x[sel, c] = f[sel]
                cols.append(x)
    q, _ = np.linalg.qr(np.stack(cols, -1).reshape(n * outputs, -1))

    def refit(v):
        return v - (q @ (q.T @ v.reshape(-1))).reshape(n, outputs)

    return t, q.reshape(n, outputs, -1), refit
