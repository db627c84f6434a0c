"""Where rmac-mj caches what is expensive: compiled numba kernels and the near-optimal returns.

:func:`user_cache_dir` is ``$RMAC_MJ_CACHE_DIR``, else ``$XDG_CACHE_HOME/rmac-mj``, else
``~/.cache/rmac-mj``; :func:`configure_numba_cache` (run from ``rmac_mj/__init__.py`` before numba
is imported) points numba at one folder per version of the kernel sources.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import pathlib
import sys
from collections.abc import Callable, Iterator, MutableMapping

_CACHE_ENV = "RMAC_MJ_CACHE_DIR"
_NUMBA_ENV = "NUMBA_CACHE_DIR"
_PACKAGE_DIR = pathlib.Path(__file__).resolve().parent
#: Package folders that hold ``@njit(cache=True)`` kernels (numba's in-tree cache is their __pycache__).
_KERNEL_DIRS = ("agents", "approximators")
#: What the first compilation in a process says (:func:`say_when_compiling`), on the ``rmac_mj`` logger.
COMPILE_NOTICE = (
    "rmac-mj: numba is compiling the learners' kernels, first use only (about {estimate} on 2 cores; "
    "cached in {location})"
)
#: The notice's estimate: RMAC's kernels, the largest, on 2 idle cores (docs/guide/speed.md).
COMPILE_ESTIMATE = "half a minute"
_notice = {"registered": False, "said": False, "muted": 0}


def user_cache_dir(environ: MutableMapping[str, str] | None = None) -> pathlib.Path:
    """``$RMAC_MJ_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/rmac-mj``, else ``~/.cache/rmac-mj``."""
    environ = os.environ if environ is None else environ
    if environ.get(_CACHE_ENV):
        return pathlib.Path(environ[_CACHE_ENV]).expanduser()
    base = environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return pathlib.Path(base) / "rmac-mj"


def kernel_source_hash(package_dir: pathlib.Path = _PACKAGE_DIR) -> str:
    """A short hash of every module in the package folders that hold compiled kernels (their sources
    decide what numba compiles, callees included)."""
    digest = hashlib.sha256()
    for folder in _KERNEL_DIRS:
        for path in sorted((package_dir / folder).glob("*.py")):
            digest.update(path.name.encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def configure_numba_cache(
    environ: MutableMapping[str, str] | None = None, package_dir: pathlib.Path = _PACKAGE_DIR
) -> str | None:
    """Point ``NUMBA_CACHE_DIR`` at ``user_cache_dir() / "numba" / kernel_source_hash()``.

    Returns the value set, or None when the user set ``NUMBA_CACHE_DIR`` (kept as it is).

    Why a folder per version: numba's own cache checks only the timestamp of the file that defines a
    kernel, not of the kernels it calls, so after an edit of ``_llr_kernels.py`` it would load
    RMAC's step compiled with the old LLR kernels. numba reads ``NUMBA_CACHE_DIR`` when first
    imported (a value set by the user is kept), hence the early call.
    """
    environ = os.environ if environ is None else environ
    if environ.get(_NUMBA_ENV):
        _remember_start(environ)
        return None
    environ[_NUMBA_ENV] = str(user_cache_dir(environ) / "numba" / kernel_source_hash(package_dir))
    _remember_start(environ)
    if "numba" in sys.modules and environ is os.environ:  # imported before rmac_mj: too late for
        sys.modules["numba"].config.CACHE_DIR = environ[
            _NUMBA_ENV
        ]  # its import, not for our kernels
    return environ[_NUMBA_ENV]


def numba_cache_location(environ: MutableMapping[str, str] | None = None) -> str:
    """Where the compiled kernels are (or will be) cached, for messages and the README."""
    environ = os.environ if environ is None else environ
    if environ.get(_NUMBA_ENV):
        return environ[_NUMBA_ENV]
    return f"__pycache__ folders under {_PACKAGE_DIR}"


def numba_cache_is_empty(environ: MutableMapping[str, str] | None = None) -> bool:
    """Whether no kernel at all is cached yet where numba caches them (a first run): no index file
    (``*.nbi``) in ``NUMBA_CACHE_DIR``."""
    environ = os.environ if environ is None else environ
    folder = environ.get(_NUMBA_ENV)
    if not folder:
        return False  # numba's in-tree __pycache__ folders: not known, as if warm
    folder = pathlib.Path(folder)
    return not folder.is_dir() or not any(folder.rglob("*.nbi"))


def _remember_start(environ: MutableMapping[str, str]) -> None:
    if environ is os.environ:  # this process's own cache, before anything compiles
        _notice["started_empty"] = numba_cache_is_empty(environ)


def started_with_empty_cache() -> bool:
    """Whether the kernel cache was empty when this process imported rmac_mj (a first run): then
    nothing it needs is cached, whatever it has compiled since."""
    return bool(_notice.get("started_empty"))


def kernel_stats() -> dict[str, int]:
    """How many of the package's kernel signatures were loaded from the disk cache (``loaded``) and how
    many were compiled (``compiled``) in this process so far (numba's per-dispatcher statistics)."""
    from numba.core.registry import CPUDispatcher

    loaded = compiled = 0
    for name, module in list(sys.modules.items()):
        if not name.startswith("rmac_mj") or module is None:
            continue
        for value in list(vars(module).values()):
            if isinstance(value, CPUDispatcher):
                stats = value.stats
                loaded += sum(stats.cache_hits.values())
                compiled += sum(stats.cache_misses.values())
    return {"loaded": loaded, "compiled": compiled}


def _is_ours(ev) -> bool:
    dispatcher = ev.data.get("dispatcher")
    module = getattr(getattr(dispatcher, "py_func", None), "__module__", None) or ""
    return module.startswith("rmac_mj")


def say_when_compiling() -> None:
    """Make the first compilation of one of the package's kernels in this process (a load from the
    disk cache is none) say so once: on the ``rmac_mj`` logger when logging is set up to show its
    INFO lines, else on stderr. Without it a learner built from empty caches is silent for as long
    as numba compiles.

    Called by every module that defines kernels, when imported (registering twice is a no-op);
    silent inside :func:`on_first_compile`, whose caller says it its own way.
    """
    if _notice["registered"]:
        return
    from numba.core import event

    class _Notice(event.Listener):
        def on_start(self, ev):
            if _notice["said"] or _notice["muted"] or not _is_ours(ev):
                return
            _notice["said"] = True
            message = COMPILE_NOTICE.format(
                estimate=COMPILE_ESTIMATE, location=numba_cache_location()
            )
            logger = logging.getLogger("rmac_mj")
            if logger.hasHandlers() and logger.isEnabledFor(logging.INFO):
                logger.info(message)
            else:
                print(message, file=sys.stderr, flush=True)

        def on_end(self, ev):
            pass

    event.register("numba:compile", _Notice())
    _notice["registered"] = True


@contextlib.contextmanager
def compile_notice_muted() -> Iterator[None]:
    """:func:`say_when_compiling` stays silent inside (the caller says it its own way)."""
    _notice["muted"] += 1
    try:
        yield
    finally:
        _notice["muted"] -= 1


@contextlib.contextmanager
def on_first_compile(callback: Callable[[], None]) -> Iterator[None]:
    """Call ``callback()`` once, when numba starts its first real compilation (not a load from the disk
    cache) inside the ``with`` block: the moment to tell the user why nothing else is happening
    (:func:`say_when_compiling` stays silent meanwhile)."""
    from numba.core import event

    class _Listener(event.Listener):
        called = False

        def on_start(self, ev):
            if not self.called:
                self.called = True
                callback()

        def on_end(self, ev):
            pass

    with compile_notice_muted(), event.install_listener("numba:compile", _Listener()):
        yield
