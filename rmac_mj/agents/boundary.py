"""A learner's public boundary (:class:`AgentBoundary`, a part of :class:`~rmac_mj.agents.base.Agent`):
a state, reward and action checked once, with errors naming the argument, and a call the learner
refuses (:class:`RefusedTransition`) undone, so a refused call changes nothing."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rmac_mj.agents.spaces import STATE_LIMIT_WIDTHS


class RefusedTransition(ValueError):
    """A transition (or a trial's start) whose learning would overflow the learner's arithmetic:
    refused before anything changed (``Agent._overflow``)."""


class AgentBoundary:
    """The checks of :class:`~rmac_mj.agents.base.Agent`'s public methods; it uses the agent's
    ``name``, ``state_space``, ``action_space``, ``rng``, ``trials_`` and state dict."""

    def _checked_state(self, x: Any, name: str = "x") -> np.ndarray:
        """x as a new float64 vector of shape (n,); ValueError naming ``name`` if not finite or wrong."""
        v = np.array(x, dtype=float)
        if v.shape != (self._state_dim,):
            if v.size != self._state_dim:
                raise ValueError(
                    f"{self.name}: {name} must have shape ({self._state_dim},), got "
                    f"shape {np.shape(x)}"
                )
            v = v.reshape(self._state_dim)
        # Called once per control step on a few numbers: Python over a list is several times
        # cheaper than numpy on a short vector. A NaN fails every comparison, so this one check
        # refuses non-finite states too.
        values = v.tolist()
        if not self.state_space.accepts(values):
            if not all(map(math.isfinite, values)):
                raise ValueError(f"{self.name}: {name} must be finite, got {x!r}")
            low, high = self.state_space.limit
            i = int(np.argmax((v < low) | (v > high)))
            raise ValueError(
                f"{self.name}: {name}[{i}] = {values[i]:g} is beyond what a learner accepts, "
                f"[{low[i]:g}, {high[i]:g}] ({STATE_LIMIT_WIDTHS:g} widths of the state box around "
                f"it); a state that far out overflows the learner's arithmetic"
            )
        return v

    def _checked_reward(self, reward: Any, name: str = "reward") -> float:
        """A finite number as a float; ValueError naming ``name`` otherwise."""
        try:
            r = float(reward)
        except (TypeError, ValueError):
            raise ValueError(
                f"{self.name}: {name} must be a finite number, got {reward!r}"
            ) from None
        if not math.isfinite(r):
            raise ValueError(f"{self.name}: {name} must be finite, got {reward!r}")
        return r

    def _checked_action(self, u: Any, name: str = "u") -> np.ndarray:
        """u as a new float64 vector of shape (m,); ValueError naming ``name`` if not finite or wrong."""
        v = np.array(u, dtype=float).reshape(-1)
        if v.shape != (self.action_space.dim,):
            raise ValueError(
                f"{self.name}: {name} must have shape ({self.action_space.dim},), got "
                f"shape {np.shape(u)}"
            )
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{self.name}: {name} must be finite, got {u!r}")
        return v

    def _overflow(self, what: Any) -> RefusedTransition:
        """The error of a transition whose learning overflows (``what``: the quantity, or the
        reward). A learner raises it before it changes its own arrays (check, then change); the
        boundary puts back the random generator and the trial counter (:meth:`_refusable`)."""
        if not isinstance(what, str):
            what = f"the transition with reward {what!r}"
        return RefusedTransition(
            f"{self.name}: {what} overflows the learner's arithmetic (not finite); "
            f"refused, nothing non-finite was stored"
        )

    def _check_in_trial(self, method: str) -> None:
        if not self._in_trial:
            raise RuntimeError(
                f"{self.name}: {method}() called outside a trial; call start(x0) first"
            )

    def _refusable(self, change: Any, *args: Any) -> Any:
        """``change(*args)``, and if the learner refuses it (:class:`RefusedTransition`) the random
        generator and the trial counter as they were: the learner refuses before it changes its own
        arrays, so a refused call leaves ``state_dict()`` exactly as it was."""
        rng_state, trials = self.rng.bit_generator.state, self.trials_
        try:
            return change(*args)
        except RefusedTransition:
            self.rng.bit_generator.state, self.trials_ = rng_state, trials
            raise

    def _all_or_nothing(self, change: Any, *args: Any) -> Any:
        """``change(*args)`` for a call that runs many updates (a stored trial, planning and replay
        after a trial): if the learner refuses one, the whole state as it was before the call."""
        before = self.state_dict()
        try:
            return change(*args)
        except RefusedTransition:
            self.load_state_dict(before)
            raise
