"""What every near-optimal solver shares: the trial from the environment, cache keys and dir.

A solver's problem is the task's own trial (model, horizon, reward, start: :class:`TrialProblem`),
named by :func:`problem_identity` and hashed by :func:`problem_digest`; a result is cached under
:func:`cache_key` (problem, solver settings, solver version).
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import inspect
import json
import os
import pathlib
import time
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np
from dm_control.rl import control
from mujoco import rollout

from rmac_mj._cache import user_cache_dir

Announce = Callable[[str], None]

_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


class TrialProblem:
    """The trial of a deterministic task as a solver sees it, read from its environment.

    The task must give ``reward_of(x, u)`` and its physics ``state_of(qpos, qvel)`` (both batched).

    Attributes:
      env: the environment; model: its compiled MuJoCo model.
      n_substeps: physics steps per control step; control_timestep: seconds per control step.
    """

    #: Who speaks in error messages ("optimal", "trajopt").
    owner = "solver"

    def __init__(self, env: control.Environment):
        task, physics = env.task, env.physics
        for owner, name in ((task, "reward_of"), (physics, "state_of")):
            if not callable(getattr(owner, name, None)):
                raise ValueError(
                    f"{self.owner}: {type(owner).__name__} has no {name}(); the task "
                    "must give its reward of batched states and actions"
                )
        self.env = env
        self.model = physics.model.ptr
        self.n_substeps = int(round(env.control_timestep() / physics.timestep()))
        self.control_timestep = float(env.control_timestep())

    def _full_state(self, data) -> np.ndarray:
        state = np.empty(mujoco.mj_stateSize(self.model, _FULL))
        mujoco.mj_getState(self.model, data, state, _FULL)
        return state

    def _check_deterministic_start(self, start: np.ndarray) -> None:
        """Reset once more and refuse a start that differs from ``start`` (a random start)."""
        self.env.reset()
        if not np.array_equal(self._full_state(self.env.physics.data.ptr), start):
            raise ValueError(
                f"{self.owner}: the task's start state is random (two resets differ); "
                "the near-optimal return is for a deterministic task (start_noise=0)"
            )


def constraint_free(model: mujoco.MjModel) -> bool:
    """Whether no constraint row can ever arise in ``model``: no equality, no limited joint or
    tendon, no friction loss, no flex, and contacts disabled or no geom able to collide (each
    counted only where its stage is not disabled already)."""
    flags, bit = model.opt.disableflags, mujoco.mjtDisableBit

    def off(flag) -> bool:
        return bool(flags & int(flag))

    collides = model.npair > 0 or bool(np.any(model.geom_contype) or np.any(model.geom_conaffinity))
    return (
        (model.neq == 0 or off(bit.mjDSBL_EQUALITY))
        and (
            not (np.any(model.jnt_limited) or np.any(model.tendon_limited)) or off(bit.mjDSBL_LIMIT)
        )
        and (
            not (np.any(model.dof_frictionloss) or np.any(model.tendon_frictionloss))
            or off(bit.mjDSBL_FRICTIONLOSS)
        )
        and (not collides or off(bit.mjDSBL_CONTACT))
        and model.nflex == 0
    )


def stepped_model(env: control.Environment) -> mujoco.MjModel:
    """A model of its own for a solver to step, every step the same to the bit as ``env``'s model.

    Where the task's module gives its model (``get_model_and_assets()``, dm-control's convention),
    it is compiled again without its geoms, cameras and lights (:func:`_dynamics_only`), kept only
    if it steps a probe batch exactly as the environment's model does; else a copy of that model.
    Where no constraint can arise (:func:`constraint_free`), the copy skips MuJoCo's constraint
    stage (``mjDSBL_CONSTRAINT``): with no constraint row it only copies the unconstrained
    acceleration. On the pendulum the two together make a step about a third cheaper.
    """
    model = env.physics.model.ptr
    stepped = _dynamics_only(env) or copy.copy(model)  # copy.copy: mj_copyModel
    if constraint_free(model):
        stepped.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    return stepped


def _dynamics_only(env: control.Environment) -> mujoco.MjModel | None:
    """The task's model without what only rendering and contacts use (geoms, cameras, lights), if
    its module gives the model and it steps a probe batch (random states and controls, beyond the
    control range too) exactly as the environment's model does; else None. Without contacts and
    with inertia given explicitly, geoms take no part in the dynamics: a step skips their poses."""
    model = env.physics.model.ptr
    source = getattr(inspect.getmodule(type(env.task)), "get_model_and_assets", None)
    if not callable(source):
        return None
    try:
        xml, assets = source()
        spec = mujoco.MjSpec.from_string(xml, assets)
        for element in (*spec.geoms, *spec.cameras, *spec.lights):
            spec.delete(element)
        bare = spec.compile()
    except (ValueError, TypeError, RuntimeError, mujoco.FatalError):
        return None
    return bare if _steps_alike(model, bare) else None


def _steps_alike(model: mujoco.MjModel, other: mujoco.MjModel, probes: int = 1000) -> bool:
    """Whether ``other`` steps ``probes`` random states and controls (controls to twice beyond
    each limited range) to exactly the same full physics states as ``model``, 3 steps each."""
    sizes = [mujoco.mj_stateSize(m, _FULL) for m in (model, other)]
    shape = (model.nq, model.nv, model.nu, model.na)
    if sizes[0] != sizes[1] or shape != (other.nq, other.nv, other.nu, other.na):
        return False
    rng = np.random.default_rng(0)
    state0 = np.zeros((probes, sizes[0]))
    state0[:, 1 : 1 + model.nq + model.nv] = rng.uniform(-4.0, 4.0, (probes, model.nq + model.nv))
    low, high = np.where(model.actuator_ctrllimited[:, None], model.actuator_ctrlrange, [-1, 1]).T
    span = high - low
    control = rng.uniform(low - span, high + span, (probes, 3, model.nu))
    steps = [rollout.rollout(m, mujoco.MjData(m), state0, control)[0] for m in (model, other)]
    return bool(np.array_equal(steps[0], steps[1], equal_nan=True))


def problem_identity(
    domain: str, task: str, task_kwargs: dict[str, Any] | None = None
) -> dict[str, Any]:
    """What names a task's problem for the caches: domain, task and task_kwargs."""
    return {"domain": domain, "task": task, "task_kwargs": dict(task_kwargs or {})}


