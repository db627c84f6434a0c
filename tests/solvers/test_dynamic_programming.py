"""Tests of the near-optimal return (rmac_mj.solvers.dynamic_programming). All grids are coarse: a few seconds."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from rmac_mj import tasks
from rmac_mj.solvers import OptimalConfig, exploration_floor, problem_identity
from rmac_mj.solvers import dynamic_programming as optimal

# Coarse enough for a unit test; the converged default is about -748 (docs/optimal.md).
_COARSE = OptimalConfig(
    n_phi=91, n_phi_dot=61, n_actions=7, lookahead_actions=13, check_convergence=False
)
_FINER = OptimalConfig(
    n_phi=121, n_phi_dot=81, n_actions=13, lookahead_actions=25, check_convergence=False
)
_TINY = OptimalConfig(
    n_phi=24, n_phi_dot=15, n_actions=3, lookahead_actions=3, check_convergence=False
)


def swingup(steps: int | None = None, **task_kwargs):
    """The swing-up (``steps`` control steps per trial: a shorter problem) and its cache identity."""
    if steps is not None:
        task_kwargs["time_limit"] = steps * 0.03
    return (
        tasks.load("dc_pendulum", "swingup", task_kwargs=task_kwargs),
        problem_identity("dc_pendulum", "swingup", task_kwargs),
    )


def problem(steps: int | None = None) -> optimal.Problem:
    return optimal.Problem(swingup(steps)[0])


#: Stated tolerance of the grid-convergence test: the simulated returns of _COARSE and _FINER agree within
#: 1% (measured: -752.98 vs -749.41, 0.5%), and both lie within 1.5% of the default grid's -748.1.
_REL_TOL = 0.01


@pytest.fixture(scope="module")
def coarse_and_finer():
    env = swingup()[0]
    return optimal.solve(env, _COARSE), optimal.solve(env, _FINER)


@pytest.mark.slow
def test_coarse_grid_agrees_with_finer_grid_within_tolerance(coarse_and_finer):
    coarse, finer = coarse_and_finer
    assert abs(coarse.simulated_return - finer.simulated_return) <= _REL_TOL * abs(
        finer.simulated_return
    )
    # A swing-up must actually happen (hanging for 3 s costs 100 * 5 pi^2 = 4935) in about 1 s, as the
    # paper says, and the pendulum then stays up (the last steps are left out: with nothing after the
    # horizon to pay for, the policy lets it start to fall).
    for result in coarse_and_finer:
        assert -800.0 < result.simulated_return < -700.0
        assert np.all(np.abs(result.states[40:90, 0]) < 0.1)


@pytest.mark.slow
def test_dp_value_approaches_simulated_return_as_grid_refines(coarse_and_finer):
    coarse, finer = coarse_and_finer
    gap_coarse = abs(coarse.dp_value - coarse.simulated_return)
    gap_finer = abs(finer.dp_value - finer.simulated_return)
    assert gap_finer < gap_coarse
    assert gap_finer <= 0.02 * abs(finer.simulated_return)


@pytest.mark.slow
def test_greedy_actions_replayed_in_the_task_give_the_same_return(coarse_and_finer):
    """Same model, same reward timing (state before the step), same horizon as the learners' task."""
    result = coarse_and_finer[1]
    env = tasks.load("dc_pendulum", "swingup", task_kwargs={"random": 0})
    env.reset()
    total, steps = 0.0, 0
    for u in result.actions:
        timestep = env.step(np.array([u]))
        total += timestep.reward
        steps += 1
    assert timestep.last() and steps == result.problem["horizon"] == 100
    np.testing.assert_allclose(np.sum(result.rewards), result.simulated_return, rtol=0, atol=1e-9)
    np.testing.assert_allclose(total, result.simulated_return, rtol=0, atol=1e-9)


def test_one_step_horizon_is_exact():
    """V_0([pi, 0]) = max_u -5 pi^2 - u^2 = -5 pi^2: on a grid node, no interpolation error."""
    result = optimal.solve(swingup(steps=1)[0], _TINY)
    assert result.dp_value == pytest.approx(-5 * np.pi**2, abs=1e-4)  # V is stored as float32
    assert result.simulated_return == pytest.approx(-5 * np.pi**2, abs=1e-12)
    assert result.actions[0] == 0.0


def test_cache_round_trip_refresh_and_key(tmp_path):
    env, identity = swingup(steps=10)
    first = optimal.optimal_return(env, identity, _TINY, cache_dir=tmp_path)
    assert not first.from_cache
    files = list(tmp_path.glob("optimal-*.json"))
    assert len(files) == 1
    json.loads(files[0].read_text())  # plain JSON, readable without this package
    second = optimal.optimal_return(env, identity, _TINY, cache_dir=tmp_path)
    assert second.from_cache
    assert second.simulated_return == first.simulated_return and second.dp_value == first.dp_value
    assert second.config == first.config and second.problem == first.problem
    np.testing.assert_array_equal(second.states, first.states)
    assert not optimal.optimal_return(
        env, identity, _TINY, cache_dir=tmp_path, refresh=True
    ).from_cache
    # Threads change the speed, never the numbers: same entry. Anything else: a new one.
    assert optimal.optimal_return(
        env, identity, dataclasses.replace(_TINY, n_threads=1), cache_dir=tmp_path
    ).from_cache
    other = optimal.optimal_return(
        *swingup(steps=10, action_weights=2.0), _TINY, cache_dir=tmp_path
    )
    assert not other.from_cache and len(list(tmp_path.glob("optimal-*.json"))) == 2
    assert other.simulated_return < first.simulated_return  # the task's reward: P = 2 costs more
    env.physics.model.dof_damping[:] *= 1.5  # another model: another key
    assert optimal.cache_key(env, identity, _TINY) != files[0].name[len("optimal-") : -len(".json")]


