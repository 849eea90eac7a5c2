"""The persistent compilation cache: where it lives, how it is switched off, and that
a program compiled by one process is read back by the next."""

import json
import os
import pickle
import subprocess
import sys
import time

import numpy as np
import pytest

import diffpegasus._cache as _cache


def _env(tmp_path, **extra):
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("JAX_COMPILATION_CACHE_DIR", "DIFFPEGASUS_NO_CACHE")
    }
    env.update(XDG_CACHE_HOME=str(tmp_path / "xdg"), HOME=str(tmp_path / "home"))
    env.update(extra)
    return env


def test_default_folder_and_switch(monkeypatch, tmp_path):
    monkeypatch.delenv("JAX_COMPILATION_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert _cache.default_cache_dir() == tmp_path / "diffpegasus" / "jax"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "h"))
    assert (
        _cache.default_cache_dir() == tmp_path / "h" / ".cache" / "diffpegasus" / "jax"
    )
    monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", str(tmp_path / "j"))
    assert _cache.default_cache_dir() == tmp_path / "j"
    for value, off in (("1", True), ("yes", True), ("0", False), ("", False)):
        monkeypatch.setenv("DIFFPEGASUS_NO_CACHE", value)
        assert _cache.cache_disabled() is off
    monkeypatch.setenv("DIFFPEGASUS_NO_CACHE", "1")
    assert _cache.enable_cache(tmp_path / "never") is None
    assert not (tmp_path / "never").exists()


@pytest.mark.parametrize("where", ["before", "after"])
def test_no_cache_flag_of_the_command_line(tmp_path, where):
    args = ["--no-cache", "effects"] if where == "before" else ["effects", "--no-cache"]
    done = subprocess.run(
        [sys.executable, "-m", "diffpegasus", *args],
        env=_env(tmp_path),
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    assert not (tmp_path / "xdg" / "diffpegasus").exists()
    # without the flag the command makes its cache folder, private to the user
    done = subprocess.run(
        [sys.executable, "-m", "diffpegasus", "effects"],
        env=_env(tmp_path),
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    folder = tmp_path / "xdg" / "diffpegasus" / "jax"
    assert folder.is_dir() and (folder.stat().st_mode & 0o077) == 0


PROGRAM = """
import logging, sys
import jax, jax.numpy as jnp
from diffpegasus._cache import enable_cache
logging.basicConfig(level=logging.WARNING)
logging.getLogger("jax._src.compiler").setLevel(logging.DEBUG)
print(enable_cache())
# the real threshold (0.1 s) would need a program that compiles for a while
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
def f(x):
    return jnp.cumsum(jnp.sin(x) @ jnp.cos(x).T, axis=0)
jax.block_until_ready(jax.jit(f)(jnp.ones((8, 8))))
"""


def test_second_process_reads_the_compiled_program(tmp_path):
    env = _env(tmp_path)
    runs = [
        subprocess.run(
            [sys.executable, "-c", PROGRAM], env=env, capture_output=True, text=True
        )
        for _ in range(2)
    ]
    for r in runs:
        assert r.returncode == 0, r.stderr
    folder = tmp_path / "xdg" / "diffpegasus" / "jax"
    assert runs[0].stdout.strip() == str(folder)
    assert "cache miss for 'jit_f'" in runs[0].stderr.lower()
    assert any(p.name.startswith("jit_f-") for p in folder.iterdir())
    assert "cache hit for 'jit_f'" in runs[1].stderr.lower()


EXPORTED = """
import json, sys
import jax, jax.numpy as jnp, numpy as np
from jax._src import monitoring
import diffpegasus._cache as cache
from diffpegasus._estimate._engine import lm_step
traced = []
monitoring.register_event_time_span_listener(
    lambda event, start, end, **kw: traced.append(kw.get("fun_name"))
    if event.endswith("jaxpr_trace_duration") else None
)
cache.enable_cache()
# the key holds a digest of the package's source; fixed here so that an edit of the
# working tree between the two processes does not make them differ
cache._SOURCE_DIGEST = "test"
rng = np.random.default_rng(0)
a = rng.normal(size=(6, 6))
args = {"h": a @ a.T + np.eye(6), "g": rng.normal(size=6),
        "free": np.array([1, 1, 0, 1, 1, 1], bool), "damping": np.asarray(0.1)}
via = cache.kept_call(lm_step, {}, args)
direct = jax.jit(lm_step)(**{k: jnp.asarray(v) for k, v in args.items()})
print(json.dumps({"via": np.asarray(via).tolist(), "direct": np.asarray(direct).tolist(),
                  "traced_flat": traced.count("flat")}))
"""


def test_kept_program_is_loaded_by_a_second_process(tmp_path):
    """`kept_call` traces a package function once per machine: the second
    process reads the kept program (no tracing of it) and gets the same numbers."""
    env = _env(tmp_path)
    outs = []
    for _ in range(2):
        r = subprocess.run(
            [sys.executable, "-c", EXPORTED], env=env, capture_output=True, text=True
        )
        assert r.returncode == 0, r.stderr
        outs.append(json.loads(r.stdout.strip().splitlines()[-1]))
    folder = tmp_path / "xdg" / "diffpegasus" / "jax" / "programs"
    assert len(list(folder.glob("*.bin"))) == 1
    assert outs[0]["traced_flat"] == 1 and outs[1]["traced_flat"] == 0
    assert outs[0]["via"] == outs[1]["via"]
    for o in outs:
        assert np.allclose(o["via"], o["direct"], rtol=1e-13, atol=0)


def test_kept_call_falls_back_to_a_direct_call(tmp_path, monkeypatch):
    """Traced arguments, untrusted static arguments and functions outside the
    package are called directly, with the same result, and nothing is kept."""
    import jax
    import jax.numpy as jnp

    from diffpegasus._estimate._engine import lm_step

    monkeypatch.setattr(_cache, "_ACTIVE", tmp_path)
    monkeypatch.setattr(_cache, "_MEMO", {})
    h, g = jnp.eye(3) * 2.0, jnp.arange(3.0)
    free, damping = jnp.ones(3, bool), jnp.asarray(0.0)
    expected = lm_step(h, g, free, damping)
    inside = jax.jit(
        lambda h: _cache.kept_call(
            lm_step, {}, {"h": h, "g": g, "free": free, "damping": damping}
        )
    )(h)
    assert jnp.allclose(inside, expected)

    def mine(h, g, free, damping, scale):
        return lm_step(h, g, free, damping) * scale(1.0)

    out = _cache.kept_call(
        mine, {"scale": lambda x: x}, {"h": h, "g": g, "free": free, "damping": damping}
    )
    assert jnp.allclose(out, expected)
    assert not (tmp_path / "programs").exists()
    # a static argument naming code outside the package cannot be keyed
    with pytest.raises(pickle.PicklingError):
        _cache._call_key(lm_step, {"scale": mine}, {"h": h})


def test_processes_started_together_trace_a_kept_program_once(tmp_path):
    """Two processes that need the same kept program at the same moment (two test
    workers, two campaign processes): one traces and compiles it while the other
    waits, then reads it; both get the same numbers. Each process signals that it
    is ready and both call `kept_call` when the test says go, so without the wait
    both would trace it."""
    env = _env(tmp_path)
    barrier = (
        "import pathlib, time\n"
        "pathlib.Path(sys.argv[1]).touch()\n"
        "while not pathlib.Path(sys.argv[2]).exists():\n"
        "    time.sleep(0.002)\n"
        "via = cache.kept_call("
    )
    script = EXPORTED.replace("via = cache.kept_call(", barrier, 1)
    go = tmp_path / "go"
    ready = [tmp_path / f"ready{i}" for i in range(2)]
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", script, str(r), str(go)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for r in ready
    ]
    try:
        for _ in range(60_000):  # both imported and waiting (at most a minute)
            if all(r.exists() for r in ready) or any(
                p.poll() is not None for p in procs
            ):
                break
            time.sleep(0.001)
        go.touch()
        outs = [p.communicate(timeout=120) for p in procs]
    finally:
        for p in procs:
            p.kill()
    for p, (_, err) in zip(procs, outs, strict=True):
        assert p.returncode == 0, err
    results = [json.loads(out.strip().splitlines()[-1]) for out, _ in outs]
    assert sorted(r["traced_flat"] for r in results) == [0, 1]
    assert results[0]["via"] == results[1]["via"]
    folder = tmp_path / "xdg" / "diffpegasus" / "jax" / "programs"
    assert len(list(folder.glob("*.bin"))) == 1
