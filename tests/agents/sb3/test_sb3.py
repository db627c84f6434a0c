"""The deep-RL baselines (rmac_mj.agents.sb3): faithful to SB3's own learn(), and run like every learner."""

import dataclasses
import inspect

import numpy as np
import pytest
from learners import quick_config

from rmac_mj.agents import agent_class, config_class, make_agent, sb3
from rmac_mj.agents.sb3 import driver  # patched: whether the extra is installed
from rmac_mj.experiments import RunOptions

ENV_ID = "rmac_mj/DCPendulum-Swingup-v0"


def _drive(agent, steps: int, seed: int) -> None:
    """The runner's loop on the dm-control task for ``steps`` control steps (the last trial may be
    left unfinished: SB3's learn() stops there too)."""
    from rmac_mj import tasks
    from rmac_mj.rollout import state_of

    env = tasks.load("dc_pendulum", "swingup", task_kwargs={"random": seed})
    keys = env.task.learner_state.keys
    done = 0
    while done < steps:
        u = agent.start(state_of(env.reset().observation, keys))
        while True:
            timestep = env.step(u)
            done += 1
            x = state_of(timestep.observation, keys)
            if timestep.last():
                agent.stop(timestep.reward, x)
                break
            u = agent.step(timestep.reward, x)
            if done == steps:
                break


# Each case: the learner, overrides for a short run (the same for both sides), the steps learned.
# SAC and TD3 learn 160 steps: SB3's 100 random ones, then 60 updates, across the first trial's end (a
# time-out, bootstrapped); their networks are narrowed for speed (the defaults are checked below).
# PPO's rollouts of 40 steps end once inside a trial and once exactly at a trial's end.
CASES = [
    ("sb3-sac", {"net_arch": (64, 64), "batch_size": 64}, 160),
    ("sb3-td3", {"net_arch": (64, 64), "batch_size": 64}, 160),
    ("sb3-ppo", {"n_steps": 40, "batch_size": 20, "n_epochs": 2}, 200),
    ("sb3-crossq", {"net_arch": (64, 64), "critic_net_arch": (64, 64), "batch_size": 64}, 160),
]


@pytest.mark.slow
@pytest.mark.baselines
@pytest.mark.parametrize("algorithm, overrides, steps", CASES)
def test_learning_step_by_step_equals_sb3s_own_learn(algorithm, overrides, steps):
    """Same seed, same environment: the learner's parameters equal those of SB3's model.learn() on
    the suite's Gymnasium environment, bit for bit."""
    import importlib

    import gymnasium
    import torch
    from stable_baselines3.common.noise import NormalActionNoise

    from rmac_mj import tasks  # noqa: F401  (registers the Gymnasium ids)
    from rmac_mj.rollout import action_space_of, state_space_of

    env = tasks.load("dc_pendulum", "swingup")
    agent = make_agent(
        algorithm,
        state_space_of(env),
        action_space_of(env),
        config=overrides,
        seed=np.random.default_rng(7),
    )
    sb3_overrides = dict(overrides)
    if "critic_net_arch" in sb3_overrides:  # CrossQ: the actor's and the critics' apart
        actor, critic = sb3_overrides.pop("net_arch"), sb3_overrides.pop("critic_net_arch")
        sb3_overrides["policy_kwargs"] = {"net_arch": {"pi": list(actor), "qf": list(critic)}}
    elif "net_arch" in sb3_overrides:
        sb3_overrides["policy_kwargs"] = {"net_arch": list(sb3_overrides.pop("net_arch"))}
    if algorithm == "sb3-td3":  # SB3's TD3 takes the exploration noise as an object
        sigma = sb3_overrides.pop("action_noise", agent.config.action_noise)
        sb3_overrides["action_noise"] = (
            NormalActionNoise(np.zeros(1), sigma * np.ones(1)) if sigma else None
        )
    reference = getattr(importlib.import_module(agent.sb3_package), agent.sb3_class)(
        "MlpPolicy", gymnasium.make(ENV_ID), seed=agent.sb3_seed_, device="cpu", **sb3_overrides
    )
    reference.learn(total_timesteps=steps)
    _drive(agent, steps, seed=agent.sb3_seed_)

    learned, expected = agent.model.policy.state_dict(), reference.policy.state_dict()
    assert sorted(learned) == sorted(expected)
    for name in expected:
        assert torch.equal(learned[name], expected[name]), name
    assert agent.model.num_timesteps == reference.num_timesteps == steps
    assert agent.model._n_updates == reference._n_updates > 0


def _pendulum_spaces():
    from rmac_mj import tasks
    from rmac_mj.rollout import action_space_of, state_space_of

    env = tasks.load("dc_pendulum", "swingup")
    return state_space_of(env), action_space_of(env)


