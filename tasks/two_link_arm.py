"""Two-link robot arm domain: the `rarm` benchmark of Busoniu et al.'s ApproxRL toolbox.

The physics is the MJCF model ``models/two_link_arm/`` (a planar arm with hinge axes along gravity, so
gravity exerts no torque; see its README for every number). The task ``reach`` adds the benchmark's
problem on top: a 0.05 s control step (five RK4 substeps of 10 ms), 3 s trials (60 control steps), every
trial from x_0 = [-pi/2, 0, pi/2, 0] and the quadratic reward

    r_k = -x_{k-1}^T Q x_{k-1} - u_{k-1}^T R u_{k-1},   x = [theta1, omega1, theta2, omega2],
    Q = diag(1, 0.05, 1, 0.05),   R = 0,

computed from the state *before* the step (angles wrapped to [-pi, pi)) and the torques applied during
it: torques outside [-1.5, 1.5] x [-1, 1] N m are saturated by the actuators' control ranges and charged
as applied. The goal x = 0 is the arm stretched out along the world x axis, at rest. x is in the
benchmark's order; theta2 is the elbow angle relative to link 1. The benchmark's discount factor,
``DISCOUNT`` = 0.98, is for learners that discount; the trial's score is the undiscounted sum.

Observations: ``position`` [theta1, theta2] (wrapped) and ``velocity`` [omega1, omega2], as the joints
are ordered in the model, and per joint ``shoulder`` = [theta1, omega1] and ``elbow`` = [theta2, omega2]:
the learners' state x (``Reach.learner_state``) is ``shoulder`` then ``elbow``, which is the benchmark's
order [theta1, omega1, theta2, omega2], so Q and the start state read as in the benchmark.
"""

from __future__ import annotations

import collections
from typing import Any

import numpy as np
from dm_control import mujoco
from dm_control.rl import control
from dm_control.suite import base
from dm_control.utils import containers

from rmac_mj.models import model_path
from rmac_mj.tasks import common

DEFAULT_TIME_LIMIT = 3.0  # s, one trial of the benchmark
CONTROL_TIMESTEP = 0.05  # s, the benchmark's sampling time
STATE_WEIGHTS = (1.0, 0.05, 1.0, 0.05)  # diag Q over [theta1, omega1, theta2, omega2]
ACTION_WEIGHTS = (0.0, 0.0)  # diag R: the benchmark does not charge the torques
REACH_START = (-np.pi / 2, 0.0, np.pi / 2, 0.0)  # x_0: link 1 along -y, link 2 bent back along +x
DISCOUNT = 0.98  # the benchmark's gamma

#: Highest joint speed (rad/s) the arm reaches within one 3 s trial from x_0 under the torque limits,
#: measured on the model: 47.8 rad/s (the elbow, with both torques held at opposite extremes for the
#: whole trial; the elbow alone tends to 1 N m / 0.02 N m s = 50 rad/s). Random torque sequences peak
#: far lower: 40 uniform ones at 1.7-8.3 rad/s, 40 bang-bang ones at 2.6-17.4 rad/s; the near-optimal
#: reach at 2.2 (shoulder) and 5.0 rad/s (elbow) (models/two_link_arm/README.md, docs/optimal.md).
MAX_SPEED = 47.8

#: Velocity half-range of the nominal state box (rad/s): 4 pi = 12.6. It covers the near-optimal reach
#: 2.5 times over and every uniform random torque sequence measured; as with the pendulum (8 pi against
#: 57.5 rad/s reachable), only spinning, bang-bang policies go beyond it. The benchmark itself clips
#: speeds to +-2 pi (see models/two_link_arm/README.md).
NOMINAL_SPEED = 4 * np.pi

SUITE = containers.TaggedTasks()

#: What each task declares beyond its environment (``rmac_mj.tasks.knowledge``): reach's near-optimal
#: return is found by trajectory optimisation (iLQR from several starts, docs/optimal.md: -37.65
#: per trial); returns near the end are of order -40, so differences of about 1 are worth seeing.
KNOWLEDGE = {
    "reach": common.TaskKnowledge(
        optimum=common.Optimum("trajectory optimisation"),
        plot_hints=common.PlotHints(return_margin=1.0),
    ),
}


