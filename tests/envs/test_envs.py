"""Outside environments (rmac_mj.envs): every SPEC form end to end, the learner state inferred or
refused, terminations against truncations."""

from __future__ import annotations

import math
import textwrap

import dm_env
import numpy as np
import pytest
from dm_env import specs

gymnasium = pytest.importorskip(
    "gymnasium",
    reason='needs the [gymnasium] extra: pip install -c constraints.txt -e ".[gymnasium]"',
)

from rmac_mj import envs
from rmac_mj.agents import StandardACConfig, make_agent
from rmac_mj.envs import ObservationMap

# The inference's own steps, tested one by one.
from rmac_mj.envs.observation_map import layout_of_dm_env
from rmac_mj.envs.observations import inferred_entries
from rmac_mj.rollout import (
    action_space_of,
    run_trial,
    state_of,
    state_space_of,
    steps_per_trial,
    trial_seconds,
)

SMALL_SAC = StandardACConfig(backend="numpy")


# ----------------------------------------------------------------------------------------------------
# A user's own environments, defined here and loaded by SPEC (this file's path:function).


class Slider(dm_env.Environment):
    """A user's dm_env: a mass on a rail of +-1 m, pushed by u in [-1, 1] N for 0.1 s a step; it
    terminates off the rail. Observation: position and velocity, bounded by their specs. Reward:
    -x^2 while on the rail, -10 on the step that leaves it."""

    def __init__(self, start: float = 0.0, seed: int | None = None) -> None:
        self.start, self.rng = start, np.random.default_rng(seed)
        self.x = self.v = 0.0

    def reset(self):
        self.x, self.v = self.start + 0.01 * self.rng.standard_normal(), 0.0
        return dm_env.restart(self._observation())

    def step(self, action):
        self.v += 0.1 * float(np.asarray(action).reshape(-1)[0])
        self.x += 0.1 * self.v
        if abs(self.x) > 1.0:
            return dm_env.termination(-10.0, self._observation())
        return dm_env.transition(-(self.x**2), self._observation())

    def _observation(self):
        return {"position": np.array([self.x]), "velocity": np.array([self.v])}

    def observation_spec(self):
        return {
            "position": specs.BoundedArray((1,), float, -1.0, 1.0, name="position"),
            "velocity": specs.BoundedArray((1,), float, -2.0, 2.0, name="velocity"),
        }

    def action_spec(self):
        return specs.BoundedArray((1,), float, -1.0, 1.0)


def make_slider(start: float = 0.0, seed: int | None = None) -> Slider:
    return Slider(start, seed)


class Wheel(gymnasium.Env):
    """A user's Gymnasium env: a wheel turned by torque, observed as (cos, sin, speed)."""

    def __init__(self, steps: int = 12):
        self.observation_space = gymnasium.spaces.Box(
            np.array([-1, -1, -4.0]), np.array([1, 1, 4.0]), dtype=np.float64
        )
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)
        self.steps, self.dt = steps, 0.05
        self.angle = self.speed = 0.0
        self.k = 0

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.angle, self.speed, self.k = float(self.np_random.uniform(-np.pi, np.pi)), 0.0, 0
        return self._observation(), {}

    def step(self, action):
        self.speed = float(np.clip(self.speed + self.dt * 10 * float(action[0]), -4, 4))
        self.angle += self.dt * self.speed
        self.k += 1
        return self._observation(), -abs(self.speed), False, self.k >= self.steps, {}

    def _observation(self):
        return np.array([math.cos(self.angle), math.sin(self.angle), self.speed])


class DoubleCos(Slider):
    """Ambiguous: 'angles' holds (cos a, sin a, cos a), so element 1 pairs with 0 and with 2."""

    def _observation(self):
        return {"angles": np.array([math.cos(self.x), math.sin(self.x), math.cos(self.x)])}

    def observation_spec(self):
        return {"angles": specs.BoundedArray((3,), float, -1.0, 1.0, name="angles")}


def make_wheel(steps: int = 12) -> Wheel:
    return Wheel(steps)


def make_double_cos() -> DoubleCos:
    return DoubleCos(start=0.5)


