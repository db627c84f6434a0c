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

#: Most processes the tests start on a machine with many cores (each imports numba, MuJoCo and, for
#: the baselines, torch: about 1 GB at its peak).
_MOST_WORKERS = 4


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config):
    """With pytest-xdist installed (the [dev] extra), the tests run in one process per core, at most
    ``_MOST_WORKERS``, unless the command line says ``-n``: on 2 cores the suite takes about half the
    time. Tests go where a core is free (``--dist worksteal``). ``-n 0`` runs them in this process."""
    if (
        config.pluginmanager.hasplugin("xdist")
        and config.option.numprocesses is None
        and not hasattr(config, "workerinput")  # not in a worker
        and not config.option.collectonly
        and not config.getoption("usepdb", False)
    ):
        config.option.numprocesses = "auto"
        if config.option.dist == "no":
            config.option.dist = "worksteal"


@pytest.hookimpl(optionalhook=True)  # xdist's hook: unknown without it
def pytest_xdist_auto_num_workers(config):
    """``-n auto``: one worker per core this process may use, at most ``_MOST_WORKERS``."""
    return max(1, min(len(os.sched_getaffinity(0)), _MOST_WORKERS))


#: The learners whose kernels numba compiles (the deep-RL baselines have none), in the order the
#: first worker compiles them; the next worker starts from the other end, and so on.
_COMPILED_LEARNERS = ("rmac", "s-ac", "mlac", "recommended", "s-ac-dyna")


@pytest.hookimpl(optionalhook=True)  # xdist's hook: unknown without it
def pytest_configure_node(node):
    """(xdist's controller, for each worker) Whether the kernel cache was empty when the tests
    started: then the workers compile the kernels once between them (``_kernels_compiled_once``)."""
    from rmac_mj import _cache

    node.workerinput["rmac_mj_cold_cache"] = _cache.numba_cache_is_empty()


@pytest.fixture(scope="session", autouse=True)
def _kernels_compiled_once(request, tmp_path_factory):
    """In a worker of a run that started with an empty kernel cache: compile the learners' kernels
    before the first test, each learner under a lock that every worker takes, the workers starting
    from different learners. A learner another worker compiled loads from the cache: so the kernels
    compile once, side by side, not once in each worker (about a minute of CPU per worker on 2
    cores). A warm cache, or a run in one process, does nothing here."""
    workerinput = getattr(request.config, "workerinput", None)
    if not workerinput or not workerinput.get("rmac_mj_cold_cache"):
        return
    import fcntl

    from rmac_mj.agents import make_agent
    from rmac_mj.experiments import Protocol
    from rmac_mj.rollout import action_space_of, run_trial, state_space_of

    index = int(workerinput["workerid"].removeprefix("gw"))
    order = _COMPILED_LEARNERS[::-1] if index % 2 else _COMPILED_LEARNERS
    order = order[index // 2 % len(order) :] + order[: index // 2 % len(order)]
    locks = tmp_path_factory.getbasetemp().parent  # one folder for the run's workers
    env = Protocol().make_environment(task_seed=0)
    for algorithm in order:
        with open(locks / f"compile-{algorithm}.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # released when closed
            agent = make_agent(algorithm, state_space_of(env), action_space_of(env), seed=0)
            run_trial(env, agent, learn=True)
            run_trial(env, agent, learn=False)


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
