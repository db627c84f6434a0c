"""A learner's learned state exchanged as a flat dict of numeric numpy arrays
(:class:`StateExchange`, a part of :class:`~rmac_mj.agents.base.Agent`): written, restored exactly,
and checked before a restore, so that a state the learner cannot restore changes nothing."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from rmac_mj.agents.random_state import generator_state_array, set_generator_state


class StateExchange:
    """``state_dict``, ``load_state_dict`` and ``check_state_dict`` of
    :class:`~rmac_mj.agents.base.Agent`, on the learner's own ``_state``/``_load_state`` and its
    rehearsal, random generator and trial counter."""

    def state_dict(self) -> dict[str, np.ndarray]:
        """Everything that decides what the agent does next, as a flat dict of numeric numpy arrays:
        the learner's state, its random generator (``rng``), whether a trial runs (``in_trial``) and
        how many learning trials have begun (``trials``; a decaying exploration depends on it)."""
        state = self._state()
        for key in ("rng", "in_trial", "trials"):
            if key in state:
                raise KeyError(
                    f"{type(self).__name__}._state() must not use the reserved key {key!r}"
                )
        if self._rehearsal is not None:
            state.update(self._rehearsal.state_dict("rehearsal."))
        state["rng"] = generator_state_array(self.rng)
        state["in_trial"] = np.array(self._in_trial)
        state["trials"] = np.array(self.trials_, dtype=np.int64)
        return state

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore what :meth:`state_dict` returned; the agent then acts exactly as the original.

        Checked first (:meth:`check_state_dict`), so a refused state changes nothing.
        """
        arrays = self.check_state_dict(state)
        self._load_state(
            {
                k: v
                for k, v in arrays.items()
                if k not in ("rng", "in_trial", "trials") and not k.startswith("rehearsal.")
            }
        )
        if self._rehearsal is not None:
            self._rehearsal.load_state_dict(arrays, "rehearsal.")
        set_generator_state(self.rng, arrays["rng"])
        self._in_trial = bool(arrays["in_trial"])
        if "trials" in arrays:
            self.trials_ = int(arrays["trials"])

    def check_state_dict(self, state: Mapping[str, Any]) -> dict[str, np.ndarray]:
        """The state dict as arrays if this learner can restore it, else ValueError (TypeError for
        no mapping) naming what is wrong; nothing changes. The one check of every learner, also
        of every file a resumed run keeps: the keys (none missing, none foreign: a state dict of
        another learner is called one), each array's dtype and shape against this learner's own
        state dict, every float finite, then the learner's own rules (``_check_state``: counts
        and indices in range)."""
        if not isinstance(state, Mapping):
            raise TypeError(
                f"{self.name}: a state dict must be a mapping of names to arrays, got "
                f"{type(state).__name__}"
            )
        own = self.state_dict()
        missing = sorted(k for k in own if k not in state and not self._may_lack(k))
        foreign = sorted(k for k in state if k not in own and not self._may_lack(k))
        if missing or foreign:
            parts = [f"lacks {_listed(missing)}"] * bool(missing) + [
                f"has {_listed(foreign)}, which {self.name} does not"
            ] * bool(foreign)
            hint = " (a state dict of another learner?)" if missing and foreign else ""
            raise ValueError(f"{self.name}: the state dict {' and '.join(parts)}{hint}")
        arrays = {
            key: self._checked_entry(key, value, own.get(key)) for key, value in state.items()
        }
        # Snapshots written before the trial counter existed lack ``trials``; they load unless the
        # agent's exploration decays, which would then start again from the first trial's noise.
        if "trials" not in arrays and self._uses_trial_counter:
            raise ValueError(
                f"{self.name}: the state dict lacks 'trials', which a decaying "
                f"exploration or learning rate needs"
            )
        if "trials" in arrays and int(arrays["trials"]) < 0:
            raise ValueError(
                f"{self.name}: state 'trials' must be >= 0, got {int(arrays['trials'])}"
            )
        self._check_state(arrays)
        return arrays

    def _checked_entry(self, key: str, value: Any, own: np.ndarray | None) -> np.ndarray:
        """One entry of a state dict to restore, checked against the learner's own (``own``; None
        for an entry the learner holds only at some moments: its dtype and values are checked).

        The dtype must be the learner's own (a float32 critic would not act as the original), the
        shape too (for an entry whose length varies, the dimensions after the first), every
        float finite. The one check of every learner: ValueError naming the key, what it got and
        what was expected."""
        array = np.asarray(value)
        if own is None:
            if array.dtype.kind not in "fiub":
                raise ValueError(
                    f"{self.name}: state {key!r} must hold numbers, got dtype {array.dtype}"
                )
        elif array.dtype != own.dtype:
            raise ValueError(
                f"{self.name}: state {key!r} must hold {own.dtype}, got dtype {array.dtype}"
            )
        if own is not None:
            varies = self._shape_varies(key)
            if (
                (array.ndim != own.ndim or array.shape[1:] != own.shape[1:])
                if varies
                else (array.shape != own.shape)
            ):
                expected = ("K",) + own.shape[1:] if varies else own.shape
                raise ValueError(
                    f"{self.name}: state {key!r} must have shape {expected}, got {array.shape}"
                )
        if array.dtype.kind == "f" and not np.all(np.isfinite(array)):
            raise ValueError(
                f"{self.name}: state {key!r} must be finite; "
                f"{int(np.size(array) - np.count_nonzero(np.isfinite(array)))} of "
                f"{np.size(array)} entries are not"
            )
        return array

    def _may_lack(self, key: str) -> bool:
        """Whether a state dict may lack ``key`` (or hold it though this agent does not now): an
        entry written only by some versions or at some moments."""
        return key == "trials"

    def _shape_varies(self, key: str) -> bool:
        """Whether the shape of state entry ``key`` depends on the moment (e.g. a filling buffer,
        planning's or replay's stored transitions)."""
        return key.startswith("rehearsal.")

    def _check_state(self, state: dict[str, np.ndarray]) -> None:  # noqa: B027 (an optional hook)
        """The learner's own rules on a state dict to restore (counts and indices in range), checked
        before anything changes; ValueError naming the entry."""


def _listed(keys: list[str], most: int = 4) -> str:
    """A few keys for a message: 'a', 'b' (+3 more)."""
    shown = ", ".join(repr(k) for k in keys[:most])
    return shown + (f" (+{len(keys) - most} more)" if len(keys) > most else "")