def get_model_and_assets() -> tuple[str, dict[str, Any]]:
    """The scene XML string (the arm with floor, light and camera) and its assets (the arm's XML)."""
    return (
        model_path("two_link_arm", scene=True).read_text(),
        {"two_link_arm.xml": model_path("two_link_arm").read_bytes()},
    )


@SUITE.add("benchmarking")
def reach(
    time_limit: float = DEFAULT_TIME_LIMIT,
    control_timestep: float = CONTROL_TIMESTEP,
    state_weights=STATE_WEIGHTS,
    action_weights=ACTION_WEIGHTS,
    start_state=REACH_START,
    start_noise: float = 0.0,
    random=None,
    environment_kwargs: dict[str, Any] | None = None,
) -> control.Environment:
    """The benchmark's task: from [-pi/2, 0, pi/2, 0] to the origin, 60 steps of 0.05 s."""
    task = Reach(
        state_weights=state_weights,
        action_weights=action_weights,
        start_state=start_state,
        start_noise=start_noise,
        random=random,
    )
    physics = Physics.from_xml_string(*get_model_and_assets())
    return common.make_environment(physics, task, time_limit, control_timestep, environment_kwargs)


class Physics(mujoco.Physics):
    """The two-link arm with its physical quantities by name.

    Joint and actuator addresses are resolved by name once per model (dm-control's string indexing
    costs microseconds per access).
    """

    def _reload_from_data(self, data) -> None:
        super()._reload_from_data(data)
        model = self.model
        joints = [model.name2id(name, "joint") for name in ("shoulder", "elbow")]
        motors = [model.name2id(name, "actuator") for name in ("shoulder", "elbow")]
        self._qpos_adr = np.array([model.jnt_qposadr[j] for j in joints])
        self._qvel_adr = np.array([model.jnt_dofadr[j] for j in joints])
        self._motors = np.array(motors)
        self._ctrl_range = np.array(model.actuator_ctrlrange[motors], dtype=float)
        self._tip = model.name2id("tip", "site")

    def joint_angles(self) -> np.ndarray:
        """[theta1, theta2] wrapped to [-pi, pi) (rad); theta2 relative to link 1. Shape (2,)."""
        return common.wrap_angle(self.data.qpos[self._qpos_adr])

    def joint_velocities(self) -> np.ndarray:
        """[omega1, omega2] (rad/s); shape (2,)."""
        return self.data.qvel[self._qvel_adr].copy()

    def state(self) -> np.ndarray:
        """x = [theta1, omega1, theta2, omega2], angles wrapped (the benchmark's order); shape (4,)."""
        return self.state_of(self.data.qpos, self.data.qvel)

    def state_of(self, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
        """x of many physics states at once.

        Args:
          qpos, qvel: ndarrays of shape (..., nq) and (..., nv), e.g. from ``mujoco.rollout``.
        Returns:
          ndarray of shape (..., 4): [theta1, omega1, theta2, omega2], angles wrapped.
        """
        theta = common.wrap_angle(qpos[..., self._qpos_adr])
        omega = qvel[..., self._qvel_adr]
        return np.stack([theta[..., 0], omega[..., 0], theta[..., 1], omega[..., 1]], axis=-1)

    def set_state_vector(self, x) -> None:
        """Put the arm at x = [theta1, omega1, theta2, omega2] (rad, rad/s)."""
        theta1, omega1, theta2, omega2 = (float(v) for v in x)
        self.data.qpos[self._qpos_adr] = theta1, theta2
        self.data.qvel[self._qvel_adr] = omega1, omega2

    def torques(self) -> np.ndarray:
        """[tau1, tau2] applied now (N m), after saturation to the control ranges; shape (2,)."""
        return np.clip(self.data.ctrl[self._motors], self._ctrl_range[:, 0], self._ctrl_range[:, 1])

    def tip_position(self) -> np.ndarray:
        """Position of the end of link 2 in the world frame (m); shape (3,)."""
        return self.data.site_xpos[self._tip].copy()


class Reach(base.Task):
    """Bring the arm from ``start_state`` to the origin with the quadratic reward (module docstring)."""

    def __init__(
        self,
        state_weights=STATE_WEIGHTS,
        action_weights=ACTION_WEIGHTS,
        start_state=REACH_START,
        start_noise: float = 0.0,
        random=None,
    ):
        """
        Args:
          state_weights: Q over [theta1, omega1, theta2, omega2], as its diagonal (4,) or a full
            symmetric positive semi-definite (4, 4).
          action_weights: R over [tau1, tau2], as its diagonal (2,) or a full symmetric positive
            semi-definite (2, 2).
          start_state: x_0 = [theta1, omega1, theta2, omega2] of every episode (rad, rad/s).
          start_noise: half-width (rad) of a uniform perturbation of both start angles, drawn from the
            task's random state; 0 makes every episode start exactly at ``start_state``.
          random: int seed, ``numpy.random.RandomState`` or None (dm-control's convention).
        """
        q = common.quadratic_weights("state_weights", state_weights, 4)
        r = common.quadratic_weights("action_weights", action_weights, 2)
        x0 = common.check_start_state(start_state, 4, "[theta1, omega1, theta2, omega2]")
        common.check_in("start_noise", start_noise, 0.0, np.pi, " rad")
        common.check_random(random)
        self._q = q
        self._r = r
        self._start_state = x0
        self._start_noise = float(start_noise)
        self._reward = 0.0
        super().__init__(random=random)

    def initialize_episode(self, physics: Physics) -> None:
        x0 = self._start_state.copy()
        if self._start_noise > 0:
            x0[[0, 2]] += self.random.uniform(-self._start_noise, self._start_noise, size=2)
        physics.set_state_vector(x0)
        self._reward = 0.0
        super().initialize_episode(physics)

    def before_step(self, action, physics: Physics) -> None:
        """Check the action, apply it, and charge r_k for the state before the step and the torques."""
        physics.set_control(common.check_action(action, 2))
        self._reward = float(self.reward_of(physics.state(), physics.torques()))

    def reward_of(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """r = -x^T Q x - u^T R u for many states and applied torques at once.

        Args:
          x: ndarray of shape (..., 4), [theta1, omega1, theta2, omega2] wrapped (``Physics.state_of``).
          u: ndarray of shape (..., 2), the applied (saturated) torques [tau1, tau2] (N m).
        Returns:
          ndarray of shape (...,).
        """
        return -np.einsum("...i,ij,...j->...", x, self._q, x) - np.einsum(
            "...i,ij,...j->...", u, self._r, u
        )

    def get_observation(self, physics: Physics) -> collections.OrderedDict:
        theta, omega = physics.joint_angles(), physics.joint_velocities()
        obs = collections.OrderedDict()
        obs["position"] = theta
        obs["velocity"] = omega
        obs["shoulder"] = np.array([theta[0], omega[0]])
        obs["elbow"] = np.array([theta[1], omega[1]])
        return obs

    def get_reward(self, physics: Physics) -> float:
        """r_k of the step just taken (0 at reset, where dm-control reports no reward anyway)."""
        return self._reward

    @property
    def learner_state(self) -> common.LearnerStateSpec:
        """x = [theta1, omega1, theta2, omega2] (``shoulder`` then ``elbow``).

        The box is one period in each angle and +-NOMINAL_SPEED in each speed. The weights give every
        dimension the weighted span it has for the pendulum under Table 2's weights (1 per angle, 0.1
        per speed, 1 per voltage): angles 1 * 2 pi; speeds 0.2 * 8 pi = 5.0, as 0.1 * 16 pi for the
        pendulum's +-8 pi; torques 2 * 3 N m = 3 * 2 N m = 6, as 1 * 6 V. The action cost is R's
        diagonal ((0, 0): the benchmark charges no torque), None for a full R; the state cost Q's.
        """
        return common.LearnerStateSpec(
            keys=("shoulder", "elbow"),
            low=(-np.pi, -NOMINAL_SPEED, -np.pi, -NOMINAL_SPEED),
            high=(np.pi, NOMINAL_SPEED, np.pi, NOMINAL_SPEED),
            periodic=(True, False, True, False),
            labels=(
                "shoulder angle theta1 [rad]",
                "shoulder speed omega1 [rad/s]",
                "elbow angle theta2 [rad]",
                "elbow speed omega2 [rad/s]",
            ),
            input_weights=(1.0, 0.2, 1.0, 0.2),
            action_input_weights=(2.0, 3.0),
            action_labels=("tau1 [N m]", "tau2 [N m]"),
            action_cost=tuple(np.diag(self._r))
            if np.array_equal(self._r, np.diag(np.diag(self._r)))
            else None,
            state_cost=tuple(np.diag(self._q))
            if np.array_equal(self._q, np.diag(np.diag(self._q)))
            else None,
        )
