"""DC-motor pendulum domain: the swing-up task of Grondman et al., section 6.

The physics is the MJCF model ``models/dc_pendulum/`` (Table 1; MuJoCo's ``<dcmotor>`` actuator
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
import math
from typing import Any

import mujoco as _mujoco
import numpy as np
from absl import logging
from dm_control import mujoco
from dm_control.rl import control
from dm_control.suite import base
from dm_control.utils import containers

from rmac_mj.models import model_path
from rmac_mj.tasks import common
from rmac_mj.tasks.energy_swingup import EnergySwingUp

DEFAULT_TIME_LIMIT = 3.0  # s, one trial (section 6)
CONTROL_TIMESTEP = 0.03  # s; the paper leaves it open, its group's follow-up work uses 0.03 s
STATE_WEIGHTS = (5.0, 0.1)  # Q = diag(5, 0.1)
ACTION_WEIGHT = 1.0  # P
SWINGUP_START = (np.pi, 0.0)  # x_0 = [pi, 0]: hanging down, at rest
BALANCE_START = (0.0, 0.0)
BALANCE_START_NOISE = 0.1  # rad: half-width of the uniform perturbation of the balance start angle

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

#: The demonstrators of both tasks: 'demo' is the one ``--prior demo`` records; 'poor-demo' pumps with
#: half the voltage and balances with half the LQR gains (it still swings up).
DEMONSTRATORS = {
    "demo": EnergySwingUp(),
    "poor-demo": EnergySwingUp(pump_voltage=1.5, balance_scale=0.5),
}

#: What each task declares beyond its environment (``rmac_mj.tasks.knowledge``). The swing-up's
#: near-optimal return is the dynamic programme of docs/optimal.md on a grid of 361 x 241 states
#: (1 deg, 0.17 rad/s apart) over speeds up to 20 rad/s (the optimal swing-up peaks at 11.5); balance
#: starts at random, so it has none. Returns of order -1000 per trial: differences under 10 are noise.
KNOWLEDGE = {
    "swingup": common.TaskKnowledge(
        optimum=common.Optimum(
            "dynamic programming",
            {
                "n_phi": 361,
                "n_phi_dot": 241,
                "max_phi_dot": 20.0,
                "n_actions": 25,
                "lookahead_actions": 121,
            },
        ),
        demonstrators=DEMONSTRATORS,
        plot_hints=common.PlotHints(return_margin=10.0),
    ),
    "balance": common.TaskKnowledge(
        demonstrators=DEMONSTRATORS, plot_hints=common.PlotHints(return_margin=10.0)
    ),
}

_TWO_PI = 2.0 * math.pi
_RK4 = int(_mujoco.mjtIntegrator.mjINT_RK4)


def get_model_and_assets() -> tuple[str, dict[str, Any]]:
    """The scene XML string (the pendulum with floor, light and camera) and its assets (the model)."""
    return (
        model_path("dc_pendulum", scene=True).read_text(),
        {"dc_pendulum.xml": model_path("dc_pendulum").read_bytes()},
    )


def _make_environment(
    task: SwingUp,
    time_limit: float,
    control_timestep: float,
    environment_kwargs: dict[str, Any] | None,
) -> control.Environment:
    physics = Physics.from_xml_string(*get_model_and_assets())
    return common.make_environment(physics, task, time_limit, control_timestep, environment_kwargs)


@SUITE.add("benchmarking")
def swingup(
    time_limit: float = DEFAULT_TIME_LIMIT,
    control_timestep: float = CONTROL_TIMESTEP,
    state_weights=STATE_WEIGHTS,
    action_weights: float = ACTION_WEIGHT,
    start_state=SWINGUP_START,
    start_noise: float = 0.0,
    random=None,
    environment_kwargs: dict[str, Any] | None = None,
) -> control.Environment:
    """The paper's task: swing up from [pi, 0] and balance, 100 steps of 0.03 s."""
    task = SwingUp(
        state_weights=state_weights,
        action_weights=action_weights,
        start_state=start_state,
        start_noise=start_noise,
        random=random,
    )
    return _make_environment(task, time_limit, control_timestep, environment_kwargs)


@SUITE.add("benchmarking")
def balance(
    time_limit: float = DEFAULT_TIME_LIMIT,
    control_timestep: float = CONTROL_TIMESTEP,
    state_weights=STATE_WEIGHTS,
    action_weights: float = ACTION_WEIGHT,
    start_state=BALANCE_START,
    start_noise: float = BALANCE_START_NOISE,
    random=None,
    environment_kwargs: dict[str, Any] | None = None,
) -> control.Environment:
    """Balance upright from a small random perturbation of the start angle; same reward."""
    task = SwingUp(
        state_weights=state_weights,
        action_weights=action_weights,
        start_state=start_state,
        start_noise=start_noise,
        random=random,
    )
    return _make_environment(task, time_limit, control_timestep, environment_kwargs)