def problem_digest(env: control.Environment, identity: dict[str, Any]) -> str:
    """Hex digest of the problem a solver solves: the compiled model, the source of the task's
    module (its reward, start, horizon: any change computes afresh) and ``identity``."""
    model = env.physics.model.ptr
    buffer = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    module = inspect.getmodule(type(env.task))
    blob = json.dumps(
        {
            **identity,
            "model": hashlib.sha256(buffer.tobytes()).hexdigest(),
            "task_source": hashlib.sha256(inspect.getsource(module).encode()).hexdigest(),
        },
        sort_keys=True,
        default=repr,
    )
    return hashlib.sha256(blob.encode()).hexdigest()


def cache_key(
    env: control.Environment, identity: dict[str, Any], config: Any, solver_version: int
) -> str:
    """Hex digest identifying a solver's result: the problem (:func:`problem_digest`), every field
    of the solver's ``config`` (a dataclass) but ``n_threads``, and the solver's version."""
    fields = dataclasses.asdict(config)
    fields.pop("n_threads", None)  # changes the speed, never the numbers
    blob = json.dumps(
        {
            "problem": problem_digest(env, identity),
            "config": fields,
            "solver_version": solver_version,
        },
        sort_keys=True,
        default=repr,
    )
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


def default_cache_dir() -> pathlib.Path:
    """``$RMAC_MJ_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/rmac-mj``, else ``~/.cache/rmac-mj``."""
    return user_cache_dir()


def cache_directory(cache_dir: str | os.PathLike | None) -> pathlib.Path:
    """``cache_dir`` as a path, or :func:`default_cache_dir` when None."""
    return pathlib.Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()


#: Seconds between two progress lines of a long computation.
PROGRESS_SECONDS = 10.0


class Ticker:
    """Calls ``announce(what)`` at most every :data:`PROGRESS_SECONDS` (long computations say they
    are alive)."""

    def __init__(self, announce: Announce | None):
        self.announce, self.seconds = announce, PROGRESS_SECONDS
        self.started = self.last = time.monotonic()

    def __call__(self, what: str) -> None:
        now = time.monotonic()
        if self.announce is not None and now - self.last >= self.seconds:
            self.announce(f"  ... {what} ({now - self.started:.0f} s)")
            self.last = now


def versions() -> dict[str, str]:
    """Package versions that computed a result (kept beside it in the cache)."""
    import scipy

    from rmac_mj import __version__

    return {
        "rmac_mj": __version__,
        "mujoco": mujoco.__version__,
        "numpy": np.__version__,
        "scipy": scipy.__version__,
    }
