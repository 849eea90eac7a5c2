"""Do the recursive estimators' 95% bands cover the truth 95% of the time?

A Monte Carlo of simulated short-period flights (w, q; elevator; outputs az, w, q; a
model file linear in its parameters): the same doublet-and-multistep input, new
sensor noise per flight, white on w and q and coloured (first-order, 0.3 s
correlation time) on az, so that the equation errors are coloured as in flight. Each
flight is replayed through recursive least squares and the recursive Fourier
transform (one compiled `lax.scan`, mapped over the flights), and the fraction
of flights whose band contains the true value is counted per parameter, at several
times, for the plain (white-residual) and the corrected bounds. The flights are
simulated exactly (matrix exponential, inputs linear between samples) in NumPy,
independently of the package.

Run: `python experiments/recursive_coverage.py [--flights 200] [--out DIR]`; the
last stdout line is the JSON summary (also written to DIR/coverage.json).
"""

import argparse
import json
import os
import pathlib
import time
import types


# Why the vmapped replays stalled in XLA's CPU runtime (every thread waiting, 0 CPU;
# native stacks by gdb): the batched LU kernel of `jnp.linalg.solve` under `vmap`
# splits its batch over XLA's intra-op thread pool (`jax::ParallelBatchMap`) and
# waits for the pieces *on a thread of that same pool*. With the chunks dispatched
# asynchronously, two replays ran at once, each holding one of the pool's two
# threads (two cores) inside such a wait: nothing was left to run the pieces. Two
# such kernels run at once even within one program (XLA runs independent
# operations concurrently), so running the chunks one at a time was not enough.
# The flights are therefore replayed by `lax.map` (one flight after another in
# one program: unbatched solves, no batch split over the pool), each chunk run to
# completion before the next and saved to disk (`--out`/chunks): a run stopped
# for any reason resumes where it stopped.
os.environ.setdefault(
    "XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
)

import jax  # noqa: E402
import jax.numpy as jnp
import numpy as np
import scipy.linalg
import scipy.stats

import diffpegasus as dp
from diffpegasus._estimate import _recursive as rc


jax.config.update("jax_enable_x64", True)

U0, ZQ = 45.0, -1.5
TRUE = {"Zw": -1.2, "Zde": -4.0, "Mw": -0.06, "Mq": -2.5, "Mde": -15.0}
NOISE = {"az": 0.05, "w": 0.02, "q": 0.002}  # 1 sigma, SI units
UNSTABLE_U0, UNSTABLE_ZQ = 44.5695, -1.4768
UNSTABLE = {
    "Zw": -1.22871,
    "Zde": -4.20491,
    "Mw": 0.116197,
    "Mq": -2.7067,
    "Mde": -18.7718,
}
COLOUR_TIME = 0.3  # s, correlation time of the az noise
BAND = 1.5  # Hz: the upper end of the recursive Fourier transform's frequencies
RLS_BAND = 2.0  # Hz: least squares' low-pass of the state equations
CHUNK = 25  # flights per compiled batch


def make_model(true, u0=U0, zq=ZQ):
    """The model file (trim speed `u0`, `zq` the pitch rate's share of `az`),
    started at half the true values."""

    def rates(t, x, u, p):
        w, q = x
        return jnp.stack(
            [
                p["Zw"] * w + (u0 + zq) * q + p["Zde"] * u[0],
                p["Mw"] * w + p["Mq"] * q + p["Mde"] * u[0],
            ]
        )

    def observe(t, x, u, p):
        w, q = x
        return jnp.stack([p["Zw"] * w + zq * q + p["Zde"] * u[0], w, q])

    return dp.Model(
        states=("w", "q"),
        inputs=("de",),
        outputs=("az", "w", "q"),
        parameters={k: 0.5 * v for k, v in true.items()},
        rates=rates,
        observe=observe,
    )


MODEL = make_model(TRUE)
# the aircraft of `--aircraft`: trim speed, `zq`, the true derivatives
AIRCRAFT = {
    "short-period": (U0, ZQ, TRUE),
    # examples/unstable_aircraft.py: a set the bounds were not tuned on
    "unstable": (UNSTABLE_U0, UNSTABLE_ZQ, UNSTABLE),
}


