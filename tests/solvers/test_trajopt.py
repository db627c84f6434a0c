"""The trajectory-optimisation reference (rmac_mj.solvers.trajopt) and the per-task reference registry."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rmac_mj import cli, tasks
from rmac_mj.solvers import (
    SOLVERS,
    TrajoptConfig,
    has_optimum,
    optimum_result,
    optimum_return,
    problem_identity,
    trajopt,
)

#: The pendulum's DP reference (docs/optimal.md): the greedy policy's return on the default grid.
PENDULUM_DP = -748.14
#: Stated tolerance of the coarse setting: one start (zero), loose stopping, coarse differences.
#: Measured: -748.66, 0.52 below the DP (the default setting gives the same).
PENDULUM_TOLERANCE = 2.0
_COARSE = TrajoptConfig(corner_starts=False, random_starts=0, tolerance=1e-6, fd_step=1e-5)
_TINY = TrajoptConfig(corner_starts=False, random_starts=0, max_iterations=1)


@pytest.mark.slow
def test_coarse_setting_recovers_the_pendulums_dp_value():
    result = trajopt.optimise(tasks.load("dc_pendulum", "swingup"), _COARSE)
    assert abs(result.simulated_return - PENDULUM_DP) <= PENDULUM_TOLERANCE
    # A real swing-up: up within 0.1 rad in about 1 s and kept there (hanging costs 4935 per trial).
    assert np.all(np.abs(result.states[40:90, 0]) < 0.1)
    assert result.problem["horizon"] == 100 and result.actions.shape == (100, 1)
    assert np.all(np.abs(result.actions) <= 3.0)


@pytest.mark.slow
def test_arm_reference_replayed_in_the_task_gives_the_same_return():
    result = trajopt.optimise(tasks.load("two_link_arm", "reach"), _COARSE)
    assert result.simulated_return > -40.0  # measured -37.65; doing nothing costs -296
    env = tasks.load("two_link_arm", "reach")
    env.reset()
    total, steps = 0.0, 0
    for u in result.actions:
        timestep = env.step(u)
        total += timestep.reward
        steps += 1
    assert timestep.last() and steps == 60
    np.testing.assert_allclose(total, result.simulated_return, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.sum(result.rewards), result.simulated_return, rtol=0, atol=1e-12)
    np.testing.assert_allclose(result.states[0], [-np.pi / 2, 0.0, np.pi / 2, 0.0], atol=1e-12)


def test_cache_round_trip_and_key(tmp_path):
    env = tasks.load("two_link_arm", "reach")
    arm = problem_identity("two_link_arm", "reach")
    first = trajopt.cached_optimise(env, arm, _TINY, cache_dir=tmp_path)
    assert not first.from_cache and len(list(tmp_path.glob("trajopt-*.json"))) == 1
    second = trajopt.cached_optimise(env, arm, _TINY, cache_dir=tmp_path)
    assert second.from_cache and second.simulated_return == first.simulated_return
    np.testing.assert_array_equal(second.actions, first.actions)
    assert second.problem["domain"] == "two_link_arm" and second.starts == first.starts
    key = trajopt.cache_key(env, arm, _TINY)
    assert key == trajopt.cache_key(env, arm, dataclasses.replace(_TINY, n_threads=1))
    assert key != trajopt.cache_key(env, arm, dataclasses.replace(_TINY, seed=1))
    assert key != trajopt.cache_key(tasks.load("dc_pendulum", "swingup"), arm, _TINY)
    assert key != trajopt.cache_key(env, {**arm, "task_kwargs": {"time_limit": 1.5}}, _TINY)


@pytest.mark.parametrize(
    "field, value",
    [
        ("max_iterations", 0),
        ("tolerance", 0.0),
        ("fd_step", 2.0),
        ("random_starts", -1),
        ("seed", 1.5),
    ],
)
def test_bad_config_names_the_field(field, value):
    with pytest.raises((ValueError, TypeError), match=field):
        TrajoptConfig(**{field: value})


def test_reference_registry_dispatches_and_rejects_unknown_tasks(tmp_path, monkeypatch):
    assert has_optimum("dc_pendulum", "swingup")
    assert has_optimum("two_link_arm", "reach")
    assert not has_optimum("dc_pendulum", "balance")
    with pytest.raises(ValueError, match="no near-optimal return for dc_pendulum/balance"):
        optimum_result("dc_pendulum", "balance")
    calls = []
    real = trajopt.cached_optimise

    def tiny(env, identity, config=None, cache_dir=None, refresh=False, announce=None):
        calls.append((identity["domain"], identity["task"]))
        return real(env, identity, _TINY, cache_dir=tmp_path, refresh=refresh)

    monkeypatch.setitem(SOLVERS, "trajectory optimisation", (tiny, TrajoptConfig))
    value = optimum_return("two_link_arm", "reach")
    assert calls == [("two_link_arm", "reach")] and np.isfinite(value)


@pytest.mark.slow
def test_cli_optimal_takes_domain_and_task(tmp_path, monkeypatch, capsys):
    real = trajopt.cached_optimise
    monkeypatch.setitem(
        SOLVERS,
        "trajectory optimisation",
        (
            lambda env, identity, config=None, cache_dir=None, refresh=False, announce=None: real(
                env, identity, _TINY, cache_dir=tmp_path, refresh=refresh
            ),
            TrajoptConfig,
        ),
    )
    assert cli.main(["optimal", "--domain", "two_link_arm", "--task", "reach"]) == 0
    assert "two_link_arm/reach: near-optimal return per trial" in capsys.readouterr().out
    assert cli.main(["optimal", "--domain", "two_link_arm", "--task", "spin"]) == 2
    assert "unknown task_name 'spin' for domain 'two_link_arm'" in capsys.readouterr().err
    assert cli.main(["optimal", "--domain", "dc_pendulum", "--task", "balance"]) == 2
    assert "no near-optimal return for dc_pendulum/balance" in capsys.readouterr().err


def test_the_old_module_path_keeps_its_public_names():
    from rmac_mj.solvers import TrajoptConfig, ilqr, trajopt_problem

    assert trajopt.TrajoptConfig is TrajoptConfig
    assert trajopt.Problem is trajopt_problem.Problem
    assert (trajopt.box_qp, trajopt.ilqr) == (ilqr.box_qp, ilqr.ilqr)
