"""Where an environment comes from (its SPEC) and how the learners see it (:class:`EnvSpec`).

A SPEC is ``dm_control:DOMAIN/TASK``, ``gymnasium:ID`` (a bounded Box action space) or
``package.module:factory`` / ``path/file.py:factory`` (returns a dm_env or Gymnasium environment;
given ``kwargs``, and ``seed=`` when it takes one).
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import hashlib
import importlib
import importlib.metadata
import importlib.util
import inspect
import math
import pathlib
import secrets
import sys
import zlib
from collections.abc import Callable, Mapping
from typing import Any

import dm_env
import numpy as np

from rmac_mj import _heartbeat as heartbeat
from rmac_mj.constraints import MIN_CONTROL_TIMESTEP, OBSERVATION_SIZE, TRIAL_STEPS
from rmac_mj.envs.environment import Environment, trial_steps
from rmac_mj.envs.failures import outside, read_observation
from rmac_mj.envs.from_gymnasium import GymnasiumEnvironment
from rmac_mj.envs.observation_map import ObservationLayout, ObservationMap, layout_of_dm_env
from rmac_mj.envs.observations import check_declaration, infer_learner_state
from rmac_mj.errors import UserInputError
from rmac_mj.tasks.common import LearnerStateSpec

#: The SPEC prefixes that name a library rather than a module of the user's.
SOURCES = ("dm_control", "gymnasium")
#: Probing for (cos, sin) pairs: episodes of uniformly random actions, their steps, and the seed.
PROBE_EPISODES, PROBE_STEPS, PROBE_SEED = 3, 100, 0
#: The longest episode run to find where an environment without a time limit truncates.
MAX_PROBE_STEPS = 100_000
#: Measuring the box where the specs give none: environment steps of uniformly random actions (held
#: for the action repeat, whole episodes up to the trial length), with the probes' seed.
BOX_PROBE_STEPS = 10_000


def parse(spec: str) -> tuple[str, str]:
    """``(source, target)`` of a SPEC: ('dm_control', 'DOMAIN/TASK'), ('gymnasium', 'ID') or
    ('factory', 'module:function'); ValueError naming the SPEC otherwise."""
    if not isinstance(spec, str) or ":" not in spec:
        raise ValueError(
            f"env {spec!r} must read dm_control:DOMAIN/TASK, gymnasium:ID, "
            f"package.module:factory or path/to/file.py:factory"
        )
    prefix, _, rest = spec.partition(":")
    if prefix == "dm_control":
        domain, _, task = rest.partition("/")
        if not domain or not task or "/" in task:
            raise ValueError(
                f"env {spec!r} must read dm_control:DOMAIN/TASK, e.g. dm_control:cartpole/swingup"
            )
        return prefix, rest
    if prefix == "gymnasium":
        if not rest:
            raise ValueError(f"env {spec!r} must read gymnasium:ID, e.g. gymnasium:Pendulum-v1")
        return prefix, rest
    module, _, function = spec.rpartition(":")
    if not module or not function or not all(part.isidentifier() for part in function.split(".")):
        raise ValueError(
            f"env {spec!r}: a factory must read package.module:function or path/to/file.py:function"
        )
    return "factory", spec


def user_code(spec: str) -> bool:
    """Whether the SPEC names code of the user's, a module or a file (``module:factory``,
    ``path/file.py:factory``, a Gymnasium id its module qualifies, ``gymnasium:module:Id``), rather
    than an environment of a registry (dm-control's suite, Gymnasium's): code that opening a
    snapshot or a result directory must not run unless the user names it again."""
    source, target = parse(spec)
    return source == "factory" or (source == "gymnasium" and ":" in target)


def canonical(spec: str) -> str:
    """The SPEC with a file's path made absolute and its links resolved
    (``envs.py:make`` -> ``/home/me/run/envs.py:make``): the same file from any working directory."""
    source, _ = parse(spec)
    module, _, function = spec.rpartition(":")
    if source != "factory" or not module.endswith(".py"):
        return spec
    return f"{pathlib.Path(module).expanduser().resolve()}:{function}"


def origin(spec: str) -> dict[str, Any]:
    """Where the environment of the SPEC comes from, exactly, as JSON data: a file's resolved path
    and the SHA-256 of its bytes (read, not run); a module's file and digest (found by importing
    its parent packages, not itself); a registry's package and version, e.g.
    ``{"package": "gymnasium", "version": "1.4.0"}``. Only the file that holds the factory is
    digested, not the modules it imports."""
    source, target = parse(spec)
    if source in SOURCES:
        found: dict[str, Any] = {"package": source, "version": installed_version(source)}
        if source == "gymnasium" and ":" in target:
            found.update(_module_origin(target.partition(":")[0]))
        return found
    module, _, _ = spec.rpartition(":")
    if module.endswith(".py"):
        path = pathlib.Path(module).expanduser().resolve()
        return {"file": str(path), "sha256": _digest(path)}
    return _module_origin(module)


def describe_origin(found: Any) -> str:
    """An :func:`origin` as people read it: ``file /x/envs.py (sha256 1a2b3c4d5e6f...)``."""
    if not isinstance(found, dict):
        return repr(found)
    if "package" in found and "file" not in found:
        return f"{found['package']} {found.get('version')}"
    digest = found.get("sha256")
    held = f"sha256 {digest[:12]}..." if digest else "no such file"
    if "module" in found:
        return f"module {found['module']} ({found.get('file') or 'no file'}, {held})"
    return f"file {found.get('file')} ({held})"


def origin_problem(recorded: Any, now: dict[str, Any]) -> str | None:
    """None when the environment comes from where it was ``recorded`` to (:func:`origin`), else
    both, as people read them: ``file /x/envs.py (sha256 1a2b...) then, ... (sha256 9f8e...) now``."""
    if recorded is None or recorded == now:
        return None
    return f"{describe_origin(recorded)} then, {describe_origin(now)} now"


def _module_origin(name: str) -> dict[str, Any]:
    try:
        found = importlib.util.find_spec(name)
    except (ImportError, ValueError):
        found = None
    path = found.origin if found is not None and found.has_location else None
    if path is None:
        return {"module": name, "file": None, "sha256": None}
    path = pathlib.Path(path).resolve()
    return {"module": name, "file": str(path), "sha256": _digest(path)}


def _digest(path: pathlib.Path) -> str | None:
    """The SHA-256 of the file's bytes, None when there is no such file."""
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def installed_version(distribution: str) -> str | None:
    """The installed version of a distribution (``"gymnasium"``, ``"rmac-mj"``), None if it is not
    installed."""
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return None