def test_convergence_check_reports_a_coarser_solve():
    config = dataclasses.replace(_TINY, check_convergence=True)
    result = optimal.solve(swingup(steps=10)[0], config)
    assert result.coarse is not None
    assert (result.coarse.n_phi, result.coarse.n_phi_dot, result.coarse.n_actions) == (12, 8, 2)
    assert result.convergence_gap == abs(
        result.fine.simulated_return - result.coarse.simulated_return
    )
    assert f"{result.simulated_return:.2f}" in result.describe()
    assert "convergence gap" in result.describe()


@pytest.mark.parametrize(
    "field, value",
    [
        ("n_phi", 3),
        ("n_phi_dot", 2),
        ("n_actions", 1),
        ("lookahead_actions", 1),
        ("max_phi_dot", -1.0),
        ("max_phi_dot", float("nan")),
        ("n_threads", -1),
    ],
)
def test_bad_config_raises_value_error_naming_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        OptimalConfig(**{field: value})


def test_the_problem_comes_from_the_environment():
    """Horizon, action range and start are the task's; a random start has no single optimum."""
    grid = problem(steps=10)
    assert (grid.horizon, grid.n_substeps, grid.low, grid.high) == (10, 3, -3.0, 3.0)
    np.testing.assert_array_equal(grid.start_z, [np.pi, 0.0])
    with pytest.raises(ValueError, match="start state is random"):
        optimal.Problem(tasks.load("dc_pendulum", "balance", task_kwargs={"random": 0}))
    with pytest.raises(ValueError, match="one-joint model"):
        optimal.Problem(tasks.load("two_link_arm", "reach"))


def test_non_int_grid_size_raises_type_error():
    with pytest.raises(TypeError, match="n_phi"):
        OptimalConfig(n_phi=100.0)


_SMALL = OptimalConfig(
    n_phi=61, n_phi_dot=41, n_actions=5, lookahead_actions=9, check_convergence=False
)


@pytest.mark.slow
def test_noisy_rollouts_without_noise_are_the_greedy_rollout():
    grid = problem(steps=40)
    values = optimal.solve_values(_SMALL, grid)
    _, _, rewards = optimal.greedy_rollout(_SMALL, grid, values)
    quiet = exploration_floor.noisy_rollouts(
        _SMALL, grid, values, 0.0, 3, 0, 3, np.random.default_rng(0)
    )
    np.testing.assert_allclose(quiet, np.sum(rewards), rtol=0, atol=1e-9)
    noisy = exploration_floor.noisy_rollouts(
        _SMALL, grid, values, 1.0, 3, 0, 20, np.random.default_rng(0)
    )
    # Noise on a third of the steps makes every trial differ and costs reward on average.
    assert len(set(noisy.round(6))) == 20 and noisy.mean() < np.sum(rewards)
    every_step = exploration_floor.noisy_rollouts(
        _SMALL, grid, values, 1.0, 1, 0, 20, np.random.default_rng(0)
    )
    assert every_step.mean() < noisy.mean()


@pytest.mark.slow
def test_exploration_floor_is_cached_per_schedule(tmp_path):
    env, identity = swingup(steps=40)

    def floor(**kwargs):
        return exploration_floor.exploration_floor(
            env,
            identity,
            **{"sigma": 1.0, "period": 3, "rollouts": 8, **kwargs},
            config=_SMALL,
            cache_dir=tmp_path,
        )

    first, again = floor(), floor()
    assert not first.from_cache and again.from_cache
    assert again.mean == first.mean and np.array_equal(again.returns, first.returns)
    assert first.std == pytest.approx(np.std(first.returns, ddof=1))
    assert first.ci95[0] < first.mean < first.ci95[1]
    other = floor(sigma=2.0)
    assert not other.from_cache and other.mean != first.mean
    assert "every 3rd step" in first.describe() and "8 noisy trials" in first.describe()
    for bad in ({"sigma": -1.0}, {"period": 0}, {"phase": 3}, {"rollouts": 1}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            floor(**bad)


def test_the_old_module_path_keeps_its_public_names():
    from rmac_mj.solvers import OptimalConfig, dynamic_programming_grid

    assert optimal.OptimalConfig is OptimalConfig
    for name in (
        "Problem",
        "action_set",
        "state_grid",
        "simulate_transitions",
        "interpolate_value",
    ):
        assert getattr(optimal, name) is getattr(dynamic_programming_grid, name)
