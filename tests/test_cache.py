"""Caches: compiled kernels are reused by later processes, and land in the user cache when the package
directory is read-only; the first real compilation is announced."""

import json
import os
import subprocess
import sys

import numba
import pytest

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
print(json.dumps({**_cache.kernel_stats(), "started_empty": _cache.started_with_empty_cache()}))
"""


@pytest.mark.slow
def test_a_second_process_loads_the_kernels_instead_of_compiling_them(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}  # a cold cache of our own
    (tmp_path / "numba").mkdir()
    assert _cache.numba_cache_is_empty(env)

    def run():
        result = subprocess.run(
            [sys.executable, "-c", _LOAD_ONE_KERNEL],
            env=env,
            capture_output=True,
            text=True,
            timeout=120,
            check=True,
        )
        return json.loads(result.stdout.strip().splitlines()[-1]), result.stderr

    (first, said_first), (second, said_second) = run(), run()
    assert first["compiled"] >= 1  # the cold cache: compiled, and written to disk
    assert any((tmp_path / "numba").rglob("*.nbi")) and not _cache.numba_cache_is_empty(env)
    assert second["compiled"] == 0 and second["loaded"] >= 1  # (a callee is loaded with its caller)
    assert first["started_empty"] and not second["started_empty"]  # (run side by side: the first)
    # Outside the command line (the Python API), a compiling process says so once, on stderr.
    notice = "rmac-mj: numba is compiling the learners' kernels, first use only"
    assert said_first.count(notice) == 1 and notice not in said_second


def test_kernels_are_cached_per_version_of_their_sources(tmp_path):
    """numba checks only the timestamp of a kernel's own file; an edit of a kernel it calls must not
    load stale code, so the cache folder changes with any kernel source."""
    package = tmp_path / "package"
    for folder in _cache._KERNEL_DIRS:
        (package / folder).mkdir(parents=True)
        (package / folder / "kernels.py").write_text("def f():\n    return 1\n")
    environ = {"RMAC_MJ_CACHE_DIR": str(tmp_path / "cache")}
    first = _cache.configure_numba_cache(environ, package)
    assert first.startswith(str(tmp_path / "cache" / "numba"))
    assert environ["NUMBA_CACHE_DIR"] == first == _cache.numba_cache_location(environ)
    assert (
        _cache.configure_numba_cache({"RMAC_MJ_CACHE_DIR": str(tmp_path / "cache")}, package)
        == first
    )
    (package / _cache._KERNEL_DIRS[-1] / "kernels.py").write_text("def f():\n    return 2\n")
    second = _cache.configure_numba_cache({"RMAC_MJ_CACHE_DIR": str(tmp_path / "cache")}, package)
    assert second != first and second.startswith(str(tmp_path / "cache" / "numba"))
    chosen = {"NUMBA_CACHE_DIR": "/somewhere/else"}  # the user's choice is kept
    assert _cache.configure_numba_cache(chosen, package) is None
    assert chosen["NUMBA_CACHE_DIR"] == "/somewhere/else"


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
