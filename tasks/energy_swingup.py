"""The DC-motor pendulum's demonstrator: energy-pumping swing-up, LQR balancer.

Astrom and Furuta's swing-up (Automatica 36, 2000), tuned on the model (its inertia; the discrete
LQR about upright), deliberately not optimal; ``dc_pendulum`` declares two as demonstrators ('demo',
'poor-demo') for ``rmac-mj reproduce --prior NAME``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import mujoco
import numpy as np
import scipy.linalg
from dm_control.rl import control

from rmac_mj.tasks import common


@dataclasses.dataclass(frozen=True)
class EnergySwingUp:
    """Energy-pumping swing-up with an LQR balancer for ``dc_pendulum``: pump energy with the
    largest allowed voltage in the direction of motion until the pendulum has the upright rest
    state's energy, coast, and hand over to the linear balance controller near upright.

    Attributes:
      pump_voltage: voltage (V) applied in the direction of motion while the pendulum has less
        energy than at rest upright; 0 once it has enough (coasting).
      balance_scale: factor on the LQR gains of the balancer (1: the LQR; below 1: a sluggish one).
      capture_angle: |phi| (rad) under which the balancer takes over.
      action_noise: standard deviation (V) of the Gaussian noise added to every recorded action, so
        that the recording excites the input (see ``prior.record``).
    """

    pump_voltage: float = 3.0
    balance_scale: float = 1.0
    capture_angle: float = 0.6
    action_noise: float = 0.5

    def __post_init__(self) -> None:
        for name in ("pump_voltage", "balance_scale", "capture_angle", "action_noise"):
            value = getattr(self, name)
            if not (np.isscalar(value) and np.isfinite(value) and value >= 0):
                raise ValueError(
                    f"EnergySwingUp.{name} must be a finite number >= 0, got {value!r}"
                )
        if not 0 < self.capture_angle < np.pi:
            raise ValueError(
                f"EnergySwingUp.capture_angle must be in (0, pi), got {self.capture_angle!r}"
            )

    def controller(self, env: control.Environment) -> Callable[[np.ndarray], np.ndarray]:
        """The controller x = [phi, phi_dot] -> u (shape (1,)), built from ``env``'s model."""
        physics = env.physics
        mass = float(physics.named.model.body_mass["pendulum"])
        com = np.asarray(physics.named.model.body_ipos["pendulum"], dtype=float)
        axis = np.asarray(physics.named.model.jnt_axis["hinge"], dtype=float)
        arm = float(np.linalg.norm(com - (com @ axis) * axis))  # CoM's distance from the axis (m)
        gravity = float(np.linalg.norm(physics.model.opt.gravity))
        inertia = _hinge_inertia(physics)
        gains = self.balance_scale * lqr_gains(env)
        low, high = (float(v) for v in physics.named.model.actuator_ctrlrange["motor"])
        pump, capture = float(self.pump_voltage), float(self.capture_angle)

        def control_law(x: np.ndarray) -> np.ndarray:
            phi, phi_dot = float(common.wrap_angle(x[0])), float(x[1])
            if abs(phi) < capture:
                u = -(gains[0] * phi + gains[1] * phi_dot)
            else:
                # Energy relative to rest upright: 0 there, -2 M g l hanging down at rest.
                energy = 0.5 * inertia * phi_dot**2 + mass * gravity * arm * (np.cos(phi) - 1.0)
                u = (pump if phi_dot >= 0 else -pump) if energy < 0 else 0.0
            return np.array([min(max(u, low), high)])

        return control_law


def _hinge_inertia(physics) -> float:
    """The pendulum's inertia about its hinge (kg m^2), from MuJoCo's joint-space inertia matrix."""
    model, data = physics.model.ptr, physics.data.ptr
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    dof = int(physics.named.model.jnt_dofadr["hinge"])
    return float(full[dof, dof])


def lqr_gains(env: control.Environment, epsilon: float = 1e-5) -> np.ndarray:
    """Discrete LQR gains K (shape (2,), u = -K x) of the pendulum about upright at rest.

    The model is linearised by central differences of one control step of the environment's own
    physics (a copy; ``env`` is not touched), with the task's own weights Q and P (``state_weights``,
    ``action_weights``; Table 1's diag(5, 0.1) and 1 by default).
    """
    physics = env.physics.copy(share_model=True)
    n_sub_steps = int(round(env.control_timestep() / physics.timestep()))

    def step(x: np.ndarray, u: float) -> np.ndarray:
        with physics.reset_context():
            physics.set_state_vector(float(x[0]), float(x[1]))
        physics.set_control(np.array([u]))
        for _ in range(n_sub_steps):
            physics.step()
        return np.array([physics.angle(), physics.angular_velocity()])

    A = np.empty((2, 2))
    for i in range(2):
        e = np.zeros(2)
        e[i] = epsilon
        A[:, i] = (step(e, 0.0) - step(-e, 0.0)) / (2 * epsilon)
    B = ((step(np.zeros(2), epsilon) - step(np.zeros(2), -epsilon)) / (2 * epsilon))[:, None]
    Q = np.asarray(env.task.state_weights, dtype=float)
    R = np.array([[env.task.action_weights]])
    S = scipy.linalg.solve_discrete_are(A, B, Q, R)
    return np.linalg.solve(R + B.T @ S @ B, B.T @ S @ A).reshape(2)
