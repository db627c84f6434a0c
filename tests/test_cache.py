"""Caches: compiled kernels are reused by later processes, and land in the user cache when the package
directory is read-only; the first real compilation is announced."""

import json
import os
import subprocess
import sys

import numba

from rmac_mj import _cache

# One small kernel of the package (and the one it calls): enough to see compile-or-load, quick to compile.
_LOAD_ONE_KERNEL = """
import json
import numpy as np
import rmac_mj
from rmac_mj import _cache
from rmac_mj.approximators import _llr_kernels
out = np.empty(2)
_llr_kernels.canonical(np.array([4.0, 1.0]), np.array([2 * np.pi, 0.0]), out)
print(json.dumps(_cache.kernel_stats()))
"""


def test_a_second_process_loads_the_kernels_instead_of_compiling_them(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}  # a cold cache of our own

    def run():
        result = subprocess.run([sys.executable, "-c", _LOAD_ONE_KERNEL], env=env, capture_output=True,
                                text=True, timeout=120, check=True)
        return json.loads(result.stdout.strip().splitlines()[-1])

    first, second = run(), run()
    assert first["compiled"] >= 1  # the cold cache: compiled, and written to disk
    assert any((tmp_path / "numba").rglob("*.nbi"))
    assert second["compiled"] == 0 and second["loaded"] >= 1  # (a callee is loaded with its caller)


def test_kernels_go_to_the_user_cache_when_the_package_is_read_only(tmp_path, monkeypatch):
    environ = {"RMAC_MJ_CACHE_DIR": str(tmp_path / "cache")}
    monkeypatch.setattr(_cache, "_writable", lambda path: True)
    assert _cache.configure_numba_cache(environ) is None and "NUMBA_CACHE_DIR" not in environ
    monkeypatch.setattr(_cache, "_writable", lambda path: False)
    assert _cache.configure_numba_cache(environ) == str(tmp_path / "cache" / "numba")
    assert environ["NUMBA_CACHE_DIR"] == str(tmp_path / "cache" / "numba")
    assert _cache.numba_cache_location(environ) == environ["NUMBA_CACHE_DIR"]
    chosen = {"NUMBA_CACHE_DIR": "/somewhere/else"}  # the user's choice is kept
    assert _cache.configure_numba_cache(chosen) is None and chosen["NUMBA_CACHE_DIR"] == "/somewhere/else"


def test_user_cache_dir_follows_the_environment(tmp_path):
    assert _cache.user_cache_dir({"RMAC_MJ_CACHE_DIR": str(tmp_path)}) == tmp_path
    assert _cache.user_cache_dir({"XDG_CACHE_HOME": str(tmp_path)}) == tmp_path / "rmac-mj"


def test_the_first_compilation_is_announced_once():
    @numba.njit  # no disk cache: it compiles every time
    def twice(x):
        return 2 * x

    calls = []
    with _cache.on_first_compile(lambda: calls.append(1)):
        assert twice(2) == 4 and twice(2.5) == 5.0  # two signatures, two compilations
    assert calls == [1]
    with _cache.on_first_compile(lambda: calls.append(2)):
        twice(3)  # already compiled for int: nothing to say
    assert calls == [1]


def test_writable_asks_about_the_nearest_existing_folder(tmp_path, monkeypatch):
    asked = []
    monkeypatch.setattr(os, "access", lambda path, mode: asked.append(path) or False)
    assert _cache._writable(tmp_path / "not" / "yet") is False
    assert asked == [tmp_path]
