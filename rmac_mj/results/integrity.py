"""Whether a result directory can be trusted: its lock, and the checks of what it holds.

A run holds an exclusive ``flock`` on ``OUT/.lock`` while it writes (:class:`DirectoryLock`); a
resumed run trusts a saved experiment only when its files are whole and match the config
(:func:`curve_problem`, :func:`snapshot_problem`).
"""

from __future__ import annotations

import datetime
import fcntl
import json
import os
import pathlib
import socket
import sys
import zipfile
from typing import Any

import numpy as np

from rmac_mj.errors import UserInputError

#: The keys every curve file holds (``ResultStore.save``); files of older versions may lack
#: ``cpu_time_s``, which is optional.
CURVE_KEYS = (
    "returns",
    "greedy_trials",
    "greedy_returns",
    "wall_time_s",
    "task_seed",
    "demonstration_returns",
)
_LOCK_NAME = ".lock"


class DirectoryBusy(UserInputError):
    """Another process holds the directory's lock: it is writing there now."""


class DirectoryLock:
    """An exclusive lock on a result directory, with who holds it written into the lock file.

    ``flock`` locks belong to the open file, so a killed holder never leaves a stale lock (its file
    stays, empty of meaning once unlocked); a run that ends removes the file as it lets go.
    Re-entrant in one process only through one instance.
    """

    def __init__(self, root: pathlib.Path):
        self.path = pathlib.Path(root) / _LOCK_NAME
        self.handle = None

    def acquire(self) -> None:
        """Take the lock, or raise :class:`DirectoryBusy` naming the process that holds it."""
        if self.handle is not None:
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        while True:
            try:
                handle = open(self.path, "a+", encoding="utf-8")
            except (IsADirectoryError, PermissionError) as error:
                raise UserInputError(
                    f"{self.path} cannot be the directory's lock ({error.strerror}); remove it or "
                    "choose another --out"
                ) from None
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                handle.seek(0)
                holder = handle.read().strip()
                handle.close()
                raise DirectoryBusy(
                    f"{self.path.parent} is in use by another run "
                    f"({_describe(holder)}); wait for it to end or choose another "
                    "--out"
                ) from None
            if _same_file(handle, self.path):
                break
            handle.close()  # its holder removed that file as it let go: lock the one there now
        handle.seek(0)
        handle.truncate()
        handle.write(
            json.dumps(
                {
                    "pid": os.getpid(),
                    "host": socket.gethostname(),
                    "since": datetime.datetime.now().isoformat(timespec="seconds"),
                    "command": " ".join(["rmac-mj", *sys.argv[1:]]) if sys.argv else "python",
                }
            )
        )
        handle.flush()
        self.handle = handle

    def release(self) -> None:
        if self.handle is not None:
            if _same_file(self.handle, self.path):  # removed while still held: no one else has it
                self.path.unlink()
            fcntl.flock(self.handle, fcntl.LOCK_UN)
            self.handle.close()
            self.handle = None

    def __enter__(self) -> DirectoryLock:
        self.acquire()
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def _same_file(handle, path: pathlib.Path) -> bool:
    """Whether the open ``handle`` is the file at ``path`` now (not one removed since it was opened)."""
    try:
        return os.path.samestat(os.fstat(handle.fileno()), os.stat(path))
    except FileNotFoundError:
        return False


def _describe(holder: str) -> str:
    try:
        info = json.loads(holder)
        return f"pid {info['pid']} on {info['host']} since {info['since']}: {info['command']}"
    except (ValueError, KeyError, TypeError, RecursionError):
        return "a process that did not say who it is"


