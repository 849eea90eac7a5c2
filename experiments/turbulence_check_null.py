"""The innovations' check of the process-noise candidate against its null from a
parametric bootstrap of the fitted filter model (measurement aid): is the
chi-square point the check uses right for a launch vehicle's log?

Runs `diagnose` in-process on the independent generator's flight (10 s at 100
Hz, `--knots 4 --rate 25`, as tests/test_fem_pegasus.py does) and, at the
filter-error fit the check judges, simulates `REPLICATES` records from that
fitted model (its parameters, white and gust intensities, the gust states
started from their stationary spread, the measurement noise the filter's own
split of the innovation variance, `R - C K R`, RK4 at the sample step with the
process noise added per step), runs the fit's filter (its scheduled gains) on
each, and computes the check per output, raw and with the fit's free unknowns
projected out of the whitened innovations (a first-order refit). No fit is
repeated.

    python experiments/turbulence_check_null.py turb,7,1.5 200

`turb,SEED,SIGMA[,RATE]`, `calm,SEED[,RATE]` (the launch vehicle, 10 s, the log
at RATE Hz, default 100, read at 25 Hz), `hfb,SEED,SIGMA` (the independent HFB-320
at 20 Hz, `--vehicle hfb320`). The check bootstrapped is the first the diagnosis
computes: the kept fit's when the likelihood ratio passes, else the first noise
model's (white). When the log is read as centred block means of `RATE / 25`
samples the null is computed twice: replicates simulated at the record's samples
(`SPEC`), and replicates simulated at the log's rate with the log's own inputs and
read as the log is read (`SPEC block4`: block means, the measurement noise added
at the log's rate), which carries the decimation into the null. Results: a pickle
per null under /tmp/turbulence_check_null and a summary line per null in
experiments/results/turbulence_check_null.json.
"""

import functools
import json
import pathlib
import pickle
import sys
import time

import jax


jax.config.update("jax_enable_x64", True)
import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import scipy.stats  # noqa: E402
from typer.testing import CliRunner  # noqa: E402


ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
import independent_generator as gen  # noqa: E402

from diffpegasus._cli import app  # noqa: E402
from diffpegasus._diagnose import _process_noise as pn  # noqa: E402
from diffpegasus._estimate._engine import _input_at  # noqa: E402
from diffpegasus._estimate._filter_error import problem, run_filter  # noqa: E402
from diffpegasus._registry._pegasus import block_means, block_weights  # noqa: E402


LOGS = pathlib.Path("/tmp/turbulence_check_null")
RESULTS = ROOT / "experiments" / "results" / "turbulence_check_null.json"


def _prob(fem, initial_states):
    """The fit's filter problem; a record without its own initial state starts
    from `initial_states` (the output-error fit's, as the filter-error fit did)."""
    model = fem.model
    noise_states = tuple(model.states.index(s) for s in fem.process_noise)
    x0 = np.array(
        [
            r.x0 if r.x0 is not None else np.asarray(initial_states[i], float)
            for i, r in enumerate(fem.records)
        ]
    )
    prob = problem(model, fem.records, noise_states, x0=x0)
    sched = np.array(
        [
            np.round((np.asarray(gt) - r.t[0]) / (r.t[1] - r.t[0])).astype(int)
            for gt, r in zip(fem.gain_times, fem.records, strict=True)
        ]
    )
    prob = eqx.tree_at(lambda p: p.schedule, prob, jnp.asarray(sched))
    return prob, noise_states


