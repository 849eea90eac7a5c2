"""Is the process-noise check on clean HFB-320 flights failed by the input's timing
inside a sample? The independent generator steps the elevator at `2 s + f dt`
(`f` drawn per seed); the model interpolates the sampled input linearly, which
puts each step's impulse at the middle of the sample interval: an error of
`(f - 1/2) dt` per step. This flies one flight (rate, seed, gust) with the
seed's own `f` and with `f` set, fits it by output error and by filter error
(white, and coloured when the log prefers, as `diagnose --vehicle hfb320`), and
prints the q residuals' RMS within 0.5 s after each step against elsewhere, the
likelihood ratio and the innovations' check per output. Measurement aid.

    nice python experiments/gust_input_timing.py RATE SEED GUST [F ...]
"""

import json
import pathlib
import sys
import tempfile
import time

import jax
import numpy as np


jax.config.update("jax_enable_x64", True)
HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
import independent_generator as gen  # noqa: E402

from diffpegasus._cli._fem import diagnosis_states  # noqa: E402
from diffpegasus._cli._runners import _fit_spec  # noqa: E402
from diffpegasus._diagnose._process_noise import (  # noqa: E402
    innovation_check,
    input_timing,
    likelihood_ratio,
    ProcessNoiseRule,
    white_or_coloured,
)
from diffpegasus._estimate._gust import Gust  # noqa: E402
from diffpegasus._registry import vehicle_entry  # noqa: E402


class _Fraction:
    """A generator whose `uniform` returns `f`: the step's place in its sample."""

    def __init__(self, f):
        self.f = f

    def uniform(self, *_):
        return self.f


def fly(rate, seed, gust, f=None):
    real = np.random.default_rng

    def rng(arg=None, *a, **k):
        if f is not None and arg == 30_000 + seed:
            return _Fraction(f)
        return real(arg, *a, **k)

    np.random.default_rng = rng
    try:
        return gen.generate_hfb320(seed, rate, gust_sigma=gust)
    finally:
        np.random.default_rng = real


def measure(rate, seed, gust, f=None, **options):
    channels, meta = fly(rate, seed, gust, f)
    frac = f if f is not None else real_fraction(seed)
    csv = pathlib.Path(tempfile.mkdtemp()) / f"hfb_{rate:g}_{seed}.csv"
    gen.write(csv, channels, meta)
    t0 = time.perf_counter()
    entry = vehicle_entry("hfb320")
    spec, records = entry.problem([csv], candidates=True)
    spec, oem = _fit_spec(spec, [csv], None, (), None, None, None, records)
    rec = oem.records[0]
    t = np.asarray(rec.t)
    de = channels["de"]
    steps = t[1:][np.abs(np.diff(de)) > 0]
    near = np.zeros(len(t), bool)
    for s in steps:
        near |= (t >= s - 1e-9) & (t < s + 0.5)
    iq = spec.model.outputs.index("q")
    res = np.asarray(rec.measured)[:, iq] - np.asarray(oem.outputs[0])[:, iq]
    states = diagnosis_states((), spec)
    g = Gust(
        tuple(spec.gust),
        kinematic=tuple(s for s in spec.gust_kinematic if s in spec.model.states),
        pitch_rate=spec.gust_pitch_rate,
    )
    fem, choice = white_or_coloured(oem, states, g, gain=None, **options)
    lr, _ = likelihood_ratio(oem, fem)
    n = len(t)
    lags = int(min(np.ceil(10.0 * np.log10(n)), n // 4))
    stat, dof = innovation_check(
        np.asarray(fem.innovations[0]),
        np.column_stack([np.asarray(fem.outputs[0]), rec.inputs]),
        lags,
    )
    import scipy.stats

    timing = input_timing(oem, fem)
    stat_t, dof_t = innovation_check(
        timing["innovations"][0],
        np.column_stack([np.asarray(fem.outputs[0]), rec.inputs]),
        lags,
    )
    rule = ProcessNoiseRule()
    outs = spec.model.outputs
    nu_q = np.asarray(fem.innovations[0])[:, iq]
    row = dict(
        rate=rate,
        seed=seed,
        gust=gust,
        fraction=frac,
        oem_q_rms_after_steps=float(np.sqrt(np.mean(res[near] ** 2))),
        oem_q_rms_elsewhere=float(np.sqrt(np.mean(res[~near] ** 2))),
        fem_q_rms_after_steps=float(np.sqrt(np.mean(nu_q[near] ** 2))),
        fem_q_rms_elsewhere=float(np.sqrt(np.mean(nu_q[~near] ** 2))),
        noise_model=choice["model"],
        LR=lr,
        F=dict(zip(fem.process_noise, np.asarray(fem.F).tolist(), strict=True)),
        check=dict(zip(outs, np.round(stat, 1).tolist(), strict=True)),
        threshold=float(scipy.stats.chi2.isf(rule.significance / len(outs), dof)),
        intervals=timing["intervals"][0],
        LR_timing=timing["likelihood_ratio"],
        LR_sampled_input=timing["likelihood_ratio_sampled_input"],
        check_timing=dict(zip(outs, np.round(stat_t, 1).tolist(), strict=True)),
        threshold_timing=float(
            scipy.stats.chi2.isf(rule.significance / len(outs), dof_t)
        ),
        seconds=round(time.perf_counter() - t0, 1),
    )
    print(json.dumps(row), flush=True)
    return row


def real_fraction(seed):
    return float(np.random.default_rng(30_000 + seed).uniform(0.0, 1.0))


if __name__ == "__main__":
    rate, seed, gust = float(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
    fractions = [float(x) for x in sys.argv[4:]] or [None]
    for f in fractions:
        measure(rate, seed, gust, f)