def _open_npz(path: pathlib.Path) -> tuple[dict[str, np.ndarray] | None, str | None]:
    """All arrays of an ``.npz`` file, or (None, why it cannot be read)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            return {key: data[key] for key in data.files}, None
    except FileNotFoundError:
        return None, "missing"
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as error:
        # numpy refuses object arrays with allow_pickle=False (ValueError); a truncated or empty
        # file is no zip (BadZipFile, EOFError, OSError)
        return None, f"unreadable ({type(error).__name__}: {error})"


def _finite_numbers(array: np.ndarray) -> bool:
    return array.dtype.kind in "biuf" and bool(np.all(np.isfinite(array)))


def curve_problem(
    path: pathlib.Path, trials: int, greedy_trials: list[int], steps: int | None = None
) -> str | None:
    """None when the curve file at ``path`` is whole and holds ``trials`` finite returns and greedy
    trials after exactly ``greedy_trials``; else what is wrong with it. With a budget of ``steps``
    environment steps, ``trials`` is the most it may hold: it holds the trials until its
    ``env_steps`` reached the budget, and the greedy trials among them. ``env_steps`` (written since
    environment steps are counted) must then be a non-decreasing count per trial."""
    arrays, problem = _open_npz(path)
    if problem is not None:
        return problem
    missing = [key for key in CURVE_KEYS if key not in arrays]
    if steps is not None and "env_steps" not in arrays:
        missing.append("env_steps")
    if missing:
        return f"lacks {', '.join(missing)}"
    returns, greedy = arrays["returns"], arrays["greedy_returns"]
    if steps is not None and returns.ndim == 1 and 1 <= returns.size <= trials:
        counted = arrays["env_steps"]
        reached = (
            counted.shape == returns.shape
            and counted[-1] >= steps
            and (returns.size == 1 or counted[-2] < steps)
        )
        if not reached and returns.size < trials:
            return (
                f"its {returns.size} trials do not end where the budget of {steps} environment "
                f"steps is reached"
            )
        trials = returns.size
        greedy_trials = [t for t in greedy_trials if t <= trials]
    if returns.shape != (trials,) or not _finite_numbers(returns):
        return f"returns are not {trials} finite numbers (shape {returns.shape}, dtype {returns.dtype})"
    if "env_steps" in arrays:
        counted = arrays["env_steps"]
        if (
            counted.shape != (trials,)
            or counted.dtype.kind not in "iu"
            or np.any(np.diff(counted) < 0)
            or (counted.size and counted[0] < 1)
        ):
            return f"env_steps are not {trials} increasing counts of environment steps"
    if arrays["greedy_trials"].tolist() != greedy_trials:
        return f"greedy trials {arrays['greedy_trials'].tolist()[:5]}... are not the protocol's"
    if greedy.shape != (len(greedy_trials),) or (greedy.size and not _finite_numbers(greedy)):
        return f"greedy returns are not {len(greedy_trials)} finite numbers"
    for key in ("wall_time_s", "task_seed"):
        if arrays[key].shape != () or not _finite_numbers(arrays[key]):
            return f"{key} is not a number"
    if arrays["demonstration_returns"].ndim != 1 or not _finite_numbers(
        arrays["demonstration_returns"]
    ):
        return "demonstration_returns are not finite numbers"
    return None


def npz_length(path: pathlib.Path, key: str) -> int | None:
    """The size of array ``key`` of the ``.npz`` file at ``path``, None when it cannot be read."""
    arrays, problem = _open_npz(path)
    if problem is not None or key not in arrays:
        return None
    return int(arrays[key].size)


def curve_trials(path: pathlib.Path) -> int | None:
    """The learning trials a curve file holds, None when it cannot be read."""
    return npz_length(path, "returns")


def snapshot_problem(path: pathlib.Path, algorithm: str, trial: int) -> str | None:
    """None when the snapshot at ``path`` is whole: a meta document of ``algorithm`` after ``trial``
    and numeric, finite learned state; else what is wrong with it."""
    arrays, problem = _open_npz(path)
    if problem is not None:
        return problem
    if "meta" not in arrays:
        return "no meta document"
    try:
        meta: Any = json.loads(str(arrays["meta"]))
    except (ValueError, RecursionError):  # nested too deeply is no meta document either
        return "its meta document is not JSON"
    if not isinstance(meta, dict) or (meta.get("algorithm"), meta.get("trial")) != (
        algorithm,
        trial,
    ):
        return f"its meta document is not of {algorithm} after trial {trial}"
    for key, value in arrays.items():
        if key != "meta" and value.size and not _finite_numbers(value):
            return f"{key} is not finite numbers"
    return None
