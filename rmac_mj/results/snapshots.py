"""Agent snapshots: one ``.npz`` file, readable with ``numpy.load(path, allow_pickle=False)``.

The agent's ``state_dict`` (keys prefixed ``agent/``) and a JSON ``meta`` (format, algorithm,
hyperparameters, task, trial); no pickle, and nothing it names is imported or called when it is
opened. :func:`load_snapshot` gives back the learner, ready to act; :func:`snapshot_environment` is
the environment it acts in: an outside environment that is code of the user's runs only when the
user names it. A snapshot an earlier version wrote is read through :func:`upgrade`, the one place
that knows the earlier formats.
"""

from __future__ import annotations

import json
import os
import pathlib
import zipfile
from collections.abc import Callable
from typing import Any

import numpy as np
from dm_control.rl import control

from rmac_mj.agents import (
    ActionSpace,
    Agent,
    StateSpace,
    config_class,
    config_from_dict,
    make_agent,
)
from rmac_mj.errors import MissingInputError, UserInputError
from rmac_mj.results.files import write_npz

_PREFIX = "agent/"

#: The version of the snapshot format written here (``meta["format"]``); a snapshot without one
#: is format 1.
FORMAT = 3

#: Format 1's names that have changed since, in a learner's config (by algorithm), in its spaces and
#: in a suite task's keyword arguments (the pendulum's; no other task took that name): old -> name.
_FORMAT_1_CONFIG = {
    "s-ac": {"alpha_actor": "alpha_a", "alpha_critic": "alpha_c"},
    "mlac": {"alpha_actor": "alpha_a", "alpha_critic": "alpha_c"},
}
_FORMAT_1_SPACES = {"weights": "input_weights"}
_FORMAT_1_TASK_KWARGS = {"action_weight": "action_weights"}

#: Learner keys that format 3 gave to other learners: ``recommended`` became MPC's key (formerly
#: ``mpc``) and S-AC with Dyna planning, recommended before it, became ``s-ac-dyna``.
LEARNER_KEYS_BEFORE_FORMAT_3 = {"recommended": "s-ac-dyna", "mpc": "recommended"}


def _renamed(values: dict[str, Any], names: dict[str, str]) -> dict[str, Any]:
    return {names.get(key, key): value for key, value in values.items()}


def _from_format_1(meta: dict[str, Any]) -> dict[str, Any]:
    """Format 1 named S-AC's and MLAC's learning rates ``alpha_actor`` and ``alpha_critic``, the
    spaces' input weightings ``weights`` and the pendulum's reward weighting ``action_weight``."""
    upgraded = dict(meta, format=2)
    upgraded["config"] = _renamed(meta["config"], _FORMAT_1_CONFIG.get(meta["algorithm"], {}))
    for space in ("state_space", "action_space"):
        upgraded[space] = _renamed(meta[space], _FORMAT_1_SPACES)
    if "task_kwargs" in meta:
        upgraded["task_kwargs"] = _renamed(meta["task_kwargs"], _FORMAT_1_TASK_KWARGS)
    return upgraded


#: Up to format 2 a learner's config held each LLR memory's settings flat (``critic_capacity``);
#: since format 3, one nested ``LLRConfig`` per memory (``critic.capacity``): the memories by
#: algorithm and the settings of each.
_FLAT_MEMORIES = {
    "rmac": ("critic", "process", "reference"),
    "mlac": ("actor", "critic", "process"),
}
_FLAT_SETTINGS = ("capacity", "neighbours", "weights", "clip", "replacement", "redundancy")


def upgrade_config(algorithm: str, config: dict[str, Any]) -> dict[str, Any]:
    """A learner's config (``dataclasses.asdict`` form, or some of its fields) with the LLR memories'
    settings that format 2 and earlier kept flat (``critic_capacity``) nested as today
    (``{"critic": {"capacity": ...}}``); a config in today's form comes back as it is. The one
    upgrade of a learner's settings: snapshots (:func:`upgrade`) and a run's config.json
    (:func:`upgrade_run_config`) both go through it. ``algorithm`` is the learner's key of today."""
    memories = _FLAT_MEMORIES.get(algorithm, ())
    flat = {f"{memory}_{name}": (memory, name) for memory in memories for name in _FLAT_SETTINGS}
    if not any(key in flat for key in config):
        return config
    upgraded: dict[str, Any] = {}
    for key, value in config.items():
        if key in flat:
            memory, name = flat[key]
            upgraded.setdefault(memory, {})[name] = value
        elif key in memories and isinstance(value, dict):
            upgraded[key] = {**upgraded.get(key, {}), **value}
        else:
            upgraded[key] = value
    return upgraded


