"""The persistent compilation cache: where it lives, how it is switched off, and that
a program compiled by one process is read back by the next."""

import os
import subprocess
import sys

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