def load_factory(target: str) -> Callable[..., Any]:
    """The function a ``module:function`` or ``file.py:function`` SPEC names.

    A file's folder goes first on ``sys.path`` (if it is not there), as ``python file.py`` puts it:
    the file imports the modules beside it, in this process and in every worker that loads it."""
    module_name, _, attribute = target.rpartition(":")
    if module_name.endswith(".py"):
        path = pathlib.Path(module_name).expanduser().resolve()
        if not path.is_file():
            raise ValueError(f"env {target!r}: no file {str(path)!r}")
        if str(path.parent) not in sys.path:
            sys.path.insert(0, str(path.parent))
        name = f"rmac_mj_user_{path.stem}_{zlib.crc32(str(path).encode()):08x}"
        module = sys.modules.get(name)
        if module is None:
            loader_spec = importlib.util.spec_from_file_location(name, path)
            module = importlib.util.module_from_spec(loader_spec)
            sys.modules[name] = module
            try:
                with outside(target, f"module {path.name}"):
                    loader_spec.loader.exec_module(module)
            except BaseException:
                del sys.modules[name]  # half run: import it afresh next time
                raise
    else:
        with outside(target, f"module {module_name}"):
            try:
                module = importlib.import_module(module_name)
            except ImportError as error:
                raise UserInputError(
                    f"env {target!r}: cannot import {module_name!r} ({error}); a module "
                    f"must be installed or on PYTHONPATH, or give path/to/file.py:"
                    f"{attribute}"
                ) from None
    try:
        factory = functools.reduce(getattr, attribute.split("."), module)
    except AttributeError:
        raise ValueError(
            f"env {target!r}: {module_name!r} has no {attribute!r}{_did_you_mean(module, attribute)}"
        ) from None
    if not callable(factory):
        raise ValueError(f"env {target!r}: {attribute!r} is not callable")
    return factory


def _did_you_mean(module: Any, attribute: str) -> str:
    """``" (did you mean 'make'?)"``: the callable of ``module`` (or of the object the dotted
    ``attribute`` reaches before the missing name) closest to the missing name, or nothing."""
    *owners, missing = attribute.split(".")
    try:
        owner = functools.reduce(getattr, owners, module)
    except AttributeError:
        return ""
    names = [n for n in dir(owner) if not n.startswith("_") and callable(getattr(owner, n, None))]
    close = difflib.get_close_matches(missing, names, n=1)
    return f" (did you mean {'.'.join([*owners, close[0]])!r}?)" if close else ""


