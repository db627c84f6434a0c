"""DC-motor pendulum domain: the swing-up task of Grondman et al., section 6.

The physics is the MJCF model ``models/dc_pendulum.xml`` (Table 1; MuJoCo's ``<dcmotor>`` actuator
produces the input torque (K/R) u and the back-EMF damping K^2/R). The tasks add what the paper
defines on top: a 0.03 s control step, 3 s trials (100 control steps), the start state and the
quadratic reward

    r_k = -x_{k-1}^T Q x_{k-1} - P u_{k-1}^2,   x = [phi, phi_dot],   Q = diag(5, 0.1),  P = 1,

computed from the state *before* the step (phi wrapped to [-pi, pi)) and the voltage applied during it.
A voltage outside [-3, 3] V is saturated by the actuator's control range, as on the real rig, and the
reward is charged for the saturated (applied) voltage.
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

DEFAULT_TIME_LIMIT = 3.0        # s, one trial (section 6)
CONTROL_TIMESTEP = 0.03         # s; the paper leaves it open, its group's follow-up work uses 0.03 s
STATE_WEIGHTS = (5.0, 0.1)      # Q = diag(5, 0.1)
ACTION_WEIGHT = 1.0             # P
SWINGUP_START = (np.pi, 0.0)    # x_0 = [pi, 0]: hanging down, at rest
BALANCE_START = (0.0, 0.0)
BALANCE_START_NOISE = 0.1       # rad: half-width of the uniform perturbation of the balance start angle

#: Highest angular speed the pendulum reaches under |u| <= 3 V (rad/s), measured on the model by
#: spinning it with a constant 3 V from every start on a grid: 57.5 rad/s.
MAX_SPEED = 57.5

#: Velocity half-range of the nominal state box that learners cover (rad/s): 8 pi, as the authors'
#: group uses for this pendulum. Swing-ups use far less (the near-optimal one peaks at 11.5 rad/s,
#: learned ones at 16-18); only early, spinning policies go faster, and a tile coder clips them.
#: Covering all of MAX_SPEED instead spreads S-AC's 7 tiles so thin that it learned clearly worse
#: (40 experiments: -1425 against -1023 per trial at the end, 15 against 2 stuck; docs/sac.md).
NOMINAL_SPEED = 8 * np.pi

SUITE = containers.TaggedTasks()


def get_model_and_assets() -> tuple[str, dict[str, Any]]:
    """The model XML string and its (empty) asset dict."""
    return model_path("dc_pendulum").read_text(), {}


def _make_environment(task: "SwingUp", time_limit: float, control_timestep: float,
                      environment_kwargs: dict[str, Any] | None) -> control.Environment:
    physics = Physics.from_xml_string(*get_model_and_assets())
    return common.make_environment(physics, task, time_limit, control_timestep, environment_kwargs)


@SUITE.add("benchmarking")
def swingup(time_limit: float = DEFAULT_TIME_LIMIT, control_timestep: float = CONTROL_TIMESTEP,
            state_weights=STATE_WEIGHTS, action_weight: float = ACTION_WEIGHT,
            start_state=SWINGUP_START, start_noise: float = 0.0, random=None,
            environment_kwargs: dict[str, Any] | None = None) -> control.Environment:
    """The paper's task: swing up from [pi, 0] and balance, 100 steps of 0.03 s."""
    task = SwingUp(state_weights=state_weights, action_weight=action_weight,
                   start_state=start_state, start_noise=start_noise, random=random)
    return _make_environment(task, time_limit, control_timestep, environment_kwargs)


@SUITE.add("benchmarking")
def balance(time_limit: float = DEFAULT_TIME_LIMIT, control_timestep: float = CONTROL_TIMESTEP,
            state_weights=STATE_WEIGHTS, action_weight: float = ACTION_WEIGHT,
            start_state=BALANCE_START, start_noise: float = BALANCE_START_NOISE, random=None,
            environment_kwargs: dict[str, Any] | None = None) -> control.Environment:
    """Balance upright from a small random perturbation of the start angle; same reward."""
    task = SwingUp(state_weights=state_weights, action_weight=action_weight,
                   start_state=start_state, start_noise=start_noise, random=random)
    return _make_environment(task, time_limit, control_timestep, environment_kwargs)


wrap_angle = common.wrap_angle  # phi (rad, scalar or array) wrapped to [-pi, pi)