def with_learner_keys_of_today(document: dict[str, Any]) -> dict[str, Any]:
    """A config or summary document of a directory written before format 3 under today's learner
    keys (:data:`LEARNER_KEYS_BEFORE_FORMAT_3`): its own per-learner keys (a summary's rows), its
    ``agents`` and its ``protocol``'s algorithms and learner settings."""
    today = LEARNER_KEYS_BEFORE_FORMAT_3

    def renamed(mapping: dict[str, Any]) -> dict[str, Any]:
        return {today.get(key, key): value for key, value in mapping.items()}

    document = renamed(document)
    if isinstance(document.get("agents"), dict):
        document["agents"] = renamed(document["agents"])
    protocol = document.get("protocol")
    if isinstance(protocol, dict):
        protocol = dict(protocol)
        if isinstance(protocol.get("algorithms"), list):
            protocol["algorithms"] = [today.get(a, a) for a in protocol["algorithms"]]
        if isinstance(protocol.get("agent_configs"), dict):
            protocol["agent_configs"] = renamed(protocol["agent_configs"])
        document["protocol"] = protocol
    return document


def upgrade_run_config(document: dict[str, Any]) -> dict[str, Any]:
    """A run's config.json (its ``protocol``'s ``agent_configs`` and its resolved ``agents``) in
    today's form, from any earlier version's: learner keys of today
    (:func:`with_learner_keys_of_today`, before format 3), then :func:`upgrade_config` for each
    learner. Its ``format`` stays the one written: it says how the directory names its files."""

    def learners(configs: Any) -> Any:
        if not isinstance(configs, dict):
            return configs  # damaged: its readers say so
        return {
            name: upgrade_config(name, config) if isinstance(config, dict) else config
            for name, config in configs.items()
        }

    if document.get("format", 2) < 3:
        document = with_learner_keys_of_today(document)
    upgraded = dict(document)
    if isinstance(document.get("protocol"), dict) and "agent_configs" in document["protocol"]:
        protocol = document["protocol"]
        upgraded["protocol"] = dict(protocol, agent_configs=learners(protocol["agent_configs"]))
    if "agents" in document:
        upgraded["agents"] = learners(document["agents"])
    return upgraded


def _from_format_2(meta: dict[str, Any]) -> dict[str, Any]:
    """Format 2 keyed MPC ``mpc`` and S-AC with Dyna planning ``recommended``
    (:data:`LEARNER_KEYS_BEFORE_FORMAT_3`), and kept each LLR memory's settings flat in a learner's
    config (:func:`upgrade_config`)."""
    algorithm = LEARNER_KEYS_BEFORE_FORMAT_3.get(meta["algorithm"], meta["algorithm"])
    config = upgrade_config(algorithm, meta["config"])
    return dict(meta, format=3, algorithm=algorithm, config=config)


#: Format n -> the step that upgrades a meta document of format n to format n + 1.
_UPGRADES = {1: _from_format_1, 2: _from_format_2}


def upgrade(meta: dict[str, Any]) -> dict[str, Any]:
    """A snapshot's meta document in the format written here (:data:`FORMAT`), from any earlier
    one, one format at a time (:data:`_UPGRADES`). UserInputError for a format this version does
    not read."""
    version = meta.get("format", 1)
    if version not in _UPGRADES and version != FORMAT:
        raise UserInputError(
            f"snapshot format {version!r}; this version of rmac-mj reads formats 1 to {FORMAT}"
        )
    while version != FORMAT:
        meta = _UPGRADES[version](meta)
        version = meta["format"]
    # Format 3 as first written (on main, the morning it was introduced) still kept the memories'
    # settings flat; nothing was released in between, so they are nested here, not by a format 4.
    config = upgrade_config(meta["algorithm"], meta["config"])
    return meta if config is meta["config"] else dict(meta, config=config)


