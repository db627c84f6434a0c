"""dc_pendulum's fast ``Physics.step`` against dm-control's own: the same MuJoCo state, bit for bit,
and the same invalid-state checks."""

import numpy as np
import pytest
from dm_control.mujoco import engine
from dm_control.rl import control

from rmac_mj import tasks

#: MjData fields compared after every step: the state and what the step's last mj_step1 recomputes.
FIELDS = (
    "time",
    "qpos",
    "qvel",
    "qacc",
    "act",
    "ctrl",
    "xpos",
    "xquat",
    "cdof",
    "actuator_force",
    "actuator_velocity",
    "qfrc_bias",
    "qfrc_actuator",
    "energy",
    "warning",
)


def _pair(legacy_step: bool, integrator: int | None):
    envs = [
        tasks.load("dc_pendulum", "swingup", environment_kwargs={"legacy_step": legacy_step})
        for _ in range(2)
    ]
    for env in envs:
        env.reset()
        if integrator is not None:
            env.physics.model.opt.integrator = integrator
    return envs[0].physics, envs[1].physics


@pytest.mark.parametrize("legacy_step", [True, False])
@pytest.mark.parametrize("integrator", [None, 0, 3], ids=["rk4", "euler", "implicitfast"])
@pytest.mark.parametrize("nstep", [1, 3])
def test_step_leaves_the_same_mjdata_as_dm_controls(legacy_step, integrator, nstep):
    fast, stock = _pair(legacy_step, integrator)
    rng = np.random.default_rng(0)
    for _ in range(30):
        u = rng.uniform(-4, 4)
        fast.set_voltage(u)
        stock.set_control([u])
        fast.step(nstep)
        engine.Physics.step(stock, nstep)  # dm-control's implementation on an identical twin
        for field in FIELDS:
            a, b = getattr(fast.data.ptr, field), getattr(stock.data.ptr, field)
            if field == "warning":
                a, b = [w.number for w in a], [w.number for w in b]
            np.testing.assert_array_equal(a, b, err_msg=field)


@pytest.mark.parametrize("step", ["fast", "dm-control"])
def test_an_exploding_state_raises_physics_error_or_logs_when_suppressed(step):
    env = tasks.load("dc_pendulum", "swingup")
    env.reset()
    physics = env.physics
    do_step = physics.step if step == "fast" else (lambda n: engine.Physics.step(physics, n))
    with physics.reset_context():
        physics.set_state_vector(0.0, 0.0)
    physics.set_state_vector(0.0, np.nan)
    with pytest.raises(control.PhysicsError, match="mjWARN_BADQVEL"):
        do_step(3)
    physics.set_state_vector(0.0, np.nan)
    with physics.suppress_physics_errors():
        do_step(3)  # logged, not raised (MuJoCo has reset the state)
    assert np.isfinite(physics.angular_velocity())
    do_step(3)  # no new warning: no error


@pytest.mark.parametrize(
    "counts",
    [(0, 0, 0, 0, 0, 0, 0), (0, 0, 0, 0, 5, 0, 0), (0, 0, 0, 0, 1, 0, 0), (2, 0, 0, 0, 0, 0, 0)],
)
def test_errors_exactly_when_dm_controls_step_does(counts):
    # MuJoCo's automatic reset after a NaN velocity zeroes the warning counters, then counts
    # BADQVEL once: with a higher count before, no counter grows and dm-control raises nothing.
    outcomes = []
    for step in ("fast", "dm-control"):
        env = tasks.load("dc_pendulum", "swingup")
        env.reset()
        physics = env.physics
        physics.data.warning.number[:] = counts[: len(physics.data.warning.number)]
        physics.set_state_vector(0.0, np.nan)
        try:
            physics.step(3) if step == "fast" else engine.Physics.step(physics, 3)
            outcomes.append("no error")
        except control.PhysicsError as error:
            outcomes.append(str(error))
    assert outcomes[0] == outcomes[1]


def test_env_step_raises_physics_error_through_dm_control():
    env = tasks.load("dc_pendulum", "swingup")
    env.reset()
    env.physics.set_state_vector(0.0, 1e11)  # beyond MuJoCo's mjMAXVAL
    with pytest.raises(control.PhysicsError):
        env.step([0.0])


def test_accessors_follow_a_reloaded_model():
    env = tasks.load("dc_pendulum", "swingup")
    env.reset()
    physics = env.physics
    copy = physics.copy()
    physics.set_state_vector(1.0, 2.0)
    copy.set_state_vector(-1.0, -2.0)  # the copy's cached views point at its own MjData
    assert (physics.angle(), physics.angular_velocity()) == (1.0, 2.0)
    assert (copy.angle(), copy.angular_velocity()) == (-1.0, -2.0)
    physics.reload_from_xml_string(*tasks.dc_pendulum.get_model_and_assets())
    physics.set_state_vector(0.5, 0.0)
    physics.step(3)  # steps the new MjData, whose fresh warning counters it checks
    assert physics.data.time == pytest.approx(0.03)
    assert physics.angle() == pytest.approx(physics.data.qpos[0]) and physics.angle() != 0.5