def input_signal(t):
    """A doublet, then a 3-2-1-1 repeated with alternating sign (rad)."""
    de = np.where((t > 1.0) & (t < 2.0), 0.02, 0.0) - np.where(
        (t >= 2.0) & (t < 3.0), 0.02, 0.0
    )
    unit = 0.4
    for start, sign in ((5.0, 1), (12.0, -1), (19.0, 1), (26.0, -1)):
        s = t - start
        de = de + sign * 0.015 * (
            ((s >= 0) & (s < 3 * unit)) * 1.0
            - ((s >= 3 * unit) & (s < 5 * unit))
            + ((s >= 5 * unit) & (s < 6 * unit))
            - ((s >= 6 * unit) & (s < 7 * unit))
        )
    return de


def _ar1(rng, shape, rho, sigma):
    """First-order autoregressive noise along the last axis, stationary,
    standard deviation `sigma`."""
    e = rng.normal(size=shape) * sigma
    e[..., 1:] *= np.sqrt(1 - rho**2)
    for k in range(1, shape[-1]):
        e[..., k] += rho * e[..., k - 1]
    return e


def simulate(
    n_flights,
    duration,
    rate,
    seed,
    scale=1.0,
    sensor_time=0.0,
    true=TRUE,
    u0=U0,
    zq=ZQ,
):
    """Noise-free states exactly (matrix exponential with inputs linear between
    samples), then per-flight noise (with `sensor_time` > 0 s, the w and q
    sensors' noise first-order coloured with that correlation time instead of
    white); the aircraft `true`, `u0`, `zq` (the short-period one by default)."""
    dt = 1.0 / rate
    t = np.arange(0.0, duration + 0.5 * dt, dt)
    de = input_signal(t)
    a = np.array([[true["Zw"], u0 + zq], [true["Mw"], true["Mq"]]])
    b = np.array([[true["Zde"]], [true["Mde"]]])
    f = np.zeros((4, 4))
    f[:2, :2], f[:2, 2:3], f[2, 3] = a, b, 1.0
    e = scipy.linalg.expm(f * dt)
    phi, g1, g2 = e[:2, :2], e[:2, 2], e[:2, 3] / dt
    x = np.zeros((len(t), 2))
    for k in range(len(t) - 1):
        x[k + 1] = phi @ x[k] + (g1 - g2) * de[k] + g2 * de[k + 1]
    az = true["Zw"] * x[:, 0] + zq * x[:, 1] + true["Zde"] * de
    clean = np.column_stack([az, x])
    rng = np.random.default_rng(seed)
    white = (
        rng.normal(size=(n_flights, len(t), 3))
        * np.array([0.0, NOISE["w"], NOISE["q"]])
        * scale
    )
    # first-order coloured noise of standard deviation NOISE["az"]
    rho = np.exp(-dt / COLOUR_TIME)
    drive = rng.normal(size=(n_flights, len(t))) * scale * NOISE["az"]
    drive = drive * np.sqrt(1 - rho**2)
    col = np.zeros((n_flights, len(t)))
    col[:, 0] = rng.normal(size=n_flights) * NOISE["az"] * scale
    for k in range(1, len(t)):
        col[:, k] = rho * col[:, k - 1] + drive[:, k]
    white[..., 0] = col
    if sensor_time > 0:
        rho_s = np.exp(-dt / sensor_time)
        for j, name in ((1, "w"), (2, "q")):
            white[..., j] = _ar1(rng, (n_flights, len(t)), rho_s, NOISE[name] * scale)
    return t, de, clean[None] + white


FIELDS = ("theta", "stderr", "stderr_corrected", "halfwidth", "dof")


class Hist:
    """The replay history's fields the summary uses, as NumPy arrays."""

    def __init__(self, **fields):
        self.__dict__.update(fields)


def replay_chunk(batched, h, y, o, path):
    """One chunk of flights replayed to completion (or read back from `path`)."""
    if path.exists():
        with np.load(path) as f:
            return Hist(**{k: f[k] for k in FIELDS})
    res = jax.block_until_ready(batched(h, y, o))
    out = Hist(**{k: np.asarray(getattr(res, k)) for k in FIELDS})
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, **out.__dict__)
    tmp.replace(path)
    return out


def coverage(theta, halfwidth, truth):
    """Fraction of flights whose 95% band (`theta +- halfwidth`) holds the
    truth, per checked time and parameter: `(times, p)`."""
    inside = np.abs(theta - truth[None, None, :]) <= halfwidth
    return inside.mean(axis=0)