def snapshot_arrays(
    agent: Agent, state_space: StateSpace, action_space: ActionSpace, **meta: Any
) -> dict[str, np.ndarray]:
    """The arrays of a snapshot of ``agent`` (what :func:`save_snapshot` writes).

    ``meta`` (JSON-ready) conventionally holds ``domain``, ``task``, ``task_kwargs`` (or, for an outside
    environment, its resolved spec as ``environment``: ``rmac_mj.envs.EnvSpec.as_dict``),
    ``experiment``, ``seed`` and ``trial`` (the number of learning trials done).
    """
    document = {
        "format": FORMAT,
        "algorithm": agent.name,
        "config": agent.config_dict(),
        "state_space": {
            "low": state_space.low.tolist(),
            "high": state_space.high.tolist(),
            "periodic": state_space.periodic.tolist(),
            "input_weights": state_space.input_weights.tolist(),
        },
        "action_space": {
            "low": action_space.low.tolist(),
            "high": action_space.high.tolist(),
            "input_weights": action_space.input_weights.tolist(),
            "cost": None if action_space.cost is None else action_space.cost.tolist(),
        },
        **meta,
    }
    arrays = {_PREFIX + key: np.asarray(value) for key, value in agent.state_dict().items()}
    for key, value in arrays.items():
        if value.dtype == object:
            raise TypeError(f"state_dict entry {key[len(_PREFIX) :]!r} is not a numeric array")
    arrays["meta"] = np.array(json.dumps(document))
    return arrays


def save_snapshot(
    path: str | os.PathLike,
    agent: Agent,
    state_space: StateSpace,
    action_space: ActionSpace,
    **meta: Any,
) -> pathlib.Path:
    """Write a snapshot of ``agent`` to ``path`` atomically (see :func:`snapshot_arrays`)."""
    return write_npz(path, **snapshot_arrays(agent, state_space, action_space, **meta))


def load_snapshot(path: str | os.PathLike) -> tuple[Agent, dict[str, Any]]:
    """Rebuild the agent saved at ``path``; return it and the snapshot's meta document (in the
    current format, :func:`upgrade`).

    The agent acts in the user's own loop: ``agent.greedy_action(x)`` without exploring or learning
    (``agent.begin_greedy_trial()`` before each trial), or it learns on (``start``/``step``/
    ``stop``); ``snapshot_environment(agent, meta)`` is the environment it learned on.
    UserInputError when the file is not a snapshot, or a damaged one.
    """
    path = pathlib.Path(path)
    if not path.is_file():
        raise MissingInputError(f"no snapshot at {path}")
    try:
        return _read_snapshot(path)
    except UserInputError:
        raise
    except (
        ValueError,
        TypeError,
        KeyError,
        AttributeError,
        OSError,
        EOFError,
        RecursionError,  # a meta document nested too deeply
    ) as error:
        # zipfile.BadZipFile is an Exception only: a file that is not a zip at all
        raise UserInputError(
            f"{path} is not a readable rmac-mj snapshot ({type(error).__name__}: {error})"
        ) from error
    except zipfile.BadZipFile as error:
        raise UserInputError(f"{path} is not an rmac-mj snapshot (not a zip: {error})") from error


def _read_snapshot(path: pathlib.Path) -> tuple[Agent, dict[str, Any]]:
    """:func:`load_snapshot` of an existing file, its errors unrefined."""
    with np.load(path, allow_pickle=False) as data:
        if "meta" not in data.files:
            raise UserInputError(f"{path} is not an rmac-mj snapshot (no 'meta' entry)")
        meta = upgrade(json.loads(str(data["meta"])))
        state = {key[len(_PREFIX) :]: data[key] for key in data.files if key.startswith(_PREFIX)}
    state_space = StateSpace(**meta["state_space"])
    action_space = ActionSpace(**meta["action_space"])
    config = config_from_dict(config_class(meta["algorithm"]), meta["config"])
    agent = make_agent(meta["algorithm"], state_space, action_space, config=config, seed=0)
    agent.load_state_dict(state)
    return agent, meta


def snapshot_state_problem(arrays: dict[str, np.ndarray], learner: Agent) -> str | None:
    """None when the learned state in a snapshot's ``arrays`` (as :func:`snapshot_arrays` wrote
    them) is one ``learner`` (a learner built as the run builds it) can restore: its keys, dtypes
    and shapes as the learner's ``check_state_dict`` checks them; else what is wrong."""
    state = {key[len(_PREFIX) :]: value for key, value in arrays.items() if key.startswith(_PREFIX)}
    try:
        learner.check_state_dict(state)
    except (TypeError, ValueError) as error:
        return f"its learned state is not what the run's {learner.name} holds ({error})"
    return None