HERE = __file__


def tiny_run(env) -> list[float]:
    agent = make_agent("s-ac", state_space_of(env), action_space_of(env), config=SMALL_SAC, seed=0)
    returns = [run_trial(env, agent) for _ in range(2)]
    returns.append(run_trial(env, agent, learn=False))
    assert all(np.isfinite(returns))
    return returns


# ----------------------------------------------------------------------------------------------------
# Each SPEC form end to end.


def test_gymnasium_pendulum_is_inferred_and_runs():
    env = envs.load("gymnasium:Pendulum-v1", {"max_episode_steps": 15}, seed=3)
    ls = env.learner_state
    assert ls.keys == ("atan2(observation[1], observation[0])", "observation[2]")
    assert ls.periodic == (True, False) and ls.low == (-math.pi, -8.0) and ls.high == (math.pi, 8.0)
    assert steps_per_trial(env) == 15 and trial_seconds(env) == pytest.approx(0.75)
    tiny_run(env)


def test_gymnasium_seed_gives_the_same_starts():
    starts = [
        [state_of(e.reset().observation, e.learner_state) for _ in range(3)]
        for e in (envs.load("gymnasium:Pendulum-v1", seed=7) for _ in range(2))
    ]
    np.testing.assert_array_equal(starts[0], starts[1])
    assert not np.array_equal(starts[0][0], starts[0][1])  # later resets continue the stream


def test_dm_control_with_declared_bounds_and_action_repeat():
    bounds = {"position[0]": [-1.8, 1.8], "velocity[0]": [-5, 5], "velocity[1]": [-20, 20]}
    env = envs.load(
        "dm_control:cartpole/swingup",
        {"time_limit": 0.2},
        seed=0,
        learner_state={"bounds": bounds},
        action_repeat=2,
    )
    assert env.learner_state.keys == (
        "position[0]",
        "atan2(position[2], position[1])",
        "velocity[0]",
        "velocity[1]",
    )
    assert env.learner_state.periodic == (False, True, False, False)
    assert steps_per_trial(env) == 10 and env.control_timestep() == pytest.approx(0.02)
    # The angle is the pole's, pi when it hangs down.
    x = state_of(env.reset().observation, env.learner_state)
    assert abs(abs(x[1]) - math.pi) < 0.05
    tiny_run(env)


def test_factory_from_a_file_returning_dm_env_with_its_seed():
    env = envs.load(
        f"{HERE}:make_slider", {"start": 0.5}, seed=4, trial_steps=6, control_timestep=0.1
    )
    assert env.learner_state.keys == ("position", "velocity")
    assert steps_per_trial(env) == 6 and trial_seconds(env) == pytest.approx(0.6)
    again = envs.load(
        f"{HERE}:make_slider", {"start": 0.5}, seed=4, trial_steps=6, control_timestep=0.1
    )
    assert env.reset().observation["position"] == again.reset().observation["position"]
    tiny_run(env)


