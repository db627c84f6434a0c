"""Prior knowledge (section 7): recorded transitions, their ``.npz`` format, recording.

``record(env, controller, trials, seed)`` records a demonstrator, ``save_demonstration`` and
``load_demonstration`` write and read the file, and ``Agent.seed_from(**demo.arrays())`` puts it
into a learner (the paper's conclusion: memories may start from measurements instead of empty).
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
import zipfile
from collections.abc import Callable
from typing import Any

import numpy as np
from dm_control.rl import control

from rmac_mj.agents import ActionSpace, StateSpace, check_transitions
from rmac_mj.errors import MissingInputError, UserInputError
from rmac_mj.results import files
from rmac_mj.rollout import action_space_of, learner_state_of, state_of

#: The keys of a demonstration file, in order.
FIELDS = ("states", "actions", "rewards", "next_states", "trial")


@dataclasses.dataclass(frozen=True)
class Demonstration:
    """Recorded transitions; the ``.npz`` file (``numpy.load(allow_pickle=False)``) holds exactly
    these keys:

    =============== ================ ==============================================================
    key             shape, dtype     meaning
    =============== ================ ==============================================================
    ``states``      (T, n) float     x_t, the learner's state before transition t
    ``actions``     (T, m) float     u_t, the action applied (after saturation) during transition t
    ``rewards``     (T,) float       r_{t+1}, the reward of transition t
    ``next_states`` (T, n) float     x_{t+1}, the state after transition t
    ``trial``       (T,) integer     which recorded trial transition t belongs to, non-decreasing
    =============== ================ ==============================================================

    The state is what the agents see (the task's ``learner_state``: for the DC-motor pendulum x =
    [phi, phi_dot] in rad and rad/s, phi = 0 upright; angles may be unwrapped), the action is in the
    task's units (V). Within a trial ``next_states[t] == states[t + 1]``; the learners use each
    transition on its own (only the returns-to-go run along a trial), so gaps between trials are
    fine.

    Attributes:
      states: ndarray of shape (T, n).
      actions: ndarray of shape (T, m).
      rewards: ndarray of shape (T,).
      next_states: ndarray of shape (T, n).
      trial: int64 ndarray of shape (T,), non-decreasing.

    Checked at construction (ValueError naming the field): shapes agree, T >= 1, finite values,
    integer and non-decreasing trial ids.
    """

    states: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    next_states: np.ndarray
    trial: np.ndarray

    def __post_init__(self) -> None:
        checked = check_transitions(*(getattr(self, f) for f in FIELDS), owner="Demonstration")
        for field, value in zip(FIELDS, checked):
            value.setflags(write=False)
            object.__setattr__(self, field, value)

    @property
    def n_transitions(self) -> int:
        return int(self.states.shape[0])

    @property
    def n_trials(self) -> int:
        return int(len(np.unique(self.trial)))

    def arrays(self) -> dict[str, np.ndarray]:
        """The fields by name, as ``Agent.seed_from`` and ``numpy.savez`` take them."""
        return {field: getattr(self, field) for field in FIELDS}

    def trial_returns(self) -> np.ndarray:
        """The sum of rewards of each recorded trial, in order; shape (n_trials,)."""
        _, first = np.unique(self.trial, return_index=True)
        return np.add.reduceat(self.rewards, np.sort(first))

    def check_for(self, state_space: StateSpace, action_space: ActionSpace) -> None:
        """ValueError unless the recording fits a task: n and m agree, actions inside the bounds."""
        n, m = self.states.shape[1], self.actions.shape[1]
        if n != state_space.dim:
            raise ValueError(
                f"states have n={n} entries per row, the task's state has {state_space.dim}"
            )
        if m != action_space.dim:
            raise ValueError(
                f"actions have m={m} entries per row, the task's action has {action_space.dim}"
            )
        tolerance = 1e-9 * np.maximum(1.0, np.abs(action_space.high - action_space.low))
        outside = np.any(
            (self.actions < action_space.low - tolerance)
            | (self.actions > action_space.high + tolerance),
            axis=1,
        )
        if outside.any():
            raise ValueError(
                f"actions: {int(outside.sum())} of {len(outside)} rows lie outside the "
                f"task's action range [{action_space.low.tolist()}, "
                f"{action_space.high.tolist()}] (record the applied, saturated action)"
            )


def save_demonstration(path: str | os.PathLike, demo: Demonstration) -> pathlib.Path:
    """Write ``demo`` as an ``.npz`` file in the documented format (atomically)."""
    if not isinstance(demo, Demonstration):
        raise TypeError(f"demo must be a Demonstration, got {type(demo).__name__}")
    return files.write_npz(path, **demo.arrays())


def load_demonstration(
    path: str | os.PathLike,
    state_space: StateSpace | None = None,
    action_space: ActionSpace | None = None,
) -> Demonstration:
    """Read a demonstration file; with the task's spaces, also check that it fits the task.

    Raises:
      MissingInputError: no such file.
      UserInputError: the file is not a valid demonstration; the message names the file and what is
        wrong (not an .npz, a missing or unexpected key, a wrong shape or dtype, non-finite values,
        trial ids going back, n or m not the task's, actions beyond the action bounds).
    """
    path = pathlib.Path(path)
    if not path.is_file():
        raise MissingInputError(f"{path}: no such demonstration file")
    if not zipfile.is_zipfile(path):
        raise UserInputError(
            f"{path}: not an .npz file (numpy.savez writes one; see "
            "docs/prior-knowledge.md for the keys)"
        )
    try:
        with np.load(path, allow_pickle=False) as data:
            keys = set(data.files)
            missing = [k for k in FIELDS if k not in keys]
            unexpected = sorted(keys - set(FIELDS))
            if missing or unexpected:
                raise UserInputError(
                    f"{path}: a demonstration holds exactly the keys {list(FIELDS)}; "
                    + "; ".join(
                        ([f"missing {missing}"] if missing else [])
                        + ([f"unexpected {unexpected}"] if unexpected else [])
                    )
                )
            arrays = {k: data[k] for k in FIELDS}
    except UserInputError:
        raise
    except (zipfile.BadZipFile, OSError, EOFError) as error:
        raise UserInputError(f"{path}: not a readable .npz file ({error})") from None
    except ValueError as error:  # object arrays refused by allow_pickle=False, a corrupt member
        raise UserInputError(f"{path}: {error}") from None
    try:
        demo = Demonstration(**arrays)
        if state_space is not None and action_space is not None:
            demo.check_for(state_space, action_space)
    except ValueError as error:
        raise UserInputError(f"{path}: {error}") from None
    return demo


def record(
    env: control.Environment,
    controller: Callable[[np.ndarray], Any],
    trials: int,
    seed: int | np.random.Generator | None = None,
    action_noise: float = 0.0,
) -> Demonstration:
    """Run ``controller`` (x -> u) for ``trials`` episodes of ``env`` and record the transitions.

    Args:
      env: a dm-control environment (its own task seed decides the start states).
      controller: maps the learner's state x (``episode.state_of``, shape (n,)) to an action of
        shape (m,) (a float is taken for m = 1).
      trials: episodes to record, >= 1.
      seed: seed of the action noise.
      action_noise: standard deviation of Gaussian noise added to every action before saturation
        (action units). A deterministic controller's action is a function of the state, so its data
        alone cannot tell a process model's df/du from df/dx; the noise excites the input.
    Returns:
      The recording; ``actions`` hold the applied (saturated) actions.
    """
    if isinstance(trials, bool) or not isinstance(trials, (int, np.integer)) or trials < 1:
        raise ValueError(f"trials must be a positive integer, got {trials!r}")
    if not (np.isfinite(action_noise) and action_noise >= 0):
        raise ValueError(f"action_noise must be finite and >= 0, got {action_noise!r}")
    rng = np.random.default_rng(seed)
    action_space = action_space_of(env)
    learner_state = learner_state_of(env)
    rows: dict[str, list] = {field: [] for field in FIELDS}
    for index in range(int(trials)):
        timestep = env.reset()
        x = state_of(timestep.observation, learner_state)
        while not timestep.last():
            u = np.asarray(controller(x.copy()), dtype=float).reshape(action_space.dim)
            if action_noise > 0:
                u = u + rng.normal(0.0, action_noise, size=action_space.dim)
            u = action_space.clip(u)
            timestep = env.step(u)
            x_next = state_of(timestep.observation, learner_state)
            for field, value in zip(FIELDS, (x, u, float(timestep.reward), x_next, index)):
                rows[field].append(value)
            x = x_next
    return Demonstration(
        states=np.array(rows["states"]),
        actions=np.array(rows["actions"]),
        rewards=np.array(rows["rewards"]),
        next_states=np.array(rows["next_states"]),
        trial=np.array(rows["trial"], dtype=np.int64),
    )