def snapshot_environment(
    agent: Agent,
    meta: dict,
    domain: str | None = None,
    task: str | None = None,
    env: str | None = None,
    render: bool = False,
    trust_env: bool = False,
    log: Callable[[str], None] | None = None,
) -> control.Environment:
    """The environment a snapshot's agent acts in: the one it learned on (its domain, task and
    task_kwargs, or the outside environment its meta records under ``environment``), or
    ``domain``/``task`` of the suite with their defaults, or the outside environment ``env`` (a
    SPEC: the one it learned on, named again, or another, its learner state inferred);
    UserInputError if its state or action dimensions differ from the agent's. ``render``: an
    outside environment made to draw its frames.

    A snapshot is data: the suite's tasks and dm-control's and Gymnasium's registries are built from
    it, but an outside environment that is code of the user's (a module or file) runs only when
    ``env`` names it again or with ``trust_env``; and only from where it came from when it learned
    (``environment_origin``: a file's digest, a registry's version), else refused naming both.
    ``log`` hears why an environment named by ``env`` is not the one it learned on."""
    from rmac_mj import envs
    from rmac_mj.envs import spec as env_spec

    learned_on = envs.EnvSpec(**meta["environment"]) if "environment" in meta else None
    name = learned_on.env if learned_on is not None else f"{meta['domain']}/{meta['task']}"
    if env is not None and (domain is not None or task is not None):
        raise UserInputError(
            "give an outside environment (env) or a suite task (domain/task), not both"
        )
    if (learned_on is not None and domain is None and task is None) or env is not None:
        named = env is not None and learned_on is not None and env_spec.canonical(env) == name
        if learned_on is not None and env is None and env_spec.user_code(name) and not trust_env:
            raise UserInputError(
                f"the snapshot learned on env {name!r}, code of yours: opening a snapshot runs "
                f"none of it. To run it, name it: --env {name} (or --trust-env; env=, "
                "trust_env=True in Python)"
            )
        if learned_on is not None and (env is None or named):
            _check_origin(meta, name, named, log)
        spec = learned_on if env is None or named else envs.EnvSpec(env)
        if env is not None and not named and log is not None and learned_on is not None:
            log(f"the snapshot learned on {name}; drawn on {spec.env}, as --env asks")
        made, own, where = _built(spec, render), env is None or named, spec.env
    else:
        made, own, where = _suite_task(meta, learned_on is None, name, domain, task)
    if not own:
        _check_dimensions(made, agent, where, name)
    return made


def _built(spec, render: bool) -> control.Environment:
    """The outside environment ``spec`` built (drawing its frames when ``render``)."""
    try:
        return spec.make(render=render)
    except ValueError as error:
        raise UserInputError(f"cannot build {spec.env}: {error}") from None


def _suite_task(meta: dict, of_suite: bool, name: str, domain: str | None, task: str | None):
    """A suite task for a snapshot: ``domain``/``task``, the snapshot's where not given (its
    task_kwargs when it is the one it learned on, ``of_suite``); (environment, whether it is
    the one it learned on, its name)."""
    from rmac_mj import tasks

    domain = domain or meta.get("domain")
    task = task or (meta.get("task") if domain == meta.get("domain") else None)
    if task is None:
        raise UserInputError(
            f"give the task of domain {domain!r} too (the snapshot learned {name})"
        )
    own = of_suite and (domain, task) == (meta["domain"], meta["task"])
    try:
        made = tasks.load(domain, task, task_kwargs=meta.get("task_kwargs") if own else None)
    except ValueError as error:
        raise UserInputError(str(error)) from None
    return made, own, f"{domain}/{task}"


def _check_dimensions(made: control.Environment, agent: Agent, where: str, name: str) -> None:
    """UserInputError unless ``made`` (named ``where``) has the agent's state and action
    dimensions (it learned on ``name``)."""
    from rmac_mj.rollout import action_space_of, state_space_of

    n, m = state_space_of(made).dim, action_space_of(made).dim
    if (n, m) != (agent.state_space.dim, agent.action_space.dim):
        raise UserInputError(
            f"{where} has {n} state and {m} action dimensions, the agent "
            f"(learned on {name}) {agent.state_space.dim} and "
            f"{agent.action_space.dim}"
        )


def _check_origin(meta: dict, name: str, named: bool, log: Callable[[str], None] | None) -> None:
    """The environment ``name`` a snapshot learned on, where it comes from now against its record
    (``environment_origin``): refused naming both when it changed, unless the user named it again
    (``named``: then ``log`` hears it, and it is drawn as it is now)."""
    from rmac_mj.envs import spec as env_spec

    problem = env_spec.origin_problem(meta.get("environment_origin"), env_spec.origin(name))
    if problem is None:
        return
    if not named:
        raise UserInputError(
            f"env {name!r} is not what the snapshot learned on ({problem}): a snapshot acts "
            f"where it learned. To draw it on the environment as it is now, name it: --env {name}"
        )
    if log is not None:
        log(
            f"env {name!r} has changed since the snapshot learned on it ({problem}); drawn as "
            "it is now, as --env asks"
        )
