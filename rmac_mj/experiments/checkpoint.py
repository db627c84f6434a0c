"""An unfinished experiment, saved between trials so that a resumed run continues it.

The agent's state dict (generator included), the task's random state, the curve so far and the time
spent, in ``OUT/checkpoints/<algorithm>/exp_<iii>.npz``; written atomically, removed once the curve
is saved.
"""

from __future__ import annotations

import hashlib
import json
import pathlib
from typing import Any

import numpy as np

from rmac_mj.agents import Agent
from rmac_mj.agents.base import generator_state_array, set_generator_state
from rmac_mj.results import files

_AGENT, _CURVE, _ENV = "agent/", "curve/", "env/"
#: Wall seconds of an experiment between two checkpoints (the first after the first trial that ends
#: this long after the start): an experiment of a few seconds never writes one.
CHECKPOINT_SECONDS = 60.0


def protocol_digest(protocol_document: dict[str, Any]) -> str:
    """What a checkpoint must have been written under: the protocol (as data) but its experiment
    count, which a resume may raise without changing any experiment."""
    document = {**protocol_document, "experiments": 0}
    return hashlib.sha256(json.dumps(document, sort_keys=True).encode()).hexdigest()


def _task_random(env: Any) -> np.random.RandomState | None:
    for owner in (env, getattr(env, "base", None)):
        random = getattr(getattr(owner, "task", None), "random", None)
        if isinstance(random, np.random.RandomState):
            return random
    return None


def _gymnasium_random(env: Any) -> np.random.Generator | None:
    base = getattr(env, "base", None)
    gymnasium_env = getattr(base, "env", None)
    if gymnasium_env is None or getattr(base, "_seed", None) is not None:
        return None  # not Gymnasium's, or not yet reset: its seed is still to be applied
    random = getattr(gymnasium_env, "np_random", None)
    if (
        isinstance(random, np.random.Generator)
        and random.bit_generator.state.get("bit_generator") == "PCG64"
    ):
        return random
    return None


def environment_state(env: Any) -> dict[str, np.ndarray] | None:
    """The random state of ``env``'s starts between two trials, as numeric arrays; None when it
    cannot be told (a factory's environment of unknown make): such an experiment is not
    checkpointed."""
    random = _task_random(env)
    if random is not None:
        _, keys, position, has_gauss, gauss = random.get_state()
        return {
            "mt19937_keys": np.asarray(keys, dtype=np.uint32),
            "mt19937_position": np.array([position, has_gauss], dtype=np.int64),
            "mt19937_gauss": np.array(gauss, dtype=np.float64),
        }
    generator = _gymnasium_random(env)
    if generator is not None:
        return {"pcg64": generator_state_array(generator)}
    return None


def restore_environment(env: Any, state: dict[str, np.ndarray]) -> None:
    """Put :func:`environment_state`'s arrays back into ``env`` (built afresh from the same seed)."""
    if "mt19937_keys" in state:
        position, has_gauss = (int(v) for v in state["mt19937_position"])
        _task_random(env).set_state(
            (
                "MT19937",
                np.asarray(state["mt19937_keys"], dtype=np.uint32),
                position,
                has_gauss,
                float(state["mt19937_gauss"]),
            )
        )
        return
    base = env.base
    base.reset()  # applies the pending seed once, as the first trial did; then the saved stream
    set_generator_state(base.env.np_random, state["pcg64"])


def write(
    path: pathlib.Path,
    *,
    digest: str,
    agent: Agent,
    environment: dict[str, np.ndarray],
    returns: list[float],
    env_steps: list[int],
    greedy_trials: list[int],
    greedy_returns: list[float],
    wall_time_s: float,
    cpu_time_s: float,
) -> None:
    """Write the checkpoint of an experiment after ``len(returns)`` trials."""
    arrays = {_AGENT + key: np.asarray(value) for key, value in agent.state_dict().items()}
    arrays.update({_ENV + key: value for key, value in environment.items()})
    arrays.update(
        {
            _CURVE + "returns": np.asarray(returns, dtype=float),
            _CURVE + "env_steps": np.asarray(env_steps, dtype=np.int64),
            _CURVE + "greedy_trials": np.asarray(greedy_trials, dtype=int),
            _CURVE + "greedy_returns": np.asarray(greedy_returns, dtype=float),
            "wall_time_s": np.float64(wall_time_s),
            "cpu_time_s": np.float64(cpu_time_s),
            "digest": np.array(digest),
        }
    )
    files.write_npz(path, **arrays)


def read(path: pathlib.Path, digest: str) -> dict[str, Any] | None:
    """The checkpoint at ``path`` as ``{"agent": state dict, "environment": arrays, "returns": ...}``,
    or None when there is none, it cannot be read, or it was written under another protocol (the
    experiment then starts from its first trial, which gives the same result, later)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {key: data[key] for key in data.files}
    except (OSError, ValueError, EOFError):
        return None
    try:
        if str(arrays["digest"]) != digest:
            return None
        curve = {key[len(_CURVE) :]: arrays[key] for key in arrays if key.startswith(_CURVE)}
        checkpoint = {
            "agent": {key[len(_AGENT) :]: arrays[key] for key in arrays if key.startswith(_AGENT)},
            "environment": {
                key[len(_ENV) :]: arrays[key] for key in arrays if key.startswith(_ENV)
            },
            "returns": [float(v) for v in curve["returns"]],
            "env_steps": [int(v) for v in curve["env_steps"]],
            "greedy_trials": [int(v) for v in curve["greedy_trials"]],
            "greedy_returns": [float(v) for v in curve["greedy_returns"]],
            "wall_time_s": float(arrays["wall_time_s"]),
            "cpu_time_s": float(arrays["cpu_time_s"]),
        }
    except (KeyError, ValueError, TypeError):
        return None
    if not _whole(checkpoint):
        return None
    return checkpoint


#: The random state of an environment, as :func:`environment_state` writes it: key -> (dtype,
#: shape), one of the two kinds.
_ENVIRONMENT_STATES = (
    {
        "mt19937_keys": (np.uint32, (624,)),
        "mt19937_position": (np.int64, (2,)),
        "mt19937_gauss": (np.float64, ()),
    },
    {"pcg64": (np.uint64, (6,))},
)


def _whole(checkpoint: dict[str, Any]) -> bool:
    """Whether a read checkpoint holds what :func:`write` wrote: a curve of finite returns with
    increasing step counts, greedy trials among them, and an environment state of one of the
    two kinds (the agent's state is checked by the learner that loads it)."""
    returns, steps = checkpoint["returns"], checkpoint["env_steps"]
    greedy, greedy_returns = checkpoint["greedy_trials"], checkpoint["greedy_returns"]
    environment = checkpoint["environment"]
    return (
        bool(returns)
        and len(steps) == len(returns)
        and all(np.isfinite(returns))
        and steps[0] >= 1
        and all(a <= b for a, b in zip(steps, steps[1:]))
        and len(greedy_returns) == len(greedy)
        and all(np.isfinite(greedy_returns))
        and all(1 <= t <= len(returns) for t in greedy)
        and any(
            environment.keys() == kind.keys()
            and all(
                environment[key].dtype == dtype and environment[key].shape == shape
                for key, (dtype, shape) in kind.items()
            )
            for kind in _ENVIRONMENT_STATES
        )
        and np.isfinite(checkpoint["wall_time_s"])
        and np.isfinite(checkpoint["cpu_time_s"])
    )
