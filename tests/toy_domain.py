"""A test-only domain that is not the pendulum: n = 4 state dimensions, m = 2 actions.

A bar spinning about a vertical hinge (periodic angle theta, torque tau) beside a cart on a rail
(position s, force f), no gravity torque, 10 steps of 0.02 s (two RK4 substeps of 0.01 s): a trial is
0.2 s, not the pendulum's 3 s. The learner's state is x = [theta, s, omega, v] (observations
``position`` then ``velocity``), the reward -x^T x - 0.1 u^T u of the state before the step.

``register(monkeypatch)`` adds it to ``rmac_mj.tasks`` as domain ``toy`` with task ``settle`` for one
test; the experiments layer must run on it without knowing it.
"""

from __future__ import annotations

import collections

import numpy as np
from dm_control import mujoco
from dm_control.suite import base
from dm_control.utils import containers

from rmac_mj import tasks
from rmac_mj.tasks import common

DOMAIN, TASK = "toy", "settle"
TIME_LIMIT, CONTROL_TIMESTEP = 0.2, 0.02
START = (np.pi / 2, 0.3, 0.0, 0.0)

MODEL = """
<mujoco model="toy">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.01" integrator="RK4" gravity="0 0 0"><flag contact="disable"/></option>
  <visual><global offwidth="320" offheight="240"/><quality shadowsize="0"/></visual>
  <worldbody>
    <light name="top" pos="0 0 2" dir="0 0 -1" castshadow="false"/>
    <geom name="floor" type="plane" size="1 1 0.01" rgba="0.3 0.3 0.35 1" contype="0" conaffinity="0"/>
    <camera name="above" pos="0 0.25 1.6" xyaxes="1 0 0 0 1 0"/>
    <body name="bar" pos="0 0 0.05">
      <joint name="spin" type="hinge" axis="0 0 1" damping="0.05"/>
      <geom name="bar" type="box" size="0.2 0.03 0.03" mass="1" rgba="0.9 0.3 0.2 1"/>
    </body>
    <body name="cart" pos="0 0.5 0.05">
      <joint name="slide" type="slide" axis="1 0 0" damping="0.1"/>
      <geom name="cart" type="box" size="0.05 0.05 0.05" mass="0.5" rgba="0.2 0.5 0.9 1"/>
    </body>
  </worldbody>
  <actuator>
    <motor name="tau" joint="spin" ctrlrange="-1 1"/>
    <motor name="f" joint="slide" ctrlrange="-2 2"/>
  </actuator>
</mujoco>
"""

SUITE = containers.TaggedTasks()


@SUITE.add()
def settle(
    time_limit: float = TIME_LIMIT,
    control_timestep: float = CONTROL_TIMESTEP,
    start_noise: float = 0.1,
    random=None,
    environment_kwargs=None,
):
    physics = Physics.from_xml_string(MODEL)
    return common.make_environment(
        physics,
        Settle(start_noise, random=random),
        time_limit,
        control_timestep,
        environment_kwargs,
    )


class Physics(mujoco.Physics):
    def position(self) -> np.ndarray:
        """[theta (wrapped), s]."""
        q = self.named.data.qpos
        return np.array([common.wrap_angle(float(q["spin"][0])), float(q["slide"][0])])

    def velocity(self) -> np.ndarray:
        """[omega, v]."""
        v = self.named.data.qvel
        return np.array([float(v["spin"][0]), float(v["slide"][0])])


class Settle(base.Task):
    def __init__(self, start_noise: float, random=None):
        self._noise = float(start_noise)
        self._reward = 0.0
        super().__init__(random=random)

    def initialize_episode(self, physics):
        x0 = np.array(START) + self.random.uniform(-self._noise, self._noise, 4) * [1, 1, 0, 0]
        physics.named.data.qpos["spin"], physics.named.data.qpos["slide"] = x0[:2]
        physics.named.data.qvel["spin"], physics.named.data.qvel["slide"] = x0[2:]
        self._reward = 0.0
        super().initialize_episode(physics)

    def before_step(self, action, physics):
        physics.set_control(common.check_action(action, 2))
        x = np.r_[physics.position(), physics.velocity()]
        u = np.clip(
            physics.data.ctrl,
            physics.model.actuator_ctrlrange[:, 0],
            physics.model.actuator_ctrlrange[:, 1],
        )
        self._reward = -float(x @ x) - 0.1 * float(u @ u)

    def get_observation(self, physics):
        obs = collections.OrderedDict()
        obs["position"] = physics.position()
        obs["velocity"] = physics.velocity()
        return obs

    def get_reward(self, physics):
        return self._reward

    @property
    def learner_state(self) -> common.LearnerStateSpec:
        return common.LearnerStateSpec(
            keys=("position", "velocity"),
            low=(-np.pi, -1.0, -20.0, -5.0),
            high=(np.pi, 1.0, 20.0, 5.0),
            periodic=(True, False, False, False),
            labels=(
                "bar angle theta [rad]",
                "cart position s [m]",
                "bar rate omega [rad/s]",
                "cart speed v [m/s]",
            ),
            input_weights=(1.0, 1.0, 0.1, 0.2),
            action_input_weights=(1.0, 0.5),
            action_labels=("torque tau [N m]", "force f [N]"),
        )


class Brake:
    """The toy's demonstrator: brake the bar and the cart (u = -[omega, 2 v], saturated)."""

    action_noise = 0.1

    def controller(self, env):
        return lambda x: np.clip([-x[2], -2.0 * x[3]], [-1.0, -2.0], [1.0, 2.0])


#: What the task declares beyond its environment, in its own module, as a task of the suite does.
KNOWLEDGE = {
    TASK: common.TaskKnowledge(
        demonstrators={"demo": Brake()}, plot_hints=common.PlotHints(return_margin=0.5)
    )
}


def register(monkeypatch) -> None:
    """Make ``toy``/``settle`` a task of ``rmac_mj.tasks`` until the test ends."""
    import sys

    monkeypatch.setitem(tasks._DOMAINS, DOMAIN, sys.modules[__name__])
    monkeypatch.setattr(tasks, "ALL_TASKS", tuple(sorted(tasks.ALL_TASKS + ((DOMAIN, TASK),))))
    monkeypatch.setitem(tasks.TASKS_BY_DOMAIN, DOMAIN, (TASK,))
    monkeypatch.setitem(tasks.SUITE, DOMAIN, SUITE)