def wrap_angle_float(phi: float) -> float:
    """:func:`~rmac_mj.tasks.common.wrap_angle` of one Python float, in float arithmetic (the same IEEE operations, so the
    same bits as the numpy version: Python's and numpy's ``%`` both take the sign of the divisor)."""
    return (phi + math.pi) % _TWO_PI - math.pi


class Physics(mujoco.Physics):
    """The DC-motor pendulum with its physical quantities by name.

    The addresses of the named joint and actuator are resolved by name once per model, and the raw
    MuJoCo structs and the arrays the task reads are kept with them (dm-control's string indexing
    and its wrapper's attribute look-ups cost microseconds per access; see docs/performance.md).
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
        # Views into this MjData's memory: valid until the data is replaced, which calls this again.
        self._mj_model, self._mj_data = model.ptr, self.data.ptr
        self._mj_option = model.ptr.opt  # a live view: reads see later changes of the integrator
        self._qpos, self._qvel, self._ctrl = self.data.qpos, self.data.qvel, self.data.ctrl

    def step(self, nstep: int = 1) -> None:
        """Advance ``nstep`` physics steps: dm-control's ``Physics.step``, in fewer Python calls.

        The same MuJoCo calls as dm-control 1.0.50 (with ``legacy_step``, the default: RK4 takes
        ``mj_step(nstep)`` then ``mj_step1`` so that position- and velocity-dependent fields match the
        new state; other integrators finish the pending step with ``mj_step2`` first), and the same
        check once per call: a MuJoCo warning raised during the step raises ``PhysicsError``, or is
        logged inside ``suppress_physics_errors()``. Only the bookkeeping is cheaper: the warning
        counters are compared as bytes instead of through a context manager and three numpy calls.
        """
        model, data, warnings = self._mj_model, self._mj_data, self._warnings
        before = warnings.tobytes()
        if not self.legacy_step:
            _mujoco.mj_step(model, data, nstep)
        else:
            if self._mj_option.integrator == _RK4:
                _mujoco.mj_step(model, data, nstep)
            else:
                _mujoco.mj_step2(model, data)
                if nstep > 1:
                    _mujoco.mj_step(model, data, nstep - 1)
            _mujoco.mj_step1(model, data)
        if warnings.tobytes() != before:
            self._report_new_warnings(np.frombuffer(before, dtype=warnings.dtype))

    def _report_new_warnings(self, before: np.ndarray) -> None:
        """Raise ``PhysicsError`` naming the MuJoCo warnings whose counters grew (or log them).

        Counters can also fall (MuJoCo's automatic reset after a bad state zeroes them before
        counting the new warning); like dm-control, only growth counts.
        """
        names = [
            name
            for name, grew in zip(_mujoco.mjtWarning.__members__, self._warnings > before)
            if grew
        ]
        if not names:
            return
        message = f"Physics state is invalid. Warning(s) raised: {', '.join(names)}"
        if self._warnings_cause_exception:
            raise control.PhysicsError(message)
        logging.warning(message)

    def angle(self) -> float:
        """phi in [-pi, pi) (rad): 0 upright, -pi hanging down."""
        return wrap_angle_float(self._qpos.item(self._qpos_adr))

    def angular_velocity(self) -> float:
        """phi_dot (rad/s)."""
        return self._qvel.item(self._qvel_adr)

    def state(self) -> np.ndarray:
        """x = [phi, phi_dot], phi wrapped; ndarray of shape (2,)."""
        return np.array((self.angle(), self.angular_velocity()))

    def state_of(self, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
        """x = [phi, phi_dot] (phi wrapped) of many physics states at once.

        Args:
          qpos, qvel: ndarrays of shape (..., nq) and (..., nv), e.g. from ``mujoco.rollout``.
        Returns:
          ndarray of shape (..., 2).
        """
        return np.stack(
            [common.wrap_angle(qpos[..., self._qpos_adr]), qvel[..., self._qvel_adr]], axis=-1
        )

    def set_state_vector(self, phi: float, phi_dot: float) -> None:
        """Put the pendulum at angle ``phi`` (rad) with speed ``phi_dot`` (rad/s), at rest otherwise."""
        self._qpos[self._qpos_adr] = phi
        self._qvel[self._qvel_adr] = phi_dot

    def set_voltage(self, u: float) -> None:
        """Command the motor voltage ``u`` (V); the actuator saturates it to its control range."""
        self._ctrl[self._motor] = u

    def voltage(self) -> float:
        """The motor voltage applied now (V), after saturation to the control range."""
        return min(max(self._ctrl.item(self._motor), self._ctrl_low), self._ctrl_high)

    def motor_torque(self) -> float:
        """Shaft torque of the motor (N m): (K/R) u - (K^2/R) phi_dot."""
        return float(self.data.actuator_force[self._motor])

    def orientation(self) -> np.ndarray:
        """[cos(phi), sin(phi)]; ndarray of shape (2,)."""
        # math.cos/sin are the C library's, which numpy's float64 cos/sin also call (numpy has no
        # SIMD float64 sin/cos, disabled in numpy#23925); tests/experiments/test_trajectory_pin.py catches a change.
        phi = self._qpos.item(self._qpos_adr)
        return np.array((math.cos(phi), math.sin(phi)))


class SwingUp(base.Task):
    """Swing-up and balance with the quadratic reward of section 6 (see the module docstring)."""

    def __init__(
        self,
        state_weights=STATE_WEIGHTS,
        action_weights: float = ACTION_WEIGHT,
        start_state=SWINGUP_START,
        start_noise: float = 0.0,
        random=None,
    ):
        """
        Args:
          state_weights: Q, as its diagonal (2,) or a full symmetric positive semi-definite (2, 2).
          action_weights: P >= 0, the reward's action weighting (one action: a number).
          start_state: x_0 = [phi, phi_dot] of every episode (rad, rad/s).
          start_noise: half-width (rad) of a uniform perturbation of the start angle, drawn from the
            task's random state; 0 makes every episode start exactly at ``start_state``.
          random: int seed, ``numpy.random.RandomState`` or None (dm-control's convention).
        """
        q = common.quadratic_weights("state_weights", state_weights, 2)
        if isinstance(action_weights, (list, tuple, np.ndarray)) and np.size(action_weights) == 1:
            action_weights = np.asarray(action_weights, dtype=float).item()
        if not (common.is_real(action_weights) and action_weights >= 0):
            raise ValueError(f"action_weights must be a finite number >= 0, got {action_weights!r}")
        x0 = common.check_start_state(start_state, 2, "[phi, phi_dot]")
        common.check_in("start_noise", start_noise, 0.0, np.pi, " rad")
        common.check_random(random)
        self._q = q
        self._p = float(action_weights)
        self._x = np.empty(2)  # scratch for x in the reward
        self._start_state = x0
        self._start_noise = float(start_noise)
        self._reward = 0.0
        super().__init__(random=random)

    @property
    def state_weights(self) -> np.ndarray:
        """Q, the reward's state weighting: ndarray of shape (2, 2) (a copy)."""
        return self._q.copy()

    @property
    def action_weights(self) -> float:
        """P, the reward's action weighting."""
        return self._p

    def initialize_episode(self, physics: Physics) -> None:
        phi, phi_dot = self._start_state
        if self._start_noise > 0:
            phi += self.random.uniform(-self._start_noise, self._start_noise)
        physics.set_state_vector(phi, phi_dot)
        self._reward = 0.0
        super().initialize_episode(physics)

    def before_step(self, action, physics: Physics) -> None:
        """Check the action, apply it, and charge r_k for the state before the step and the action.

        A wrong shape or a NaN/inf voltage raises ``ValueError`` before anything is applied.
        """
        action = np.asarray(action)
        if action.shape != (1,) and action.shape != ():
            raise ValueError(f"action must have shape (1,) (one voltage), got shape {action.shape}")
        if action.dtype.kind not in "iuf":  # a complex voltage is refused, not cut to its real part
            raise ValueError(f"action must be a real number, got {action!r}")
        u = float(action.item())
        if not math.isfinite(u):
            raise ValueError(f"action must be finite, got {action!r}")
        physics.set_voltage(u)
        u = physics.voltage()
        self._reward = (
            -self._state_cost(physics.angle(), physics.angular_velocity()) - self._p * u * u
        )

    def _state_cost(self, phi: float, phi_dot: float) -> float:
        """x^T Q x for x = [phi, phi_dot].

        Deliberately numpy's product (BLAS ``gemv`` then ``ddot``), not float arithmetic: BLAS may
        fuse the last multiply-add (it does on AVX2/AVX-512 machines), which rounds differently from
        ``a*b + c*d`` in about one reward in seven; keeping the product keeps every reward bit for bit.
        """
        x = self._x
        x[0], x[1] = phi, phi_dot
        return float(x.dot(self._q).dot(x))

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
        obs["angle"] = np.array((physics.angle(),))
        obs["velocity"] = np.array((physics.angular_velocity(),))
        obs["orientation"] = physics.orientation()
        return obs

    def get_reward(self, physics: Physics) -> float:
        """r_k of the step just taken (0 at reset, where dm-control reports no reward anyway)."""
        return self._reward

    @property
    def learner_state(self) -> common.LearnerStateSpec:
        """x = [phi, phi_dot]; the box is one period in phi and +-NOMINAL_SPEED; Table 2's weights; the
        reward's action cost P and state cost (Q's diagonal; None for a full Q)."""
        return common.LearnerStateSpec(
            keys=("angle", "velocity"),
            low=(-np.pi, -NOMINAL_SPEED),
            high=(np.pi, NOMINAL_SPEED),
            periodic=(True, False),
            labels=("angle phi [rad]", "angular velocity phi_dot [rad/s]"),
            input_weights=(1.0, 0.1),
            action_input_weights=(1.0,),
            action_labels=("u [V]",),
            action_cost=(self._p,),
            state_cost=tuple(np.diag(self._q))
            if np.array_equal(self._q, np.diag(np.diag(self._q)))
            else None,
            reward_scale=float(self._q[0, 0]) * math.pi**2 or None,
        )
