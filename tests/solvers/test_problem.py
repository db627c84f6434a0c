"""The model a solver steps (``problem.stepped_model``): without geoms, cameras and lights where the
task's module gives its model, constraints skipped only where none can arise, every step the same
to the bit; a model that steps otherwise is not taken."""

from __future__ import annotations

import mujoco
import numpy as np
from mujoco import rollout

from rmac_mj import tasks
from rmac_mj.solvers import problem
from rmac_mj.solvers.problem import constraint_free, stepped_model

_CONSTRAINT = int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)

_LIMITED = """
<mujoco>
  <option><flag contact="disable"/></option>
  <worldbody><body><joint name="j" type="hinge" axis="0 1 0" range="-1 1"/>
    <geom type="capsule" size="0.02" fromto="0 0 0 0 0 0.3" mass="0.1"/></body></worldbody>
  <actuator><motor joint="j"/></actuator>
</mujoco>
"""


def _steps(model, seed=0, n=2000):
    rng = np.random.default_rng(seed)
    size = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    state0 = np.zeros((n, size))
    state0[:, 1 : 1 + model.nq] = rng.uniform(-4, 4, (n, model.nq))
    state0[:, 1 + model.nq : 1 + model.nq + model.nv] = rng.uniform(-25, 25, (n, model.nv))
    control = rng.uniform(-3, 3, (n, 3, model.nu))
    return rollout.rollout(model, mujoco.MjData(model), state0, control)[0]


def test_the_pendulum_is_stepped_without_geoms_and_constraint_stage_and_the_same():
    env = tasks.load("dc_pendulum", "swingup")
    model = env.physics.model.ptr
    stepped = stepped_model(env)
    assert constraint_free(model) and stepped is not model
    assert stepped.ngeom == 0 and model.ngeom > 0
    assert stepped.opt.disableflags & _CONSTRAINT and not model.opt.disableflags & _CONSTRAINT
    np.testing.assert_array_equal(_steps(stepped), _steps(model))


def test_a_model_of_the_module_that_steps_otherwise_is_not_taken(monkeypatch):
    env = tasks.load("dc_pendulum", "swingup")
    module = type(env.task).__module__
    xml, assets = tasks.dc_pendulum.get_model_and_assets()
    heavier = {
        name: data.replace(b'mass="0.055"', b'mass="0.056"') for name, data in assets.items()
    }
    monkeypatch.setattr(f"{module}.get_model_and_assets", lambda: (xml, heavier))
    assert problem._dynamics_only(env) is None
    stepped = stepped_model(env)  # the environment's own model, copied
    assert stepped.ngeom == env.physics.model.ngeom
    np.testing.assert_array_equal(_steps(stepped), _steps(env.physics.model.ptr))


def test_a_joint_limit_keeps_the_constraint_stage():
    model = mujoco.MjModel.from_xml_string(_LIMITED)
    assert not constraint_free(model)
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_LIMIT)
    assert constraint_free(model)
    model.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    assert not constraint_free(model)  # its capsule may collide now
