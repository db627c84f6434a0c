"""Result files: atomic writes of JSON, CSV and ``.npz``, a JSON cache, and provenance.

Everything written here is plain: JSON, CSV and ``.npz`` files that numpy or pandas read without this
package (``numpy.load(..., allow_pickle=False)``). Every file is written to a temporary name and
renamed into place, so a reader (or a resumed run) never sees half a file.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import os
import pathlib
import platform
import stat
import subprocess
import tempfile
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from rmac_mj.constraints import Limit
from rmac_mj.envs.spec import installed_version
from rmac_mj.errors import MissingInputError, UserInputError


def read_bounded(path: str | os.PathLike, limit: Limit, what: str) -> bytes:
    """The bytes of the regular file at ``path``, refused before they are read when it is anything
    else (a device such as /dev/zero, a pipe, a directory) or larger than ``limit`` bytes (a
    :class:`~rmac_mj.constraints.Limit`). ``what`` names the file in the refusals, e.g. "a sweep
    file". Raises MissingInputError when there is none, UserInputError naming it otherwise."""
    path = pathlib.Path(path)
    try:
        # O_NONBLOCK: opening a pipe must not wait for a writer; a regular file ignores it.
        descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        raise MissingInputError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise UserInputError(f"{path}: is a directory, not {what}") from None
    except OSError as error:
        raise UserInputError(f"{path} cannot be read ({error.strerror or error})") from None
    with os.fdopen(descriptor, "rb") as handle:
        mode = os.fstat(descriptor).st_mode
        if not stat.S_ISREG(mode):
            kind = "a directory" if stat.S_ISDIR(mode) else "a device, pipe or socket"
            raise UserInputError(f"{path}: is {kind}, not a regular file; {what} must be one")
        size = os.fstat(descriptor).st_size
        data = handle.read(limit.value + 1) if size <= limit.value else b""
        if size > limit.value or len(data) > limit.value:  # also one that grew while it was read
            raise UserInputError(
                f"{path}: " + limit.refusal(f"the size in bytes of {what}", max(size, len(data)))
            )
    return data


def write_atomic(path: str | os.PathLike, write) -> pathlib.Path:
    """Call ``write(file_handle)`` on a temporary file beside ``path``, then rename it into place.

    A reader never sees a half-written ``path``: it is either absent or complete. The file gets the
    permissions a plain ``open(path, "w")`` would give (0666 less the umask), not the temporary file's
    private 0600, so results on a shared machine or cluster stay readable by the group.
    """
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle = tempfile.NamedTemporaryFile(
        dir=path.parent, prefix=f".{path.name}.", suffix=".tmp", delete=False
    )
    try:
        with handle:
            write(handle)
        os.chmod(handle.name, 0o666 & ~_umask())
        os.replace(handle.name, path)
    except BaseException:
        pathlib.Path(handle.name).unlink(missing_ok=True)
        raise
    return path


def _umask() -> int:
    """The process's umask (read by setting it and putting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_json(path: str | os.PathLike, document: Any) -> pathlib.Path:
    text = json.dumps(document, indent=2, sort_keys=False, allow_nan=False)
    return write_atomic(path, lambda handle: handle.write(text.encode() + b"\n"))


def cached_json(
    path: str | os.PathLike,
    decode,
    compute,
    refresh: bool = False,
    announce=None,
    message: str = "",
):
    """A result cached as JSON at ``path``: ``decode(document)`` of the file when it is there and
    readable (an unreadable or foreign entry is recomputed and overwritten), else ``compute()``,
    written with ``.to_json_dict()``. ``announce(message)`` is called before a computation."""
    path = pathlib.Path(path)
    if not refresh and path.is_file():
        try:
            with open(path) as handle:
                return decode(json.load(handle))
        except (OSError, ValueError, KeyError, TypeError):
            pass
    if announce is not None and message:
        announce(message)
    result = compute()
    try:
        write_json(path, result.to_json_dict())
    except OSError as err:
        raise ValueError(f"cannot write the cache entry {str(path)!r}: {err}") from err
    return result


def write_csv(
    path: str | os.PathLike, header: Sequence[str], rows: Iterable[Sequence[Any]]
) -> pathlib.Path:
    """A UTF-8 CSV file of ``header`` then ``rows``, written atomically (see :func:`write_atomic`)."""

    def write(handle) -> None:
        text = io.TextIOWrapper(handle, newline="", encoding="utf-8")
        writer = csv.writer(text)
        writer.writerow(header)
        writer.writerows(rows)
        text.flush()
        text.detach()

    return write_atomic(path, write)


def write_npz(path: str | os.PathLike, **arrays: np.ndarray) -> pathlib.Path:
    return write_atomic(path, lambda handle: np.savez(handle, **arrays))


def code_version() -> dict[str, Any]:
    """The package version and, in a git checkout, the commit and whether the tree is dirty."""
    version = {"package": installed_version("rmac-mj")}
    root = pathlib.Path(__file__).resolve().parents[2]

    def git(*args: str) -> str:
        return subprocess.run(
            ["git", *args], cwd=root, capture_output=True, text=True, timeout=10, check=True
        ).stdout.strip()

    try:
        commit = git("rev-parse", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no")
        version["commit"] = commit
        version["dirty"] = bool(dirty)
    except (OSError, subprocess.SubprocessError):
        version["commit"] = None
    return version


def provenance() -> dict[str, Any]:
    """Package versions, code version and machine: stored beside every result."""
    return {
        "code": code_version(),
        "packages": {
            name: installed_version(name)
            for name in ("mujoco", "dm-control", "numpy", "scipy", "numba", "matplotlib")
        },
        "python": platform.python_version(),
        "machine": {
            "cpus": os.cpu_count(),
            "processor": platform.processor() or platform.machine(),
            "system": platform.system(),
        },
    }


def as_jsonable(value: Any) -> Any:
    """Dataclasses, tuples and numpy scalars/arrays as plain JSON data."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return as_jsonable(dataclasses.asdict(value))
    if isinstance(value, dict):
        return {str(k): as_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [as_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def finite_or_none(value: Any) -> Any:
    """``value`` (JSON data) with every non-finite float (NaN, inf) replaced by None, so that it can
    be written as strict JSON."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: finite_or_none(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(item) for item in value]
    return value