def test_factory_from_a_module_returning_gymnasium(tmp_path, monkeypatch):
    (tmp_path / "my_tasks.py").write_text(
        textwrap.dedent(f"""
        import importlib.util
        spec = importlib.util.spec_from_file_location("source", {HERE!r})
        source = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(source)
        def wheel(steps=12):
            return source.Wheel(steps)
    """)
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    env = envs.load("my_tasks:wheel", {"steps": 8}, seed=1)
    assert env.learner_state.keys == ("atan2(observation[1], observation[0])", "observation[2]")
    assert steps_per_trial(env) == 8 and env.control_timestep() == 0.05
    tiny_run(env)


def test_a_task_files_folder_is_importable_and_a_wrong_factory_name_gets_the_closest(
    tmp_path, monkeypatch
):
    """A task file imports the module beside it, as ``python file.py`` would, wherever the run
    starts (here and in a fresh process, as a worker is)."""
    import subprocess
    import sys

    monkeypatch.setattr(sys, "path", list(sys.path))  # the loader puts the folder first
    folder = tmp_path / "my folder"
    folder.mkdir()
    (folder / "h39_dot_model.py").write_text(_DRAWN)
    (folder / "dot_task.py").write_text(
        "import gymnasium\n"
        "from h39_dot_model import Dot\n\n\n"
        "def make():\n"
        "    return gymnasium.wrappers.TimeLimit(Dot(), max_episode_steps=5)\n"
    )
    spec = f"{folder / 'dot_task.py'}:make"
    env = envs.load(spec, seed=0)
    assert steps_per_trial(env) == 5 and sys.path[0] == str(folder)
    code = f"from rmac_mj import envs; print(envs.load({spec!r}, seed=0).trial_seconds)"
    out = subprocess.run(
        [sys.executable, "-c", code], cwd="/", capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == "0.5"
    with pytest.raises(ValueError, match=r"has no 'mak' \(did you mean 'make'\?\)"):
        envs.load(f"{folder / 'dot_task.py'}:mak")
    with pytest.raises(ValueError, match=r"has no 'zzz'$"):  # nothing close: nothing guessed
        envs.load(f"{folder / 'dot_task.py'}:zzz")


_LABELLED = """
import gymnasium
import numpy as np


class Labelled(gymnasium.Env):
    learner_state = {"labels": ["position [m]", "velocity [m/s]"], "action_labels": ["force [N]"]}

    def __init__(self, action_high=1.0):
        self.observation_space = gymnasium.spaces.Box(
            np.array([-3.0, -5.0], dtype=np.float32), np.array([3.0, 5.0], dtype=np.float32)
        )
        self.action_space = gymnasium.spaces.Box(-1.0, np.float32(action_high), (1,))
        self.dt = 0.05

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return np.zeros(2, dtype=np.float32), {}

    def step(self, action):
        return np.zeros(2, dtype=np.float32), 0.0, False, False, {}


def make(**kwargs):
    return gymnasium.wrappers.TimeLimit(Labelled(**kwargs), max_episode_steps=5)
"""


def test_an_environment_labels_its_dimensions_and_messages_name_them(tmp_path):
    """Issue 39: an environment's own ``learner_state`` (a dict of the declarable fields) labels
    the policy figure's axes, a user's declaration goes over it field by field; a bad box is named
    by its dimension and label with plain numbers."""
    from rmac_mj.tasks import LearnerStateSpec

    (tmp_path / "labelled.py").write_text(_LABELLED)
    spec = f"{tmp_path / 'labelled.py'}:make"
    env = envs.load(spec, seed=0)
    assert env.learner_state.labels == ("position [m]", "velocity [m/s]")
    assert env.learner_state.action_labels == ("force [N]",)
    mine = envs.load(spec, seed=0, learner_state={"bounds": {"observation[0]": [-2, 2]}})
    assert mine.learner_state.labels == ("position [m]", "velocity [m/s]")
    assert (mine.learner_state.low[0], mine.learner_state.high[0]) == (-2.0, 2.0)
    with pytest.raises(
        ValueError, match=r"must be bounded.*: dimension 0, u\[0\]: low -1, high -1$"
    ):
        envs.load(spec, {"action_high": -1.0})
    with pytest.raises(ValueError) as refused:
        LearnerStateSpec(
            keys=("p", "v"), low=(np.float64(3.0), -1.0), high=(np.float64(-3.0), 1.0),
            periodic=(False, False), labels=("position [m]", "velocity [m/s]"),
            input_weights=(1.0, 1.0), action_input_weights=(1.0,), action_labels=("u",),
        )  # fmt: skip
    assert str(refused.value).endswith("dimension 0, position [m]: low 3, high -3")
    assert "np.float64" not in str(refused.value)


def make_suite_pendulum(seed=None):
    """A factory returning a dm-control task that declares its own learner_state."""
    from rmac_mj import tasks

    return tasks.load("dc_pendulum", "swingup", task_kwargs={"random": seed})


def test_a_task_that_declares_its_learner_state_is_taken_at_its_word():
    from rmac_mj import tasks

    env = envs.load(f"{HERE}:make_suite_pendulum", seed=0)
    assert env.learner_state == tasks.load("dc_pendulum", "swingup").task.learner_state


# ----------------------------------------------------------------------------------------------------
# The learner state: folding, refusals.


def test_cos_sin_folding_recovers_the_angle():
    angles = np.random.default_rng(0).uniform(-np.pi, np.pi, 50)
    spec = {"position": specs.Array((3,), float), "velocity": specs.Array((1,), float)}
    layout = layout_of_dm_env(spec)
    samples = np.stack([[0.3, np.cos(a), np.sin(a), 2.0] for a in angles])
    entries = inferred_entries(layout, samples)
    assert entries == ["position[0]", "atan2(position[2], position[1])", "velocity"]
    fold = ObservationMap(entries, layout)
    for a in angles:
        x = fold({"position": np.array([0.3, np.cos(a), np.sin(a)]), "velocity": np.array([2.0])})
        np.testing.assert_allclose(x, [0.3, a, 2.0], atol=1e-12)


def test_pendulum_v1_angle_is_the_simulators():
    env = envs.load("gymnasium:Pendulum-v1", seed=5)
    env.reset()
    for u in (2.0, -1.0, 0.5):
        x = state_of(env.step(np.array([u])).observation, env.learner_state)
        theta, theta_dot = env.base.env.unwrapped.state
        assert x[0] == pytest.approx((theta + np.pi) % (2 * np.pi) - np.pi, abs=1e-6)
        assert x[1] == pytest.approx(theta_dot, abs=1e-5)


def test_an_ambiguous_observation_is_refused_naming_the_key():
    with pytest.raises(
        ValueError, match=r"observation 'angles' is ambiguous.*angles\[0\], angles\[1\]"
    ):
        envs.load(f"{HERE}:make_double_cos", trial_steps=5, control_timestep=0.1)
    # Declared, it runs.
    env = envs.load(
        f"{HERE}:make_double_cos",
        trial_steps=5,
        control_timestep=0.1,
        learner_state={"keys": ["atan2(angles[1], angles[0])"]},
    )
    assert env.learner_state.periodic == (True,)


@pytest.mark.parametrize(
    "spec, kwargs, message",
    [
        (
            f"{HERE}:make_slider",
            {},
            r"does not say its time step \(no dt\); give --control-timestep S.*\(control_timestep",
        ),
        ("gymnasium:CartPole-v1", {}, r"action space is Discrete"),
        ("gymnasium:NoSuchEnv-v0", {}, r"gymnasium:NoSuchEnv-v0"),
        ("dm_control:cartpole/swingupp", {}, r"its tasks: .*cartpole/swingup"),
        ("no_such_module:make", {}, r"cannot import 'no_such_module'"),
        ("gymnasium:Pendulum-v1", {"learner_state": {"bound": {}}}, r"did you mean 'bounds'"),
        (
            "gymnasium:Pendulum-v1",
            {"learner_state": {"bounds": {"theta": [0, 1]}}},
            r"names 'theta'.*x = \[atan2",
        ),
    ],
)
def test_what_is_missing_or_wrong_is_refused_in_one_line(spec, kwargs, message):
    with pytest.raises(ValueError, match=message) as error:
        envs.load(spec, seed=0, **kwargs)
    assert "\n" not in str(error.value)


@pytest.mark.slow
def test_a_box_the_specs_do_not_give_is_measured_and_a_declared_one_wins():
    spec = envs.EnvSpec(
        "dm_control:cartpole/swingup",
        action_repeat=5,
        learner_state={"bounds": {"position[0]": [-1.8, 1.8]}},
    ).resolve()
    state = spec.learner_state
    assert set(spec.measured_bounds) == {"velocity[0]", "velocity[1]"}
    assert (state.low[0], state.high[0]) == (-1.8, 1.8)  # declared
    # random actions held for 5 steps swing the pole at several rad/s; the margin widens what they
    # reached, so the box holds every state they visited
    low, high = spec.measured_bounds["velocity[1]"]
    assert low < -5.0 and high > 5.0 and (state.low[3], state.high[3]) == (low, high)
    # the same seed, the same box: every worker and every resume sees one learner state
    assert (
        envs.EnvSpec(
            "dm_control:cartpole/swingup",
            action_repeat=5,
            learner_state={"bounds": {"position[0]": [-1.8, 1.8]}},
        )
        .resolve()
        .measured_bounds
        == spec.measured_bounds
    )
    # the measured box travels with the spec (snapshots, config.json) and rebuilds it as it was
    again = envs.EnvSpec(**spec.as_dict()).resolve()
    assert (
        again.measured_bounds == spec.measured_bounds and again.learner_state == spec.learner_state
    )


def test_measured_box_widens_the_visited_range_about_its_centre():
    from rmac_mj.envs.observations import measured_box

    low, high = measured_box(np.array([[0.0, 3.0], [2.0, 3.0]]), margin=0.5)
    np.testing.assert_allclose(low, [-0.5, 2.0])  # [0, 2] half-width 1 -> 1.5; a still one: +-1
    np.testing.assert_allclose(high, [2.5, 4.0])


def test_without_a_measurement_an_unbounded_dimension_is_refused_naming_it():
    from dm_env import specs

    from rmac_mj.envs import infer_learner_state
    from rmac_mj.envs.observation_map import layout_of_dm_env

    layout = layout_of_dm_env({"velocity": specs.Array((1,), float, "velocity")})
    with pytest.raises(
        ValueError,
        match=r"no finite bounds for velocity .*learner_state.bounds = "
        r"\{\"velocity\" = \[LOW, HIGH\]\}",
    ):
        infer_learner_state(layout, np.zeros((1, 1)), np.array([-1.0]), np.array([1.0]))


def test_slider_needs_a_time_limit():
    with pytest.raises(
        ValueError,
        match=r"has no time limit and does not truncate its episodes; give --trial-steps N \(trial_steps",
    ):
        envs.load(f"{HERE}:make_slider", control_timestep=0.1)


# ----------------------------------------------------------------------------------------------------
# Terminations end a trial with discount 0; truncations and time limits with discount 1.


def test_termination_and_truncation_reach_the_trial_loop():
    env = envs.load(
        f"{HERE}:make_slider", {"start": 0.9}, seed=0, trial_steps=50, control_timestep=0.1
    )
    env.reset()
    steps, timestep = 0, None
    while timestep is None or not timestep.last():
        timestep = env.step(np.array([1.0]))
        steps += 1
    assert steps < 50 and timestep.discount == 0.0 and timestep.reward == -10.0
    wheel = envs.load(f"{HERE}:make_wheel", seed=0)
    wheel.reset()
    for _ in range(12):
        timestep = wheel.step(np.array([0.1]))
    assert timestep.last() and timestep.discount == 1.0


def test_run_trial_tells_the_learner_a_termination_from_a_time_limit(monkeypatch):
    from rmac_mj.agents import Agent

    told, stop = [], Agent.stop
    monkeypatch.setattr(
        Agent,
        "stop",
        lambda self, reward, x, terminal=False: (
            told.append(terminal),
            stop(self, reward, x, terminal),
        )[1],
    )
    slider = envs.load(
        f"{HERE}:make_slider", {"start": 0.95}, seed=0, trial_steps=50, control_timestep=0.1
    )
    wheel = envs.load(f"{HERE}:make_wheel", seed=0)
    for env in (slider, wheel):
        agent = make_agent(
            "s-ac", state_space_of(env), action_space_of(env), config=SMALL_SAC, seed=0
        )
        while not told or (env is wheel and len(told) < 2):
            run_trial(env, agent)
            if env is slider and not told[-1]:
                told.clear()  # this trial stayed on the rail until its time limit: try again
    assert told[0] is True and told[-1] is False


@pytest.mark.parametrize("name", ["rmac", "s-ac", "mlac"])
def test_a_terminal_states_value_is_not_bootstrapped(name):
    """Two identical learners whose critic holds V(x_1) well below 0 learn x_0 -> x_1 with reward 0.
    Told x_1 is terminal, the TD error is 0 - V(x_0); told it is a time limit, gamma V(x_1) - V(x_0):
    the terminal one ends with the higher V(x_0), by about alpha_c gamma |V(x_1)|."""
    env = envs.load(f"{HERE}:make_slider", seed=0, trial_steps=10, control_timestep=0.1)
    x0, x1 = np.array([-0.8, 0.0]), np.array([0.8, 0.0])
    config = {"action_cost": 0.0} if name == "mlac" else {}

    def learner_that_fears_x1():
        agent = make_agent(name, state_space_of(env), action_space_of(env), config=config, seed=0)
        for _ in range(40):  # V(x_1) -> -10: x_1 is followed by -10 and a terminal state
            agent.start(x1)
            agent.stop(-10.0, x1 + np.array([0.0, 0.5]), terminal=True)
        return agent

    terminal, time_limit = learner_that_fears_x1(), learner_that_fears_x1()
    v1 = terminal.value(x1)
    assert v1 < -3.0 and time_limit.value(x1) == v1 and time_limit.value(x0) == terminal.value(x0)
    for agent, is_terminal in ((terminal, True), (time_limit, False)):
        agent.start(x0)
        agent.stop(0.0, x1, terminal=is_terminal)
    assert terminal.value(x0) > time_limit.value(x0) + 0.01 * abs(v1)


def test_action_repeat_sums_the_rewards():
    one = envs.load(f"{HERE}:make_slider", seed=2, trial_steps=4, control_timestep=0.1)
    two = envs.load(
        f"{HERE}:make_slider", seed=2, trial_steps=2, control_timestep=0.1, action_repeat=2
    )
    one.reset(), two.reset()
    rewards = [one.step(np.array([0.5])).reward for _ in range(4)]
    repeated = [two.step(np.array([0.5])).reward for _ in range(2)]
    np.testing.assert_allclose(repeated, [rewards[0] + rewards[1], rewards[2] + rewards[3]])
    assert two.control_timestep() == pytest.approx(0.2)


# ----------------------------------------------------------------------------------------------------
# The runner: a protocol on an outside environment, its snapshots, its sweep file.


def tiny_protocol(**fields):
    from rmac_mj.experiments import Protocol

    return Protocol(
        **{
            "algorithms": ("s-ac",),
            "experiments": 1,
            "trials": 2,
            "evaluate_every": 1,
            "snapshot_trials": (),
            "agent_configs": {"s-ac": {"backend": "numpy"}},
            **fields,
        }
    )


def test_a_protocol_runs_an_outside_environment_and_its_snapshot_acts_in_it(tmp_path):
    from rmac_mj.experiments import RunOptions, run_protocol
    from rmac_mj.results import load_snapshot, snapshot_environment

    protocol = tiny_protocol(
        env="gymnasium:Pendulum-v1",
        task_kwargs={"max_episode_steps": 10},
        learner_state={"action_cost": [0.001]},
        evaluate_starts=3,
    )
    assert (protocol.domain, protocol.task) == (None, None)
    assert protocol.environment_name == "gymnasium:Pendulum-v1"
    summary = run_protocol(protocol, tmp_path, RunOptions(jobs=1, progress=False, figures=False))
    assert summary["trial_seconds"] == pytest.approx(0.5)
    assert list(summary["learner_state"]["keys"]) == [
        "atan2(observation[1], observation[0])",
        "observation[2]",
    ]
    assert list(summary["learner_state"]["action_cost"]) == [0.001]
    agent, meta = load_snapshot(tmp_path / "snapshots" / "s-ac" / "exp_000" / "trial_0002.npz")
    env = snapshot_environment(agent, meta)
    assert env.learner_state.keys == tuple(summary["learner_state"]["keys"])
    assert np.isfinite(run_trial(env, agent, learn=False))


def test_an_evaluation_is_the_mean_over_the_same_seeded_starts():
    from rmac_mj.experiments import build_experiment
    from rmac_mj.experiments.experiment import (
        evaluation,  # the greedy trials' environment, internal
    )

    protocol = tiny_protocol(
        env="gymnasium:Pendulum-v1", task_kwargs={"max_episode_steps": 10}, evaluate_starts=4
    )
    experiment = build_experiment(protocol, "s-ac", 0)
    evaluate = evaluation(protocol, 0)
    first = evaluate(experiment.env, experiment.agent)
    assert evaluate(experiment.env, experiment.agent) == first  # the same starts, nothing learned
    assert (
        evaluation(protocol, 1)(experiment.env, experiment.agent) != first
    )  # another experiment's


def test_env_fields_need_env_and_exclude_a_suite_task():
    with pytest.raises(
        ValueError,
        match=r"action_repeat \(--action-repeat\), trial_steps \(--trial-steps\) describe an outside",
    ):
        tiny_protocol(action_repeat=2, trial_steps=5)
    with pytest.raises(ValueError, match="name two environments"):
        tiny_protocol(env="gymnasium:Pendulum-v1", domain="two_link_arm", task="reach")


@pytest.mark.slow
def test_a_sweep_file_takes_env_and_a_learner_state_table(tmp_path):
    from rmac_mj.sweeps import load_sweep

    path = tmp_path / "cartpole.toml"
    path.write_text(
        textwrap.dedent("""
        [protocol]
        env = "dm_control:cartpole/swingup"
        action_repeat = 2
        trial_steps = 5
        algorithms = ["s-ac"]
        experiments = 1
        [learner_state]
        bounds = { "position[0]" = [-1.8, 1.8], "velocity[0]" = [-5, 5], "velocity[1]" = [-20, 20] }
        [grid]
        "s-ac.alpha_a" = [0.005, 0.02]
    """)
    )
    sweep = load_sweep(path)
    protocol = sweep.configurations[0].protocol
    assert protocol.env == "dm_control:cartpole/swingup" and protocol.action_repeat == 2
    env = protocol.make_environment(0)
    assert env.learner_state.keys[1] == "atan2(position[2], position[1])"
    assert steps_per_trial(env) == 5
    path.write_text(path.read_text().replace(', "velocity[1]" = [-20, 20]', ""))
    measured = load_sweep(path).configurations[0].protocol  # the undeclared one is measured
    assert list(measured.measured_bounds) == ["velocity[1]"]


# ----------------------------------------------------------------------------------------------------
# The command line.


@pytest.mark.slow
def test_cli_config_reproduce_policy_resume_on_a_users_factory(tmp_path, capsys):
    from rmac_mj.cli import main

    config = tmp_path / "slider.toml"
    config.write_text(
        textwrap.dedent(f"""
        [protocol]
        env = "{HERE}:make_slider"
        task_kwargs = {{ start = 0.5 }}
        trial_steps = 6
        control_timestep = 0.1
        algorithms = ["s-ac"]
        "s-ac.backend" = "numpy"
        [learner_state]
        labels = ["position x [m]", "velocity v [m/s]"]
    """)
    )
    out = tmp_path / "slider"
    assert (
        main(
            [
                "reproduce",
                "--config",
                str(config),
                "--experiments",
                "1",
                "--trials",
                "2",
                "--evaluate-every",
                "1",
                "--evaluate-starts",
                "2",
                "--jobs",
                "1",
                "--no-progress",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert "one trial = 0.6 s of simulated time" in capsys.readouterr().out
    snapshot = out / "snapshots" / "s-ac" / "exp_000" / "trial_0002.npz"
    # The factory is code of the user's: a snapshot runs it when it is named again (or trusted).
    assert main(["policy", str(snapshot), "--out", str(tmp_path / "map")]) == 2
    assert "code of yours" in capsys.readouterr().err
    named = ["--env", f"{HERE}:make_slider"]
    assert main(["policy", str(snapshot), *named, "--out", str(tmp_path / "map")]) == 0
    assert (tmp_path / "map.png").is_file()
    # A resume takes the outside environment's settings from the directory's config.json.
    assert main(["reproduce", "--resume", "--out", str(out), "--no-progress", "--trust-env"]) == 0
    assert "one trial = 0.6 s of simulated time" in capsys.readouterr().out


@pytest.mark.slow
def test_render_a_dm_control_environment_between_its_control_steps():
    from rmac_mj.videos import render_episode

    env = envs.load(
        "dm_control:cartpole/swingup",
        seed=0,
        action_repeat=5,
        trial_steps=6,
        learner_state={
            "bounds": {"position[0]": [-1.8, 1.8], "velocity[0]": [-5, 5], "velocity[1]": [-20, 20]}
        },
    )
    episode = render_episode(
        env, policy=lambda x: np.array([0.5]), width=64, height=48, frames_per_step=5
    )
    assert episode.frames.shape == (6 * 5 + 1, 48, 64, 3) and episode.fps == pytest.approx(100)
    # The frames between control steps come from a scratch physics: the episode is env.step's own.
    again = envs.load(
        "dm_control:cartpole/swingup",
        seed=0,
        action_repeat=5,
        trial_steps=6,
        learner_state=env.learner_state,
    )
    again.reset()
    assert episode.returns[-1] == pytest.approx(
        sum(again.step(np.array([0.5])).reward for _ in range(6))
    )


def test_cli_optimal_and_bench_on_an_outside_environment(capsys):
    from rmac_mj.bench import step_costs
    from rmac_mj.cli import main

    assert main(["optimal", "--env", "gymnasium:Pendulum-v1"]) == 2
    assert "no near-optimal return for gymnasium:Pendulum-v1" in capsys.readouterr().err
    costs = step_costs(20, 1, env="gymnasium:Pendulum-v1")
    assert costs["raw_step"] == "the environment's own step (Gymnasium)"
    assert all(0 < costs[key] < float("inf") for key in ("physics_step_us", "env_step_us"))


@pytest.mark.slow
def test_the_guides_worked_example_runs_as_it_stands(tmp_path, monkeypatch, capsys):
    import pathlib
    import re

    page = pathlib.Path(__file__).parents[2] / "docs" / "guide" / "your-own-task.md"
    task_file, usage = re.findall(r"```python\n(.*?)```", page.read_text(), re.S)[:2]
    assert task_file.startswith("# my_task.py")
    (tmp_path / "my_task.py").write_text(task_file)
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(usage, str(page), "exec"), namespace)
    printed = capsys.readouterr().out.splitlines()
    assert printed == ["('atan2(observation[1], observation[0])', 'observation[2]')", "3.0"]
    assert len(namespace["returns"]) == 30 and all(np.isfinite(namespace["returns"]))


_DRAWN = """
import gymnasium
import numpy as np


class Dot(gymnasium.Env):
    metadata = {"render_modes": ["rgb_array"]}

    def __init__(self, render_mode=None):
        self.observation_space = gymnasium.spaces.Box(-1.0, 1.0, (1,))
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, (1,))
        self.render_mode, self.x, self.dt = render_mode, 0.0, 0.1

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.x = 0.5
        return np.array([self.x], dtype=np.float32), {}

    def step(self, action):
        return np.array([self.x], dtype=np.float32), -self.x ** 2, False, False, {}

    def render(self):
        return np.full((8, 8, 3), 200, dtype=np.uint8)


def drawn(render_mode=None):
    return gymnasium.wrappers.TimeLimit(Dot(render_mode=render_mode), max_episode_steps=5)


def undrawn():
    return gymnasium.wrappers.TimeLimit(Dot(), max_episode_steps=5)
"""


def test_render_asks_a_factory_for_frames_through_render_mode(tmp_path):
    pytest.importorskip("gymnasium")
    from rmac_mj import envs
    from rmac_mj.errors import UserInputError

    (tmp_path / "dot.py").write_text(_DRAWN)
    frame = envs.load(f"{tmp_path / 'dot.py'}:drawn", seed=0, render=True).render_frame()
    assert frame.shape == (8, 8, 3) and frame.dtype == np.uint8
    with pytest.raises(UserInputError) as refused:
        envs.load(f"{tmp_path / 'dot.py'}:undrawn", seed=0, render=True).render_frame()
    message = str(refused.value)
    assert "cannot be rendered" in message and "render_mode argument" in message
    assert "EnvSpec" not in message  # no internal API in what a user reads