@functools.partial(jax.jit, static_argnames=("model", "noise_states", "step"))
def _replicate(
    model, noise_states, prob, theta, f, k, sm, x0sd, keys, blocks, step, fine
):
    """Simulated records (truth + noise) and the filter's innovations on them.

    `step` 1: the model's outputs at the record's samples plus white noise of sd
    `sm`. `step` > 1: as the log is read, simulated at `step` times the record's
    rate (process noise per fine step), white noise of sd `sm` added at the fine
    rate, then the record's centred block means, `blocks @ fine` (`blocks` the
    reader's weights, `(length, fine length)`); the known inputs then from `fine`,
    a layout holding the log's own samples of them (the record's are their block
    means), so that the block means of the simulated outputs carry the inputs'
    motion inside each block as the log's do."""
    lay = prob.layout
    r = 0
    dt = lay.dt[r] / step
    delay = model.input_delays(theta)
    nf = step * (lay.length - 1) + 1
    ts = lay.t0[r] + dt * jnp.arange(nf)
    nx = prob.x0.shape[1]
    fvec = jnp.zeros(nx).at[jnp.asarray(noise_states)].set(f)

    def field(t, x):
        return model.f(t, x, _input_at(fine, r, t, delay), theta)

    def one(key):
        k1, k2, k3 = jax.random.split(key, 3)
        w = jax.random.normal(k1, (nf, nx))
        v = jax.random.normal(k2, (nf, sm.shape[0])) * sm
        x0 = prob.x0[r]

        def rk4(x, inp):
            t, wi = inp
            y = model.g(t, x, _input_at(fine, r, t, delay), theta)
            a = field(t, x)
            b = field(t + dt / 2, x + dt / 2 * a)
            c = field(t + dt / 2, x + dt / 2 * b)
            d = field(t + dt, x + dt * c)
            x1 = x + dt / 6 * (a + 2 * b + 2 * c + d) + jnp.sqrt(dt) * fvec * wi
            return x1, y

        _, ys = jax.lax.scan(rk4, x0 + x0sd * jax.random.normal(k3, (nx,)), (ts, w))
        z = ys + v if step == 1 else blocks @ (ys + v)
        p2 = eqx.tree_at(
            lambda p: p.layout.measured, prob, prob.layout.measured.at[r].set(z)
        )
        nu, yhat, _ = run_filter(model, p2, r, theta, k)
        return nu, yhat

    return jax.vmap(one)(keys)