def flight_arguments(parser):
    """The options that choose the simulated flights (shared with the scripts that
    take these flights apart)."""
    parser.add_argument("--flights", type=int, default=200)
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--rate", type=float, default=50.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--aircraft",
        choices=tuple(AIRCRAFT),
        default="short-period",
        help="unstable: the unstable aircraft's short-period derivatives (Mw > 0)",
    )
    parser.add_argument(
        "--noise-scale", type=float, default=1.0, help="multiplies every noise level"
    )
    parser.add_argument(
        "--sensor-correlation",
        type=float,
        default=0.0,
        help="s: w and q sensor noise first-order coloured (0: white)",
    )


def setup(args):
    """The flights of the options `args` ([`flight_arguments`][]) and their
    regressions: a namespace with `t` `(n,)`, `dt`, the `model`, its `true`
    derivatives, `regs` (one per flight), `names`, `truth` `(p,)` in their
    order, `h`, `y`, `o` stacked over the flights, `theta0`, the checked times
    `check_times` (s) and their sample indices `times_idx`."""
    u0, zq, true = AIRCRAFT[args.aircraft]
    model = make_model(true, u0, zq)
    t, de, measured = simulate(
        args.flights,
        args.duration,
        args.rate,
        args.seed,
        args.noise_scale,
        args.sensor_correlation,
        true,
        u0,
        zq,
    )
    dt = 1.0 / args.rate
    regs = [
        rc.model_regression(
            model, dp.Record(t, de[:, None], measured[i], x0=np.zeros(2))
        )
        for i in range(args.flights)
    ]
    names = regs[0].parameters
    check_times = [c for c in (10.0, 15.0, 20.0, 25.0) if c < args.duration]
    check_times.append(args.duration)
    return types.SimpleNamespace(
        t=t,
        dt=dt,
        model=model,
        true=true,
        regs=regs,
        names=names,
        truth=np.array([true[n] for n in names]),
        h=jnp.stack([r.h for r in regs]),
        y=jnp.stack([r.y for r in regs]),
        o=jnp.stack([r.o for r in regs]),
        theta0=jnp.asarray(np.asarray(model.start)[list(regs[0].index)]),
        check_times=check_times,
        times_idx=[int(round((c - t[0]) / dt)) for c in check_times],
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    flight_arguments(parser)
    parser.add_argument(
        "--methods", default="rls,rls_memory_10s,rft", help="comma-separated labels"
    )
    parser.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("results/recursive_coverage")
    )
    args = parser.parse_args()
    flights = setup(args)
    dt, regs, names, truth = flights.dt, flights.regs, flights.names, flights.truth
    h, y, o, theta0 = flights.h, flights.y, flights.o, flights.theta0
    check_times, times_idx = flights.check_times, flights.times_idx
    freqs = tuple(float(f) for f in np.arange(0.1, BAND + 0.01, 0.04))
    estimators = {
        "rls": rc.RecursiveLeastSquares(
            forgetting=1.0, derivative=regs[0].derivative, dt=dt, bandwidth=RLS_BAND
        ),
        "rls_memory_10s": rc.RecursiveLeastSquares(
            forgetting=rc.forgetting_for(10.0, dt),
            derivative=regs[0].derivative,
            dt=dt,
            bandwidth=RLS_BAND,
        ),
        "rft": rc.RecursiveFourier(
            frequencies=freqs, forgetting=1.0, derivative=regs[0].derivative, dt=dt
        ),
    }
    summary = {
        "flights": args.flights,
        "duration_s": args.duration,
        "rate_hz": args.rate,
        "noise_scale": args.noise_scale,
        "sensor_correlation_s": args.sensor_correlation,
        "aircraft": args.aircraft,
        "rls_bandwidth_hz": RLS_BAND,
        "noise": NOISE,
        "az_noise_correlation_time_s": COLOUR_TIME,
        "check_times_s": check_times,
        "parameters": list(names),
        "methods": {},
    }
    wanted = args.methods.split(",")
    estimators = {k: v for k, v in estimators.items() if k in wanted}
    for label, est in estimators.items():
        start = time.perf_counter()
        batched = jax.jit(
            lambda hh, yy, oo, est=est: jax.lax.map(
                lambda a: rc.replay(est, *a, theta0, at=tuple(times_idx)),
                (hh, yy, oo),
            )
        )
        # flights in chunks of CHUNK (one compiled program), one at a time (see
        # the note on stalls at the top), each kept on disk once done
        parts = [
            replay_chunk(
                batched, h[i : i + CHUNK], y[i : i + CHUNK], o[i : i + CHUNK],
                args.out / "chunks" / (
                    f"{label}_{args.aircraft}_{args.duration:g}s_rate{args.rate:g}_"
                    f"noise{args.noise_scale:g}_sensor{args.sensor_correlation:g}_"
                    f"seed{args.seed}_of{args.flights}_{i}.npz"
                ),
            )
            for i in range(0, args.flights, CHUNK)
        ]  # fmt: skip
        hist = Hist(
            **{k: np.concatenate([getattr(p, k) for p in parts]) for k in FIELDS}
        )
        theta = np.asarray(hist.theta)
        elapsed = time.perf_counter() - start
        cov_plain = coverage(theta, 1.96 * np.asarray(hist.stderr), truth)
        cov_corr = coverage(theta, np.asarray(hist.halfwidth), truth)
        final = theta[:, -1, :]
        summary["methods"][label] = {
            "seconds_all_flights": elapsed,
            "coverage_plain": {
                n: cov_plain[:, k].tolist() for k, n in enumerate(names)
            },
            "coverage_corrected": {
                n: cov_corr[:, k].tolist() for k, n in enumerate(names)
            },
            "coverage_corrected_mean": float(cov_corr.mean()),
            "coverage_plain_mean": float(cov_plain.mean()),
            "final_mean": dict(zip(names, final.mean(axis=0).tolist(), strict=True)),
            "final_scatter": dict(zip(names, final.std(axis=0).tolist(), strict=True)),
            # the interquartile range over 1.349: the scatter without outliers
            "final_robust_scatter": dict(
                zip(
                    names,
                    (
                        np.subtract(*np.percentile(final, [75, 25], axis=0)) / 1.349
                    ).tolist(),
                    strict=True,
                )
            ),
            "final_mean_stderr_corrected": dict(
                zip(
                    names,
                    np.asarray(hist.stderr_corrected)[:, -1, :].mean(axis=0).tolist(),
                    strict=True,
                )
            ),
        }
        # bias against scatter: how much of the miss a band of the noise alone
        # cannot hold
        sd_c = np.asarray(hist.stderr_corrected)[:, -1, :]
        for k, n in enumerate(names):
            print(
                f"  {n}: bias/scatter {(final[:, k].mean() - truth[k]) / final[:, k].std():+.3f}"
                f", scatter/mean band {final[:, k].std() / sd_c[:, k].mean():.3f}"
                f", coverage at {check_times} s: {np.round(cov_corr[:, k], 3).tolist()}"
            )
        # the band's own noise: its degrees of freedom over the flights (a
        # chi-square variance with v dof has variance 2 mean^2 / v) against the
        # estimator's own estimate `dof`, and the coverage a Student-t band at
        # the estimated dof would have
        var_c = np.asarray(hist.stderr_corrected) ** 2
        dof_seen = 2 * var_c.mean(axis=0) ** 2 / var_c.var(axis=0)  # (times, p)
        dof_est = np.asarray(hist.dof).mean(axis=0)
        t_band = np.asarray(hist.stderr_corrected) * scipy.stats.t.ppf(
            0.975, np.maximum(np.asarray(hist.dof), 1.0)
        )
        cov_t = coverage(theta, t_band, truth)
        for k, n in enumerate(names):
            print(
                f"  {n}: band dof over the flights {np.round(dof_seen[:, k], 1).tolist()}"
                f", estimated {np.round(dof_est[:, k], 1).tolist()}"
                f", coverage with t at the estimated dof {np.round(cov_t[:, k], 3).tolist()}"
            )
        summary["methods"][label]["band_dof_over_flights"] = {
            n: dof_seen[:, k].tolist() for k, n in enumerate(names)
        }
        summary["methods"][label]["band_dof_estimated_mean"] = {
            n: dof_est[:, k].tolist() for k, n in enumerate(names)
        }
        summary["methods"][label]["coverage_student_t_estimated_dof"] = {
            n: cov_t[:, k].tolist() for k, n in enumerate(names)
        }
        summary["methods"][label]["bias_over_scatter"] = {
            n: float((final[:, k].mean() - truth[k]) / final[:, k].std())
            for k, n in enumerate(names)
        }
        summary["methods"][label]["scatter_over_rms_stderr"] = {
            n: float(final[:, k].std() / np.sqrt(np.mean(sd_c[:, k] ** 2)))
            for k, n in enumerate(names)
        }
        print(
            f"{label}: coverage plain {cov_plain.mean():.3f}, corrected "
            f"{cov_corr.mean():.3f} ({elapsed:.1f} s for {args.flights} flights)"
        )
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "coverage.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