class Physics(mujoco.Physics):
    """The DC-motor pendulum with its physical quantities by name.

    The addresses of the named joint and actuator are resolved by name once per model (dm-control's
    string indexing costs microseconds per access, a third of an ``env.step``).
    """

    def _reload_from_data(self, data) -> None:
        super()._reload_from_data(data)
        model = self.model
        hinge = model.name2id("hinge", "joint")
        motor = model.name2id("motor", "actuator")
        self._qpos_adr = int(model.jnt_qposadr[hinge])
        self._qvel_adr = int(model.jnt_dofadr[hinge])
        self._motor = motor
        self._ctrl_low, self._ctrl_high = (float(v) for v in model.actuator_ctrlrange[motor])

    def angle(self) -> float:
        """phi in [-pi, pi) (rad): 0 upright, -pi hanging down."""
        return float(wrap_angle(self.data.qpos[self._qpos_adr]))

    def angular_velocity(self) -> float:
        """phi_dot (rad/s)."""
        return float(self.data.qvel[self._qvel_adr])

    def state(self) -> np.ndarray:
        """x = [phi, phi_dot], phi wrapped; ndarray of shape (2,)."""
        return np.array([self.angle(), self.angular_velocity()])

    def state_of(self, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
        """x = [phi, phi_dot] (phi wrapped) of many physics states at once.

        Args:
          qpos, qvel: ndarrays of shape (..., nq) and (..., nv), e.g. from ``mujoco.rollout``.
        Returns:
          ndarray of shape (..., 2).
        """
        return np.stack([wrap_angle(qpos[..., self._qpos_adr]), qvel[..., self._qvel_adr]], axis=-1)

    def set_state_vector(self, phi: float, phi_dot: float) -> None:
        """Put the pendulum at angle ``phi`` (rad) with speed ``phi_dot`` (rad/s), at rest otherwise."""
        self.data.qpos[self._qpos_adr] = phi
        self.data.qvel[self._qvel_adr] = phi_dot

    def voltage(self) -> float:
        """The motor voltage applied now (V), after saturation to the control range."""
        return min(max(float(self.data.ctrl[self._motor]), self._ctrl_low), self._ctrl_high)

    def motor_torque(self) -> float:
        """Shaft torque of the motor (N m): (K/R) u - (K^2/R) phi_dot."""
        return float(self.data.actuator_force[self._motor])

    def orientation(self) -> np.ndarray:
        """[cos(phi), sin(phi)]; ndarray of shape (2,)."""
        phi = self.data.qpos[self._qpos_adr]
        return np.array([np.cos(phi), np.sin(phi)])


class SwingUp(base.Task):
    """Swing-up and balance with the quadratic reward of section 6 (see the module docstring)."""

    def __init__(self, state_weights=STATE_WEIGHTS, action_weight: float = ACTION_WEIGHT,
                 start_state=SWINGUP_START, start_noise: float = 0.0, random=None):
        """
        Args:
          state_weights: Q, as its diagonal (2,) or a full symmetric positive semi-definite (2, 2).
          action_weight: P >= 0.
          start_state: x_0 = [phi, phi_dot] of every episode (rad, rad/s).
          start_noise: half-width (rad) of a uniform perturbation of the start angle, drawn from the
            task's random state; 0 makes every episode start exactly at ``start_state``.
          random: int seed, ``numpy.random.RandomState`` or None (dm-control's convention).
        """
        q = common.quadratic_weights("state_weights", state_weights, 2)
        if not (np.isscalar(action_weight) and np.isfinite(action_weight) and action_weight >= 0):
            raise ValueError(f"action_weight must be a finite number >= 0, got {action_weight!r}")
        x0 = np.asarray(start_state, dtype=float)
        if x0.shape != (2,) or not np.all(np.isfinite(x0)):
            raise ValueError(f"start_state must be finite [phi, phi_dot], got {start_state!r}")
        if not (np.isscalar(start_noise) and np.isfinite(start_noise) and 0 <= start_noise <= np.pi):
            raise ValueError(f"start_noise must be in [0, pi] rad, got {start_noise!r}")
        self._q = q
        self._p = float(action_weight)
        self._start_state = x0
        self._start_noise = float(start_noise)
        self._reward = 0.0
        super().__init__(random=random)

    def initialize_episode(self, physics: Physics) -> None:
        phi, phi_dot = self._start_state
        if self._start_noise > 0:
            phi += self.random.uniform(-self._start_noise, self._start_noise)
        physics.set_state_vector(phi, phi_dot)
        self._reward = 0.0
        super().initialize_episode(physics)

    def before_step(self, action, physics: Physics) -> None:
        """Check the action, apply it, and charge r_k for the state before the step and the action."""
        physics.set_control(common.check_action(action, 1))
        self._reward = float(self.reward_of(physics.state(), np.array([physics.voltage()])))

    def reward_of(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """rho(x, u) = -x^T Q x - P u^2 for many states and applied voltages at once.

        Args:
          x: ndarray of shape (..., 2), [phi, phi_dot] with phi wrapped (``Physics.state_of``).
          u: ndarray of shape (..., 1), the applied (saturated) voltage.
        Returns:
          ndarray of shape (...,).
        """
        return -np.einsum("...i,ij,...j->...", x, self._q, x) - self._p * u[..., 0] ** 2

    def get_observation(self, physics: Physics) -> collections.OrderedDict:
        obs = collections.OrderedDict()
        obs["angle"] = np.array([physics.angle()])
        obs["velocity"] = np.array([physics.angular_velocity()])
        obs["orientation"] = physics.orientation()
        return obs

    def get_reward(self, physics: Physics) -> float:
        """r_k of the step just taken (0 at reset, where dm-control reports no reward anyway)."""
        return self._reward

    @property
    def learner_state(self) -> common.LearnerState:
        """x = [phi, phi_dot]; the box is one period in phi and +-NOMINAL_SPEED; Table 2's weights."""
        return common.LearnerState(
            keys=("angle", "velocity"), low=(-np.pi, -NOMINAL_SPEED), high=(np.pi, NOMINAL_SPEED),
            periodic=(True, False), labels=("angle phi [rad]", "angular velocity phi_dot [rad/s]"),
            weights=(1.0, 0.1), action_weights=(1.0,), action_labels=("u [V]",))

    @property
    def state_bounds(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nominal box of x = [phi, phi_dot]: (low, high, periodic), each of shape (2,)."""
        return (np.array([-np.pi, -NOMINAL_SPEED]), np.array([np.pi, NOMINAL_SPEED]),
                np.array([True, False]))
