"""Calls into an outside environment, its failures turned into one :class:`EnvironmentFailure`.

Whatever an outside environment does while its module is imported, its factory builds it, or it is
reset or stepped (raises, calls ``sys.exit``, hands back an observation that is not numbers) becomes an
:class:`~rmac_mj.errors.EnvironmentFailure` naming the SPEC, the phase and the line of the
environment's code it came from, with the original exception as its cause (the traceback a developer
reads). Our own refusals (:class:`~rmac_mj.errors.UserInputError`) and Ctrl-C pass through.
"""

from __future__ import annotations

import contextlib
import math
import numbers
import os
import traceback
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from rmac_mj.errors import EnvironmentFailure, UserInputError


def _origin(error: BaseException) -> str:
    """`` (at file.py:LINE)``: the innermost frame the error came from, or its file for a syntax
    error; empty when unknown."""
    if isinstance(error, SyntaxError) and error.filename:
        return f" (at {os.path.basename(error.filename)}:{error.lineno})"
    frames = traceback.extract_tb(error.__traceback__)
    if not frames:
        return ""
    return f" (at {os.path.basename(frames[-1].filename)}:{frames[-1].lineno})"


def describe(error: BaseException) -> str:
    """``TypeName: first line of the message (at file.py:LINE)``."""
    lines = str(error).strip().splitlines()
    message = f": {lines[0]}" if lines else ""
    return f"{type(error).__name__}{message}{_origin(error)}"


@contextlib.contextmanager
def outside(env: str, phase: str) -> Iterator[None]:
    """Run the body as a call into the environment ``env`` (its SPEC) during ``phase`` (``"import"``,
    ``"factory"``, ``"reset"``, ``"step"``...): any exception but ours and Ctrl-C, and ``sys.exit``,
    become one :class:`EnvironmentFailure`."""
    try:
        yield
    except (EnvironmentFailure, UserInputError, KeyboardInterrupt):
        raise
    except SystemExit as exit:
        raise EnvironmentFailure(
            f"env {env!r}: its {phase} called sys.exit({exit.code!r}){_origin(exit)}"
        ) from exit
    except Exception as error:
        raise EnvironmentFailure(f"env {env!r}: its {phase} raised {describe(error)}") from error


def read_observation(
    env: str, phase: str, read: Callable[[Any], np.ndarray], observation: Any, size: int
) -> np.ndarray:
    """``read(observation)``, the ``size`` numbers of the raw observation that ``phase`` gave,
    flattened; :class:`EnvironmentFailure` naming what is wrong when they are not numbers, not
    ``size`` of them, or not all finite."""
    try:
        values = np.asarray(read(observation), dtype=float)
    except (TypeError, ValueError, KeyError, IndexError) as error:
        raise EnvironmentFailure(
            f"env {env!r}: its {phase} gave an observation that is not numbers of its "
            f"observation_spec's shapes ({describe(error)})"
        ) from error
    if values.size != size:
        raise EnvironmentFailure(
            f"env {env!r}: its {phase} gave an observation of {values.size} numbers, its "
            f"observation_spec says {size}"
        )
    if not np.all(np.isfinite(values)):
        raise EnvironmentFailure(
            f"env {env!r}: its {phase} gave a non-finite observation, {values.tolist()}"
        )
    return values


def checked_reward(env: str, phase: str, reward: Any) -> float:
    """``reward`` as a finite float; :class:`EnvironmentFailure` naming it otherwise. A reward is a
    real number (a Python or numpy scalar, or a numeric array of one element): a string such as
    ``"1.0"`` is refused, not converted."""
    numeric = isinstance(reward, numbers.Real) or (
        isinstance(reward, np.ndarray) and reward.size == 1 and reward.dtype.kind in "biuf"
    )
    if not numeric:
        shown = repr(reward)
        shown = shown if len(shown) <= 80 else shown[:77] + "..."
        raise EnvironmentFailure(
            f"env {env!r}: its {phase} gave the reward {shown}, not a number (a "
            f"{type(reward).__name__})"
        )
    value = float(reward if not isinstance(reward, np.ndarray) else reward.reshape(()))
    if not math.isfinite(value):
        raise EnvironmentFailure(f"env {env!r}: its {phase} gave a non-finite reward, {reward!r}")
    return value
