"""Prior knowledge (section 7): recorded transitions into a learner's memories.

``Agent.seed_from`` checks the transitions (:func:`check_transitions`); the learner turns them into
memory samples (returns-to-go: :func:`discounted_returns`) and fills its memories
(:func:`seed_memory`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

#: The kinds of prior knowledge a learner may take from recorded transitions:
#: 'process' (x, u) -> x' samples of the dynamics; 'reference' x_k -> x_{k+1} along the demonstrated
#: closed loop (the desired behaviour); 'critic' the demonstration's discounted returns-to-go;
#: 'actor' the demonstrated (x, u) pairs.
PRIOR_PARTS = ("process", "reference", "critic", "actor")


class Transitions(NamedTuple):
    """Recorded transitions as :func:`check_transitions` returns them: states and next_states
    float (T, n), actions float (T, m), rewards float (T,), trial int64 (T,) non-decreasing."""

    states: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    next_states: np.ndarray
    trial: np.ndarray


def check_transitions(
    states: Any,
    actions: Any,
    rewards: Any,
    next_states: Any,
    trial: Any,
    state_dim: int | None = None,
    action_dim: int | None = None,
    owner: str = "transitions",
) -> Transitions:
    """Recorded transitions as float arrays (and int64 trial ids), checked once.

    Shapes: states and next_states (T, n), actions (T, m), rewards (T,), trial (T,) with T >= 1;
    everything finite; trial integer and non-decreasing (each trial's transitions contiguous and in
    time order). ``state_dim``/``action_dim``, when given, are the n and m required. ValueError names
    the field that is wrong.
    """
    states = _matrix(owner, "states", states, state_dim)
    n, T = states.shape[1], states.shape[0]
    actions = _matrix(owner, "actions", actions, action_dim)
    next_states = _matrix(owner, "next_states", next_states, n)
    rewards = _numeric(owner, "rewards", rewards, "biuf", "must be numeric").astype(float)
    trial_ids = _numeric(owner, "trial", trial, "biu", "must hold integers").astype(np.int64)
    for name, a, shape in (
        ("actions", actions, (T, actions.shape[1])),
        ("next_states", next_states, (T, n)),
        ("rewards", rewards, (T,)),
        ("trial", trial_ids, (T,)),
    ):
        if a.shape != shape:
            raise ValueError(
                f"{owner}: {name} must have shape {shape} to match states "
                f"{states.shape}, got {a.shape}"
            )
    for name, a in (
        ("states", states),
        ("actions", actions),
        ("rewards", rewards),
        ("next_states", next_states),
    ):
        bad_rows = ~np.isfinite(a.reshape(T, -1)).all(axis=1)
        if bad_rows.any():
            raise ValueError(
                f"{owner}: {name} must be finite; {int(bad_rows.sum())} of {T} rows are "
                f"not (first: row {int(np.argmax(bad_rows))})"
            )
    if T > 1 and np.any(np.diff(trial_ids) < 0):
        row = int(np.argmax(np.diff(trial_ids) < 0)) + 1
        raise ValueError(
            f"{owner}: trial must be non-decreasing (each trial's transitions together, "
            f"in time order); row {row} goes back from {trial_ids[row - 1]} to "
            f"{trial_ids[row]}"
        )
    return Transitions(states, actions, rewards, next_states, trial_ids)


def _numeric(owner: str, name: str, value: Any, kinds: str, what: str) -> np.ndarray:
    """``value`` as an array whose dtype is of ``kinds``; ValueError naming ``name`` otherwise."""
    a = np.asarray(value)
    if a.dtype.kind not in kinds:
        raise ValueError(f"{owner}: {name} {what}, got dtype {a.dtype}")
    return a


def _matrix(owner: str, name: str, value: Any, width: int | None) -> np.ndarray:
    """``value`` as a float array of shape (T, width) with T >= 1 (any width for None)."""
    a = _numeric(owner, name, value, "biuf", "must be numeric").astype(float)
    if a.ndim != 2 or a.shape[0] < 1 or (width is not None and a.shape[1] != width):
        want = f"(T, {width})" if width is not None else "(T, d)"
        raise ValueError(f"{owner}: {name} must have shape {want} with T >= 1, got {a.shape}")
    return a


def discounted_returns(rewards: np.ndarray, trial: np.ndarray, gamma: float) -> np.ndarray:
    """Discounted returns-to-go G_t = r_t + gamma G_{t+1} within each trial; shape (T,).

    The return after a trial's last transition is taken as 0 (no bootstrapping past the recording):
    the demonstrator ends balanced upright, where every reward is about 0, and a value estimate of
    unknown states is what the learner is there to find. A state gamma^j steps before the end loses
    gamma^j V(x_end) of its value; with gamma = 0.97 that is under 5% after 100 steps.
    """
    rewards = np.asarray(rewards, dtype=float)
    trial = np.asarray(trial)
    out = np.empty_like(rewards)
    running = 0.0
    for t in range(len(rewards) - 1, -1, -1):
        if t == len(rewards) - 1 or trial[t + 1] != trial[t]:
            running = 0.0
        running = rewards[t] + gamma * running
        out[t] = running
    return out


def seed_memory(memory: Any, X: np.ndarray, Y: np.ndarray) -> None:
    """Fill an LLR memory with samples X (s, n) -> Y (s, m), replacing what it held.

    With s <= capacity the memory holds exactly these samples. With more, the first ``capacity``
    fill it and the rest are inserted in time order through the memory's replacement rule, as if
    they had arrived online (under 'nearest' each later sample replaces its most redundant
    predecessor, so the memory keeps samples spread over the recording; under 'oldest' it keeps the
    last ``capacity``).
    """
    s = min(len(X), int(memory.capacity))
    memory.fit(X[:s], Y[:s])
    for x, y in zip(X[s:], Y[s:]):
        memory.insert(x, y)
