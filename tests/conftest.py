"""Test-wide set-up, before numpy and mujoco are first imported: one BLAS kernel, the GL back end."""

import os
import sys

# The pinned results (tests/agents/test_rmac.py, tests/experiments/test_trajectory_pin.py) are exact to the last bit,
# and the last bit depends on the kernels OpenBLAS runs: by default those it picks for the CPU it
# finds (SkylakeX on an AVX-512 EPYC), or those OPENBLAS_CORETYPE names (Haswell on some machines
# here). The tests fix the kernel to one every x86-64 CPU with AVX2 runs, so they mean the same on
# every such machine; subprocesses inherit it.
if "numpy" in sys.modules and os.environ.get("OPENBLAS_CORETYPE") != "Haswell":
    raise RuntimeError(
        "numpy was imported before tests/conftest.py could set OPENBLAS_CORETYPE: "
        "run the tests with OPENBLAS_CORETYPE=Haswell"
    )
os.environ["OPENBLAS_CORETYPE"] = "Haswell"

import pytest  # noqa: E402

import rmac_mj  # noqa: E402,F401  (rmac_mj/__init__.py selects the GL back end; see rmac_mj._gl)


@pytest.fixture
def toy(monkeypatch):
    """The test-only domain ``toy``/``settle`` (n = 4, m = 2, 0.2 s trials), registered in
    ``rmac_mj.tasks`` for one test (see tests/toy_domain.py)."""
    import toy_domain

    toy_domain.register(monkeypatch)
    return toy_domain


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Tests that need an optional extra are skipped, naming it, when it is not installed: those
    marked ``baselines`` or run for a deep-RL baseline (a parameter naming one) without the
    [baselines] extra, those marked ``gymnasium`` without the [gymnasium] extra. A test run for a
    deep-RL baseline is ``slow`` (torch and SB3 load and train in it): marked before ``-m``
    selects."""
    import importlib.util

    from rmac_mj.agents import sb3

    skip_baselines = None if sb3.available() else pytest.mark.skip(reason=sb3.INSTALL_HINT)
    skip_gymnasium = (
        None
        if importlib.util.find_spec("gymnasium") is not None
        else pytest.mark.skip(
            reason='needs the [gymnasium] extra: pip install -c constraints.txt -e ".[gymnasium]"'
        )
    )
    for item in items:
        if skip_gymnasium is not None and item.get_closest_marker("gymnasium"):
            item.add_marker(skip_gymnasium)
        callspec = getattr(item, "callspec", None)
        if item.get_closest_marker("baselines") or (
            callspec is not None
            and any(
                isinstance(value, str) and value in sb3.BASELINES
                for value in callspec.params.values()
            )
        ):
            item.add_marker(pytest.mark.slow)
            if skip_baselines is not None:
                item.add_marker(skip_baselines)


def pytest_configure(config):
    """Say, in one line, when the tests start compiling the kernels (the first run only): else the
    suite is silent for about a minute while the first test that runs a learner waits for numba."""
    from numba.core import event

    from rmac_mj import _cache

    class _FirstCompile(event.Listener):
        said = False

        def on_start(self, ev):
            if self.said:
                return
            self.said = True
            reporter = config.pluginmanager.get_plugin("terminalreporter")
            capture = config.pluginmanager.get_plugin("capturemanager")
            if reporter is None or capture is None:
                return
            with capture.global_and_fixture_disabled():  # inside a test: past its output capture
                reporter.write_line(
                    f"compiling the learners' kernels, first run only (about half a minute "
                    f"on 2 cores; cached in {_cache.numba_cache_location()})"
                )

        def on_end(self, ev):
            pass

    event.register("numba:compile", _FirstCompile())