@pytest.mark.baselines
@pytest.mark.parametrize("algorithm", sb3.BASELINES)
def test_the_defaults_are_sb3s(algorithm):
    """Every hyperparameter SB3's constructor takes defaults to SB3's value, and the networks to SB3's
    default architecture; the exceptions are TD3's exploration noise and CrossQ's critic width
    (their configs say why)."""
    import importlib

    learner = agent_class(algorithm)
    sb3_class = getattr(importlib.import_module(learner.sb3_package), learner.sb3_class)
    defaults = {name: p.default for name, p in inspect.signature(sb3_class).parameters.items()}
    config = config_class(algorithm)()
    shared = [f.name for f in dataclasses.fields(config) if f.name in defaults]
    assert len(shared) >= 8
    for name in shared:
        if (algorithm, name) == ("sb3-td3", "action_noise"):
            assert defaults[name] is None and config.action_noise == 0.1
            continue
        assert getattr(config, name) == defaults[name], name
    agent = make_agent(algorithm, *_pendulum_spaces(), seed=0)
    model = sb3_class("MlpPolicy", agent.model.env, device="cpu")  # SB3 with no arguments at all
    if algorithm == "sb3-ppo":
        assert model.policy.net_arch == {"pi": list(config.net_arch), "vf": list(config.net_arch)}
        assert float(model.policy.log_std.detach()[0]) == config.log_std_init
    elif algorithm == "sb3-crossq":
        assert model.policy.net_arch == {"pi": list(config.net_arch), "qf": [1024, 1024]}
        assert config.critic_net_arch == (256, 256)  # narrowed: the config says why
        for name, value in model.policy.batch_norm_params.items():
            assert value == getattr(config, name, value), name
    else:
        assert model.actor.net_arch == list(config.net_arch)
    if algorithm != "sb3-crossq":  # CrossQ's layer names are the same; its widths are not
        assert sorted(model.policy.state_dict()) == sorted(agent.model.policy.state_dict())


@pytest.mark.baselines
def test_network_input_is_the_gymnasium_observation():
    """The networks see what a Gymnasium user of the suite observes."""
    import gymnasium

    from rmac_mj import tasks
    from rmac_mj.rollout import state_of

    env = gymnasium.make("rmac_mj/TwoLinkArm-Reach-v0")
    observation, _ = env.reset(seed=1)
    dm_env = env.unwrapped.dm_env
    x = state_of(
        dm_env.physics and dm_env.task.get_observation(dm_env.physics), dm_env.task.learner_state
    )
    periodic = np.asarray(dm_env.task.learner_state.periodic)
    np.testing.assert_array_equal(sb3.network_input(x, periodic), observation.astype(np.float32))
    assert tasks  # the suite's ids are registered on import


def test_without_the_extra_the_learners_name_it(monkeypatch):  # runs without the extra too
    monkeypatch.setattr(driver, "available", lambda *package: False)
    with pytest.raises(ImportError, match=r"\[baselines\]"):
        make_agent("sb3-sac", *_pendulum_spaces(), seed=0)
    assert config_class("sb3-sac")().learning_rate == 3e-4  # the configs need no torch


@pytest.mark.parametrize(
    "args",
    [
        ["panel", "--algorithms", "sb3-sac", "--trials", "1"],
        ["panel", "--resume"],  # its default learners hold sb3-sac
        ["reproduce", "--algorithms", "s-ac,sb3-ppo", "--trials", "1"],
    ],
)
def test_without_the_extra_a_run_of_a_baseline_is_refused_naming_it(
    tmp_path, monkeypatch, capsys, args
):  # runs without the extra too
    from rmac_mj.cli import main
    from rmac_mj.errors import EXIT_BAD_INPUT

    monkeypatch.setattr(driver, "available", lambda *package: False)
    code = main([*args, "--out", str(tmp_path / "out")])
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == EXIT_BAD_INPUT and len(lines) == 1, lines
    assert "need the [baselines] extra" in lines[0] and "internal error" not in lines[0]
    assert not (tmp_path / "out").exists()


TINY = dict(
    algorithms=("sb3-sac",),
    experiments=2,
    trials=2,
    evaluate_every=1,
    snapshot_trials=(1,),
    agent_configs={"sb3-sac": quick_config("sb3-sac")},
)


@pytest.mark.slow
@pytest.mark.baselines
def test_reproduce_runs_a_baseline_and_resumes_it_alike(tmp_path):
    """A tiny rmac-mj reproduce of sb3-sac: an interrupted run finished with resume has the curves of
    an uninterrupted one (serial equals parallel: tests/experiments/test_runner.py), and the last snapshot
    rebuilds the learner."""
    from rmac_mj.experiments import Protocol, build_experiment, run_protocol
    from rmac_mj.results import ResultStore, load_snapshot
    from rmac_mj.rollout import run_trial

    protocol, store = Protocol(**TINY), ResultStore(tmp_path)
    summary = run_protocol(protocol, tmp_path, RunOptions(jobs=1, progress=False, figures=False))
    assert len(summary["sb3-sac"]["final_return_per_experiment"]) == 2
    expected = store.load_curves("sb3-sac", 2)
    assert not np.array_equal(expected.returns[0], expected.returns[1])  # independent experiments
    assert np.all(expected.cpu_times > 0)
    store.curve_path("sb3-sac", 1).unlink()  # as if killed before the last experiment
    np.random.seed(123)  # whatever the process's global generators hold: the learner has its own
    run_protocol(protocol, tmp_path, RunOptions(jobs=1, resume=True, progress=False, figures=False))
    resumed = store.load_curves("sb3-sac", 2)
    np.testing.assert_array_equal(resumed.returns, expected.returns)
    np.testing.assert_array_equal(resumed.greedy_returns, expected.greedy_returns)
    agent, _ = load_snapshot(store.snapshot_path("sb3-sac", 0, 2))
    env = build_experiment(protocol, "sb3-sac", 0).env
    assert run_trial(env, agent, learn=False) == expected.greedy_returns[0, -1]
