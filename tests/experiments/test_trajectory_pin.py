"""Speed work must not change a single bit: seeded trajectories pinned from the code before it.

``tests/data/dc_pendulum_trajectories.json`` was written by this module (``python
tests/experiments/test_trajectory_pin.py``) from the commit before the fast paths of ``env.step`` and
``run_trial`` (issue 12). It holds, for a few seeded rollouts, every observation entry and every
reward, discount and step type, and for ``run_trial`` every state and reward an agent was shown and
every return. Floats are stored by ``repr``, which round-trips exactly; the tests compare with ``==``.
Regenerate it only for a change that is *meant* to change trajectories, and say so in the commit.
It was regenerated once with the code unchanged, with OpenBLAS's Haswell kernels (tests/conftest.py:
the last bit of a reward depends on the BLAS kernel), after that code had reproduced the first file
with the SkylakeX kernels it was written with.
"""

from __future__ import annotations

import json
import pathlib

import numpy as np

from rmac_mj import tasks
from rmac_mj.agents import PolicyAgent
from rmac_mj.rollout import action_space_of, run_trial, state_space_of

PINNED = pathlib.Path(__file__).parents[1] / "data" / "dc_pendulum_trajectories.json"

#: (name, task, task_kwargs, how actions are drawn)
ROLLOUTS = [
    # Random voltages, a third of them beyond +-3 V (saturated, charged as applied).
    ("swingup_random", "swingup", {}, "uniform4"),
    # Seeded start noise.
    ("balance_seeded", "balance", {"random": 7}, "uniform4"),
    # A fast spin: the angle wraps around many times; scalar actions (shape ()) are accepted too.
    ("spin_wraps", "swingup", {"start_state": (0.0, 30.0)}, "scalar3"),
]


def _rollout(task: str, task_kwargs: dict, actions: str) -> dict[str, list]:
    env = tasks.load("dc_pendulum", task, task_kwargs=dict(task_kwargs))
    rng = np.random.default_rng(12)
    record: dict[str, list] = {
        "angle": [],
        "velocity": [],
        "orientation": [],
        "reward": [],
        "discount": [],
        "step_type": [],
        "action": [],
    }

    def keep(timestep):
        obs = timestep.observation
        assert list(obs) == ["angle", "velocity", "orientation"]
        record["angle"].append([float(v) for v in obs["angle"]])
        record["velocity"].append([float(v) for v in obs["velocity"]])
        record["orientation"].append([float(v) for v in obs["orientation"]])
        record["reward"].append(None if timestep.reward is None else float(timestep.reward))
        record["discount"].append(None if timestep.discount is None else float(timestep.discount))
        record["step_type"].append(int(timestep.step_type))

    for _ in range(2):  # two episodes: the second starts from a reset after the last step
        timestep = env.reset()
        keep(timestep)
        while not timestep.last():
            if actions == "uniform4":
                action = rng.uniform(-4.0, 4.0, size=1)
            else:
                action = np.float64(3.0)
            record["action"].append(np.asarray(action, dtype=float).reshape(-1).tolist())
            timestep = env.step(action)
            keep(timestep)
    return record


class _ScriptedAgent(PolicyAgent):
    """A seeded random-voltage 'learner' that writes down every state and reward it is shown."""

    def __init__(self, state_space, action_space, seed):
        super().__init__(
            state_space, action_space, policy=lambda x: np.array([np.tanh(x[0])]), seed=seed
        )
        self.seen: list[list[float]] = []

    def _act_randomly(self) -> np.ndarray:
        return self.rng.uniform(-3.5, 3.5, size=1)

    def _start(self, x0):
        self.seen.append([float("nan"), *x0.tolist()])
        return self._act_randomly()

    def _step(self, reward, x):
        self.seen.append([reward, *x.tolist()])
        return self._act_randomly()

    def _stop(self, reward, x, terminal):
        self.seen.append([reward, *x.tolist()])

    def _greedy_action(self, x):
        self.seen.append([float("inf"), *x.tolist()])
        return super()._greedy_action(x)


def _run_trials() -> dict[str, list]:
    env = tasks.load("dc_pendulum", "balance", task_kwargs={"random": 5})
    agent = _ScriptedAgent(state_space_of(env), action_space_of(env), seed=4)
    returns = [
        run_trial(env, agent, learn=True),
        run_trial(env, agent, learn=False),
        run_trial(env, agent, learn=True),
    ]
    # NaN/inf mark start/greedy rows; JSON has no NaN, so they are written as strings.
    seen = [[repr(v) if not np.isfinite(v) else v for v in row] for row in agent.seen]
    return {"returns": returns, "seen": seen}


def _record() -> dict:
    return {
        "rollouts": {
            name: _rollout(task, kwargs, actions) for name, task, kwargs, actions in ROLLOUTS
        },
        "run_trial": _run_trials(),
    }


def _pinned() -> dict:
    return json.loads(PINNED.read_text())


def test_env_trajectories_are_bit_identical_to_the_pinned_ones():
    pinned = _pinned()["rollouts"]
    for name, task, kwargs, actions in ROLLOUTS:
        now = _rollout(task, kwargs, actions)
        for key, values in pinned[name].items():
            assert now[key] == values, f"{name}: {key} differs from the pinned trajectory"


def test_run_trial_shows_agents_bit_identical_states_and_rewards():
    pinned, now = _pinned()["run_trial"], _run_trials()
    assert now["returns"] == pinned["returns"]
    assert now["seen"] == pinned["seen"]


if __name__ == "__main__":
    PINNED.parent.mkdir(exist_ok=True)
    PINNED.write_text(json.dumps(_record(), indent=None, separators=(",", ":")) + "\n")
    print("wrote", PINNED)