def check_null(
    fem, initial_states, lags, replicates=200, seed=0, step=1, fine_inputs=None
):
    """The check's bootstrap null at `fem` (see the module); `step` > 1 simulates
    each replicate at `step` times the record's rate and reads it as the log is
    read (centred block means of `step` samples, measurement noise added at the
    fine rate with the variance whose block mean is the filter's split), its
    known inputs `fine_inputs` `(fine samples, inputs)`, the log's own."""
    model = fem.model
    prob, noise_states = _prob(fem, initial_states)
    theta = jnp.asarray(fem.params)
    f = jnp.asarray(fem.F)
    k = jnp.asarray(fem.gain[0])
    # measured-noise variance: R - C K R at the schedule points (mean), the
    # filter's own split of the innovation variance
    nu, yhat, xs = run_filter(model, prob, 0, theta, k)
    sched = np.asarray(prob.schedule[0])
    u = fem.records[0].inputs
    cs = [
        np.asarray(
            jax.jacfwd(model.g, argnums=1)(
                fem.records[0].t[i], xs[i], jnp.asarray(u[i]), theta
            )
        )
        for i in sched
    ]
    rdiag = np.diag(np.asarray(fem.R))
    ckr = np.mean(
        [np.diag(c @ np.asarray(k[j]) @ np.asarray(fem.R)) for j, c in enumerate(cs)],
        axis=0,
    )
    rm = np.clip(rdiag - ckr, 1e-6 * rdiag, None)
    keys = jax.random.split(jax.random.PRNGKey(seed), replicates)
    length = int(prob.layout.length)
    fine = prob.layout
    if step == 1:
        blocks = np.eye(length)
        fine_var = rm
    else:
        nf = step * (length - 1) + 1
        blocks = block_means(np.eye(nf), step)[0]
        bw = block_weights(step) / step
        fine_var = rm / float(np.sum(bw * bw))
        n_rec = len(fem.records[0].t)
        uf = np.asarray(fine_inputs, float)
        if uf.shape[0] != step * (n_rec - 1) + 1:
            raise ValueError(f"{uf.shape[0]} fine samples for {n_rec} record samples")
        pad = step * (length - 1) + 1 - uf.shape[0]
        uf = np.concatenate([uf, np.repeat(uf[-1:], pad, axis=0)])
        fine = eqx.tree_at(
            lambda lay: (lay.inputs, lay.dt, lay.n),
            prob.layout,
            (
                jnp.asarray(uf)[None],
                prob.layout.dt / step,
                jnp.asarray([uf.shape[0] - pad], dtype=prob.layout.n.dtype),
            ),
        )
    # a gust state starts from its stationary spread, F^2 tau / 2
    x0sd = np.zeros(len(model.states))
    if "gust_ln_tau" in model.parameters:
        tau = float(np.exp(fem.params[model.parameters.index("gust_ln_tau")]))
        for j, s in enumerate(fem.process_noise):
            if s.startswith("gust["):
                x0sd[model.states.index(s)] = float(fem.F[j]) * np.sqrt(tau / 2)
    nus, yhats = _replicate(
        model,
        noise_states,
        prob,
        theta,
        f,
        k,
        jnp.sqrt(jnp.asarray(fine_var)),
        jnp.asarray(x0sd),
        keys,
        jnp.asarray(blocks),
        step,
        fine,
    )
    nus, yhats = np.asarray(nus), np.asarray(yhats)
    n = len(fem.records[0].t)
    # first-order refit: project the whitened innovations off the free unknowns'
    # sensitivities at the fit
    free = np.concatenate([fem.free, np.ones(len(fem.F), bool)])
    jw = np.asarray(fem.jacobian)[0, :n][..., free].reshape(n * len(rdiag), -1)
    q, rr = np.linalg.qr(jw)
    keep = np.abs(np.diag(rr)) > 1e-10 * np.max(np.abs(np.diag(rr)))
    q = q[:, keep]
    w = 1.0 / np.sqrt(rdiag)
    raw, refit = [], []
    for b in range(replicates):
        e = nus[b, :n]
        s, dof = pn.innovation_check(e, np.column_stack([yhats[b, :n], u]), lags)
        raw.append(s)
        ew = (e * w).reshape(-1)
        ew = ew - q @ (q.T @ ew)
        s2, _ = pn.innovation_check(
            ew.reshape(n, -1) / w, np.column_stack([yhats[b, :n], u]), lags
        )
        refit.append(s2)
    return dict(
        raw=np.array(raw),
        refit=np.array(refit),
        dof=dof,
        rm=rm,
        rdiag=rdiag,
        nus=nus[:5],
        yhats=yhats[:5],
    )


def summary(spec, outputs, obs, evidence, boot) -> dict:
    """Per output the observed check, the bootstrap's mean, 99% point, share at
    or above the observed value, and the threshold of a chi-square scaled to the
    bootstrap's mean and variance at the check's level (Bonferroni over the
    outputs), raw and refitted."""
    out = {
        "flight": spec,
        "observed": dict(zip(outputs, np.round(obs, 1).tolist(), strict=True)),
        "chi_square_threshold": round(evidence["threshold"], 1),
        "dof": evidence["dof"],
    }
    for k in ("raw", "refit"):
        x = boot[k]
        m, v = x.mean(0), x.var(0)
        thr = v / (2 * m) * scipy.stats.chi2.isf(0.01 / len(outputs), 2 * m * m / v)
        out[k] = {
            name: {
                "mean": round(float(m[i]), 1),
                "q99": round(float(np.quantile(x[:, i], 0.99)), 1),
                "share_at_or_above": round(float(np.mean(x[:, i] >= obs[i])), 3),
                "scaled_chi_square_threshold": round(float(thr[i]), 1),
            }
            for i, name in enumerate(outputs)
        }
    return out