@dataclasses.dataclass(frozen=True)
class EnvSpec:
    """An outside environment and how the learners see it.

    Attributes:
      env: the SPEC (``dm_control:DOMAIN/TASK``, ``gymnasium:ID`` or ``module:factory``).
      kwargs: keyword arguments of the environment: dm-control's ``task_kwargs`` (e.g.
        ``time_limit``; not ``random``, the seed), ``gymnasium.make``'s (e.g. ``g``,
        ``max_episode_steps``), or the factory's.
      learner_state: what x is: a :class:`~rmac_mj.tasks.common.LearnerStateSpec`, or a mapping of some
        of its fields (a ``[learner_state]`` table) with the others inferred, or None (all inferred;
        a dm-control task that declares ``learner_state`` itself is taken at its word).
      action_repeat: environment steps per learner step, with the same action (rewards summed).
      trial_steps: learner steps after which a trial is truncated; None: the environment's own time
        limit (dm-control's, Gymnasium's ``max_episode_steps``).
      control_timestep: seconds per environment step where the environment does not say (a plain
        dm_env, a Gymnasium env without ``dt``); None: the environment's.
      measured_bounds: set by :meth:`resolve`: the dimensions of x whose box neither the specs nor
        the declaration gave, measured from random-action rollouts
        (:func:`~rmac_mj.envs.observations.measured_box`), name -> [low, high]; None: none.
    """

    env: str
    kwargs: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    learner_state: LearnerStateSpec | Mapping[str, Any] | None = None
    action_repeat: int = 1
    trial_steps: int | None = None
    control_timestep: float | None = None
    measured_bounds: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "env", canonical(self.env))  # parses it too
        if not isinstance(self.kwargs, Mapping):
            raise ValueError(f"EnvSpec.kwargs must be a mapping, got {self.kwargs!r}")
        object.__setattr__(self, "kwargs", dict(self.kwargs))
        if self.source == "dm_control" and "random" in self.kwargs:
            raise ValueError(
                "EnvSpec.kwargs must not set 'random': the seed comes from the experiment"
            )
        if not isinstance(self.learner_state, (LearnerStateSpec, type(None))):
            object.__setattr__(self, "learner_state", check_declaration(self.learner_state))
        for name, value in (
            ("action_repeat", self.action_repeat),
            ("trial_steps", self.trial_steps),
        ):
            if value is None and name == "trial_steps":
                continue
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"EnvSpec.{name} must be a positive integer, got {value!r}")
        dt = self.control_timestep
        if dt is not None and not (
            isinstance(dt, (int, float))
            and not isinstance(dt, bool)
            and math.isfinite(dt)
            and dt >= MIN_CONTROL_TIMESTEP
        ):
            raise ValueError(
                f"EnvSpec.control_timestep must be a number of seconds >= "
                f"{MIN_CONTROL_TIMESTEP:g}, got {dt!r}"
            )

    @property
    def source(self) -> str:
        """'dm_control', 'gymnasium' or 'factory'."""
        return parse(self.env)[0]

    # ------------------------------------------------------------------------------- building
    def build_base(self, seed: int | None = None, render: bool = False) -> dm_env.Environment:
        """The environment itself as a ``dm_env.Environment`` (Gymnasium's adapted), seeded; with
        ``render``, a Gymnasium environment (or a factory that takes ``render_mode``) is made with
        ``render_mode="rgb_array"``."""
        source, target = parse(self.env)
        kwargs = dict(self.kwargs)
        if source == "dm_control":
            from dm_control import suite

            domain, task = target.split("/")
            if (domain, task) not in suite.ALL_TASKS:
                known = ", ".join(
                    f"{d}/{t}" for d, t in suite.ALL_TASKS if d == domain
                ) or ", ".join(sorted(suite.TASKS_BY_DOMAIN))
                raise ValueError(
                    f"env {self.env!r}: dm-control has no {target!r}; "
                    f"{'its tasks' if domain in suite.TASKS_BY_DOMAIN else 'domains'}: "
                    f"{known}"
                )
            with outside(self.env, "suite.load"):
                return suite.load(domain, task, task_kwargs=dict(kwargs, random=seed))
        if source == "gymnasium":
            try:
                import gymnasium
            except ImportError:
                raise ValueError(
                    f"env {self.env!r} needs Gymnasium: pip install gymnasium"
                ) from None
            if render:
                kwargs["render_mode"] = "rgb_array"
            with outside(self.env, "gymnasium.make"):
                try:
                    env = gymnasium.make(target, **kwargs)
                except gymnasium.error.Error as error:  # an unknown id, a bad argument
                    raise UserInputError(f"env {self.env!r}: {error}") from None
            return GymnasiumEnvironment(env, seed=seed, name=self.env)
        factory = load_factory(target)
        parameters = inspect.signature(factory).parameters
        if "seed" in parameters and (
            seed is not None or parameters["seed"].default is inspect.Parameter.empty
        ):  # a factory that requires its seed gets fresh entropy where no seed is given
            kwargs["seed"] = seed if seed is not None else secrets.randbits(31)
        if render and "render_mode" in parameters:
            kwargs["render_mode"] = "rgb_array"
        with outside(self.env, "factory"):
            made = factory(**kwargs)
        if isinstance(made, dm_env.Environment):
            return made
        if _is_gymnasium_env(made):
            return GymnasiumEnvironment(made, seed=seed, name=self.env)
        raise ValueError(
            f"env {self.env!r}: the factory returned a {type(made).__name__}, not a "
            f"dm_env.Environment or a gymnasium.Env"
        )

    def make(self, seed: int | None = None, render: bool = False) -> Environment:
        """The environment the learners run on, seeded with ``seed`` (an int, or None for fresh
        entropy): x as :meth:`resolve` says, trials as long as its time limit or ``trial_steps``.
        ``render``: able to draw its frames (:meth:`Environment.render_frame`)."""
        with heartbeat.working(f"env {self.env!r}: building it"):
            base = self.build_base(seed, render)
        spec = self
        if not isinstance(self.learner_state, LearnerStateSpec) or (
            self.trial_steps is None and _step_limit(base) is None
        ):
            spec = self.resolve()
        base_dt, base_limit = spec._time_of(base)
        steps = spec.trial_steps or trial_steps(base_limit, spec.action_repeat)
        return Environment(
            base,
            spec.learner_state,
            _layout(base),
            base_dt,
            steps,
            action_repeat=spec.action_repeat,
            name=self.env,
        )

    def resolve(self) -> EnvSpec:
        """This spec with its full LearnerStateSpec (declared fields kept, the rest inferred, probing an
        instance of the environment of its own for (cos, sin) pairs when ``keys`` are not given) and,
        for an environment without a time limit that truncates its episodes itself, ``trial_steps``
        measured. Raises ValueError, in one line, on whatever is missing or ambiguous."""
        with heartbeat.working(f"env {self.env!r}: probing it before the run"):
            return self._resolve()

    def _resolve(self) -> EnvSpec:
        base = self.build_base(PROBE_SEED)
        spec = self
        if self.trial_steps is None and _step_limit(base) is None:
            spec = dataclasses.replace(spec, trial_steps=_truncation_steps(base, self))
            base = self.build_base(PROBE_SEED)
        spec._time_of(base)  # refuse an environment without a time step now
        declared = self.learner_state
        if isinstance(declared, LearnerStateSpec):
            return spec
        own = _own_learner_state(base)
        if declared is None and isinstance(own, LearnerStateSpec):
            return dataclasses.replace(spec, learner_state=own)
        if isinstance(own, Mapping):  # the environment's own fields, the user's over them
            declared = _declared_over(check_declaration(own), check_declaration(declared))
        layout = _layout(base)
        needs_probe = not (declared and "keys" in declared)
        size = sum(layout.sizes.values())
        if needs_probe and size > OBSERVATION_SIZE.value:  # the probe keeps hundreds of them
            raise ValueError(
                OBSERVATION_SIZE.refusal(f"env {self.env!r}: the observation's size", size)
                + "; declare learner_state.keys to learn on some of its entries"
            )
        samples = _probe(base, layout, self.env) if needs_probe else np.zeros((0, size))
        action = base.action_spec()
        measured: dict[str, list[float]] = {}
        learner_state = infer_learner_state(
            layout,
            samples,
            np.broadcast_to(action.minimum, action.shape),
            np.broadcast_to(action.maximum, action.shape),
            declared,
            owner=self.env,
            measure=lambda mapping: _random_states(self.build_base(PROBE_SEED), mapping, spec),
            measured=measured,
        )
        base.close()
        return dataclasses.replace(
            spec, learner_state=learner_state, measured_bounds=measured or self.measured_bounds
        )

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: every field, the learner state as its fields."""
        learner_state = self.learner_state
        if isinstance(learner_state, LearnerStateSpec):
            learner_state = dataclasses.asdict(learner_state)
        document = {
            "env": self.env,
            "kwargs": dict(self.kwargs),
            "learner_state": learner_state,
            "action_repeat": int(self.action_repeat),
            "trial_steps": self.trial_steps,
            "control_timestep": self.control_timestep,
        }
        if self.measured_bounds:  # only then: an environment with bounds is described as before
            document["measured_bounds"] = {k: list(v) for k, v in self.measured_bounds.items()}
        return document

    def _time_of(self, base: dm_env.Environment) -> tuple[float, int]:
        """(seconds per base step, base steps per episode); ValueError naming what is missing."""
        dt = self.control_timestep
        if dt is None:
            own = getattr(base, "control_timestep", None)
            dt = own() if callable(own) else None
        if dt is None or not dt > 0:
            raise ValueError(
                f"env {self.env!r} does not say its time step (no dt); give "
                f"--control-timestep S, the seconds per environment step (control_timestep "
                f"in a --config file's [protocol] or to envs.load)"
            )
        if not dt >= MIN_CONTROL_TIMESTEP:
            raise ValueError(
                f"env {self.env!r} says its time step is {dt:g} s, less than "
                f"{MIN_CONTROL_TIMESTEP:g} s; set control_timestep (seconds per environment step)"
            )
        limit = _step_limit(base)
        if limit is None and self.trial_steps is None:
            raise ValueError(
                f"env {self.env!r} has no time limit and does not truncate its "
                f"episodes; give --trial-steps N (trial_steps in a --config file's "
                f"[protocol] or to envs.load; for Gymnasium, max_episode_steps in its kwargs)"
            )
        steps = None if limit is None else trial_steps(limit, self.action_repeat)
        if self.trial_steps is None and steps > TRIAL_STEPS.value:
            raise ValueError(
                TRIAL_STEPS.refusal(f"env {self.env!r}: its time limit in learner steps", steps)
                + "; set trial_steps (a shorter trial)"
            )
        return float(dt), limit if limit is not None else self.trial_steps * self.action_repeat


def _own_learner_state(base: dm_env.Environment) -> LearnerStateSpec | Mapping[str, Any] | None:
    """What the environment declares of x itself: the ``learner_state`` of a dm-control task
    (``base.task``), of a Gymnasium environment (its ``unwrapped`` one) or of the environment a
    factory returned: a LearnerStateSpec, or a mapping of some of its fields and ``bounds`` (a
    ``[learner_state]`` table); None when it declares nothing."""
    holders = (
        [base.env.unwrapped]
        if isinstance(base, GymnasiumEnvironment)
        else [getattr(base, "task", None), base]
    )
    for holder in holders:
        own = getattr(holder, "learner_state", None)
        if isinstance(own, (LearnerStateSpec, Mapping)):
            return own
    return None


def _declared_over(own: dict[str, Any], declared: dict[str, Any]) -> dict[str, Any]:
    """The environment's ``own`` declaration with the user's ``declared`` fields over it, field by
    field (``bounds`` dimension by dimension)."""
    merged = {**own, **declared}
    if "bounds" in own and "bounds" in declared:
        merged["bounds"] = {**own["bounds"], **declared["bounds"]}
    return merged


def _is_gymnasium_env(obj: Any) -> bool:
    gymnasium = sys.modules.get("gymnasium")
    return gymnasium is not None and isinstance(obj, gymnasium.Env)


def _layout(base: dm_env.Environment) -> ObservationLayout:
    layout = getattr(base, "layout", None)  # a GymnasiumEnvironment knows its space's bounds
    return (
        layout
        if isinstance(layout, ObservationLayout)
        else layout_of_dm_env(base.observation_spec())
    )


def _step_limit(base: dm_env.Environment) -> int | None:
    """Steps per episode of ``base``: Gymnasium's ``max_episode_steps``, dm-control's step limit
    (private there; read here as the trial loop does), None when it has none."""
    if isinstance(base, GymnasiumEnvironment):
        return base.step_limit()
    limit = getattr(base, "_step_limit", None)
    if limit is None or not math.isfinite(limit) or limit <= 0:
        return None
    return int(math.ceil(limit))


def _truncation_steps(base: dm_env.Environment, spec: EnvSpec) -> int | None:
    """Learner steps per trial of an environment that truncates its episodes itself (a ``last()``
    with a nonzero discount) at the same step in each of two probe episodes of random actions;
    None when it terminates instead, varies, or runs past :data:`MAX_PROBE_STEPS`."""
    rng = np.random.default_rng(PROBE_SEED)
    action = base.action_spec()
    low = np.broadcast_to(action.minimum, action.shape).astype(float)
    high = np.broadcast_to(action.maximum, action.shape).astype(float)
    lengths = set()
    what = f"env {spec.env!r}: 2 episodes of random actions, to find where it ends them"
    with heartbeat.working(what, unit="steps") as work:
        for _ in range(2):
            _probe_call(spec.env, "reset", base.reset)
            for steps in range(1, MAX_PROBE_STEPS + 1):  # noqa: B007 (read after the loop)
                timestep = _probe_call(spec.env, "step", base.step, rng.uniform(low, high))
                work.done += 1
                if timestep.last():
                    break
            if not timestep.last() or timestep.discount == 0.0:
                return None
            lengths.add(steps)
    return trial_steps(lengths.pop(), spec.action_repeat) if len(lengths) == 1 else None


def _random_states(base: dm_env.Environment, mapping: ObservationMap, spec: EnvSpec) -> np.ndarray:
    """States x (shape (T, n)) a learner sees under uniformly random actions, each held for the
    action repeat: whole episodes (up to ``spec.trial_steps``) until :data:`BOX_PROBE_STEPS`
    environment steps, seeded with :data:`PROBE_SEED`."""
    rng = np.random.default_rng(PROBE_SEED)
    action = base.action_spec()
    low = np.broadcast_to(action.minimum, action.shape).astype(float)
    high = np.broadcast_to(action.maximum, action.shape).astype(float)
    states, taken = [], 0
    what = f"env {spec.env!r}: measuring the state's box from random actions"
    with heartbeat.working(what, BOX_PROBE_STEPS, "steps") as work:
        while taken < BOX_PROBE_STEPS:
            timestep, steps = _probe_call(spec.env, "reset", base.reset), 0
            states.append(_probe_read(spec.env, "reset", mapping, timestep, mapping.dim))
            while (
                not timestep.last()
                and taken < BOX_PROBE_STEPS
                and (spec.trial_steps is None or steps < spec.trial_steps)
            ):
                u = rng.uniform(low, high)
                for _ in range(spec.action_repeat):
                    timestep = _probe_call(spec.env, "step", base.step, u)
                    taken += 1
                    if timestep.last():
                        break
                steps += 1
                work.done = taken
                states.append(_probe_read(spec.env, "step", mapping, timestep, mapping.dim))
    base.close()
    return np.asarray(states)


def _probe(base: dm_env.Environment, layout: ObservationLayout, env: str) -> np.ndarray:
    """Raw observations (flattened, shape (T, size)) of a few episodes of uniform random actions."""
    rng = np.random.default_rng(PROBE_SEED)
    spec = base.action_spec()
    low = np.broadcast_to(spec.minimum, spec.shape).astype(float)
    high = np.broadcast_to(spec.maximum, spec.shape).astype(float)
    flatten = ObservationMap([], layout).flat
    size = sum(layout.sizes.values())
    samples = []
    what = f"env {env!r}: {PROBE_EPISODES} episodes of random actions, to infer the learner's state"
    with heartbeat.working(what, PROBE_EPISODES * (PROBE_STEPS + 1), "observations") as work:
        for _ in range(PROBE_EPISODES):
            timestep = _probe_call(env, "reset", base.reset)
            samples.append(_probe_read(env, "reset", flatten, timestep, size))
            for _ in range(PROBE_STEPS):
                timestep = _probe_call(env, "step", base.step, rng.uniform(low, high))
                samples.append(_probe_read(env, "step", flatten, timestep, size))
                work.done = len(samples)
                if timestep.last():
                    break
    return np.asarray(samples)


def _probe_call(env: str, phase: str, call: Callable[..., Any], *args: Any) -> Any:
    """``call(*args)``, the environment's ``reset`` or ``step`` while it is probed before a run."""
    with outside(env, f"{phase} (probed with random actions before the run)"):
        return call(*args)


def _probe_read(
    env: str, phase: str, read: Callable[[Any], np.ndarray], timestep: dm_env.TimeStep, size: int
) -> np.ndarray:
    """``read`` of the observation ``phase`` gave while probing, ``size`` finite numbers
    (:func:`~rmac_mj.envs.failures.read_observation`)."""
    where = f"{phase} (probed with random actions before the run)"
    return read_observation(env, where, read, timestep.observation, size)
