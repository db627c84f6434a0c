"""The paper's DC-motor pendulum (Table 1) integrated with plain Python floats (Euler, 3 x 0.01 s per
0.03 s control step), so that tests pinning a learner's results depend on no simulator."""

import math

import numpy as np

J, MASS, G, LENGTH, DAMPING, K, R = 1.91e-4, 0.055, 9.81, 0.042, 3e-6, 0.0536, 9.5


def integrate(phi: float, w: float, u: float) -> tuple[float, float]:
    """One control step from (phi, w) under u volts; phi wrapped to [-pi, pi)."""
    for _ in range(3):
        w += 0.01 * (MASS * G * LENGTH * math.sin(phi) - (DAMPING + K * K / R) * w + K / R * u) / J
        phi = (phi + 0.01 * w + math.pi) % (2 * math.pi) - math.pi
    return phi, w


def control_step(x, u):
    """One control step from x = [phi, w] under u; a second action, if any, turns the pendulum by
    0.01 rad per unit. Returns (reward, next state)."""
    phi, w = integrate(float(x[0]), float(x[1]), u[0])
    if len(u) > 1:
        phi = (phi + 0.01 * u[1] + math.pi) % (2 * math.pi) - math.pi
    return -(5.0 * phi * phi + 0.1 * w * w + float(u @ u)), np.array([phi, w])


def returns(agent, trials: int, steps: int = 100) -> list[float]:
    """The sums of rewards of ``trials`` learning trials of ``agent`` from hanging down at rest."""
    out = []
    for _ in range(trials):
        phi, w = -math.pi, 0.0
        u = float(agent.start(np.array([phi, w]))[0])
        total = 0.0
        for k in range(1, steps + 1):
            phi, w = integrate(phi, w, u)
            reward = -(5.0 * phi * phi + 0.1 * w * w + u * u)
            total += reward
            x = np.array([phi, w])
            if k == steps:
                agent.stop(reward, x)
            else:
                u = float(agent.step(reward, x)[0])
        out.append(total)
    return out