def main():
    spec = sys.argv[1]
    reps = int(sys.argv[2]) if len(sys.argv) > 2 else 200
    a = spec.split(",")
    LOGS.mkdir(exist_ok=True)
    step = 1
    if a[0] == "turb":
        rate = float(a[3]) if len(a) > 3 else 100.0
        csv = LOGS / f"turb_{a[1]}_{a[2]}_{rate:g}.csv"
        if not csv.exists():
            gen.make_turbulent_log(csv, int(a[1]), rate, 10.0, float(a[2]))
        args = ["diagnose", str(csv), "--json", "--knots", "4", "--rate", "25"]
        step = int(round(rate / 25.0))
    elif a[0] == "calm":
        rate = float(a[2]) if len(a) > 2 else 100.0
        csv = LOGS / f"calm_{a[1]}_{rate:g}.csv"
        if not csv.exists():
            gen.make_log(csv, int(a[1]), rate, 10.0)
        args = ["diagnose", str(csv), "--json", "--knots", "4", "--rate", "25"]
        step = int(round(rate / 25.0))
    else:
        csv = LOGS / f"hfb_{a[1]}_{a[2]}.csv"
        if not csv.exists():
            kw = {"gust_sigma": float(a[2])} if float(a[2]) > 0 else {}
            gen.write(csv, *gen.generate_hfb320(int(a[1]), 20.0, **kw))
        args = ["diagnose", str(csv), "--vehicle", "hfb320", "--json"]
    original = pn.turbulence_evidence
    seen = []

    def wrap(result, fem, rule, innovations=None):
        out = original(result, fem, rule, innovations)
        judged = fem.innovations if innovations is None else innovations
        regressors = np.column_stack(
            [np.asarray(fem.outputs[0]), fem.records[0].inputs]
        )
        obs, _ = pn.innovation_check(np.asarray(judged[0]), regressors, out["lags"])
        kind = "coloured" if "gust_ln_tau" in fem.model.parameters else "white"
        print(
            kind,
            "check per output",
            dict(zip(fem.model.outputs, np.round(obs, 1).tolist(), strict=True)),
            file=sys.__stderr__,
            flush=True,
        )
        if seen:
            return out
        seen.append(kind)
        # the first check is the kept fit's when the likelihood ratio passes, else
        # the first noise model's (the report's per-model checks)
        for st in sorted({1, step}):
            name = spec if st == 1 else f"{spec} block{st}"
            log = np.genfromtxt(csv, delimiter=",", names=True)
            fine_inputs = np.column_stack([log[c] for c in fem.model.inputs])
            boot = check_null(
                fem,
                np.asarray(result.initial_states),
                out["lags"],
                reps,
                0,
                step=st,
                fine_inputs=fine_inputs,
            )
            d = dict(
                spec=name, outputs=fem.model.outputs, obs=obs, evidence=out, boot=boot
            )
            tag = name.replace(",", "_").replace(" ", "_")
            pickle.dump(d, open(LOGS / f"{tag}.pkl", "wb"))
            line = summary(name, fem.model.outputs, obs, out, boot)
            line["fit"] = kind
            print(json.dumps(line), file=sys.__stderr__, flush=True)
            rows = json.loads(RESULTS.read_text()) if RESULTS.exists() else []
            rows = [r for r in rows if r["flight"] != name] + [line]
            RESULTS.write_text(json.dumps(rows, indent=1) + "\n")
        return out

    pn.turbulence_evidence = wrap
    t0 = time.time()
    res = CliRunner().invoke(app, args)
    if res.exception is not None:
        raise res.exception
    report = json.loads(res.stdout.strip().splitlines()[-1])
    row = next(r for r in report["ranking"] if r["effect"] == "process_noise")
    print(report["message"], report["significant"])
    print({k: row[k] for k in ("statistic", "dof", "likelihood_ratio_passes")})
    print(f"{time.time() - t0:.0f} s")


if __name__ == "__main__":
    main()
