"""A scripted swing-up of the pendulum, for tests that need a policy that works without learning."""

import numpy as np

from rmac_mj.agents import ActionSpace, PolicyAgent, StateSpace

_J, _MGL = 1.91e-4, 0.055 * 9.81 * 0.042  # inertia (kg m^2), M g l (N m) of Table 1


def _energy_pump(x):
    """A scripted swing-up: pump energy with +-3 V, then a PD balancer near the top."""
    phi, omega = x
    if abs(phi) < 0.8:
        return np.array([np.clip(-8.0 * phi - 0.6 * omega, -3.0, 3.0)])
    energy = 0.5 * _J * omega**2 + _MGL * (np.cos(phi) - 1.0)  # 0 upright at rest
    return np.array([3.0 if (omega >= 0) == (energy < 0) else -3.0])


def energy_pump_agent():
    """The scripted swing-up as an agent (no learning)."""
    return PolicyAgent(
        StateSpace(low=[-np.pi, -30.0], high=[np.pi, 30.0], periodic=[True, False]),
        ActionSpace(low=[-3.0], high=[3.0]),
        _energy_pump,
    )
