"""MuJoCo's OpenGL back end, chosen before ``mujoco`` is first imported.

:func:`select_gl_backend` picks EGL, else OSMesa, without a display (a user's ``MUJOCO_GL`` is
kept); :func:`require_gl_backend` names the packages to install; :func:`open_renderer` opens every
renderer through that check.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import numbers
import os
import sys
from collections.abc import MutableMapping

from rmac_mj.errors import UserInputError

#: Off-screen back ends in order of preference: (MUJOCO_GL value, library stem, sonames to try).
OFFSCREEN_BACKENDS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("egl", "EGL", ("libEGL.so.1", "libEGL.so")),
    ("osmesa", "OSMesa", ("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so")),
)

#: What :func:`select_gl_backend` sets ``MUJOCO_GL`` to when no back end can load.
DISABLED = "disable"

#: ``MUJOCO_GL`` values that turn rendering off (MuJoCo's and dm-control's spellings).
_OFF = ("disable", "disabled", "off", "false", "0")

INSTALL_HINT = (
    "Off-screen rendering needs an OpenGL back end for MuJoCo, and none could start here. Install "
    "Mesa's EGL (first choice) or OSMesa, e.g. on Debian/Ubuntu:\n"
    "    sudo apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1   # EGL\n"
    "    sudo apt-get install libosmesa6                                      # or OSMesa\n"
    "then start Python again (MuJoCo picks its back end when first imported). To force one, set "
    "MUJOCO_GL=egl or MUJOCO_GL=osmesa before Python starts, and import rmac_mj before mujoco."
)


class GLBackendError(RuntimeError):
    """No OpenGL back end can render off-screen in this process."""


def can_load_library(stem: str, sonames: tuple[str, ...] = ()) -> bool:
    """True when the shared library ``lib<stem>`` can be loaded with ``ctypes`` (dlopen)."""
    if any(_loads(name) for name in sonames):
        return True
    found = ctypes.util.find_library(stem)  # slower (runs ldconfig): only when no soname loads
    return bool(found) and _loads(found)


def _loads(name: str) -> bool:
    try:
        ctypes.CDLL(name)
    except OSError:
        return False
    return True


def egl_device_count(sonames: tuple[str, ...] = OFFSCREEN_BACKENDS[0][2]) -> int:
    """How many EGL devices ``eglQueryDevicesEXT`` reports (0 when libEGL or the extension is missing).

    libEGL (libglvnd) loads even without a vendor library such as Mesa's libegl-mesa0, and then
    dm-control fails at import with MUJOCO_GL=egl; a device count of 0 tells that case apart.
    """
    for name in sonames:
        try:
            egl = ctypes.CDLL(name)
        except OSError:
            continue
        egl.eglGetProcAddress.restype = ctypes.c_void_p
        egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        address = egl.eglGetProcAddress(b"eglQueryDevicesEXT")
        if not address:
            return 0
        query = ctypes.CFUNCTYPE(
            ctypes.c_uint, ctypes.c_int, ctypes.c_void_p, ctypes.POINTER(ctypes.c_int)
        )(address)
        count = ctypes.c_int(0)
        return count.value if query(0, None, ctypes.byref(count)) else 0
    return 0


def backend_available(backend: str) -> bool:
    """True when the off-screen back end ``"egl"`` or ``"osmesa"`` can be loaded here."""
    for name, stem, sonames in OFFSCREEN_BACKENDS:
        if name == backend:
            if not can_load_library(stem, sonames):
                return False
            return backend != "egl" or egl_device_count(sonames) > 0
    raise ValueError(
        f"backend must be one of {[b[0] for b in OFFSCREEN_BACKENDS]}, got {backend!r}"
    )


def has_display(environ: MutableMapping[str, str] | None = None) -> bool:
    """True when a window system is reachable (always on macOS/Windows; X11 or Wayland on Linux)."""
    environ = os.environ if environ is None else environ
    if not sys.platform.startswith("linux"):
        return True
    return bool(environ.get("DISPLAY") or environ.get("WAYLAND_DISPLAY"))


def select_gl_backend(environ: MutableMapping[str, str] | None = None) -> str | None:
    """Set ``MUJOCO_GL`` (and ``PYOPENGL_PLATFORM``) to a back end that works here; return its name.

    A ``MUJOCO_GL`` already set is kept. Otherwise, on a Linux machine without a display: the first of
    EGL, OSMesa whose library loads (a ``PYOPENGL_PLATFORM`` of ``egl``/``osmesa`` is tried first). With
    a display, MuJoCo's default (GLFW) is left alone. When nothing loads, ``MUJOCO_GL`` is set to
    ``disable`` (MuJoCo and dm-control then import no GL at all) and :func:`require_gl_backend`
    explains. Returns the back end in effect, or None (MuJoCo's default, or none available).
    """
    environ = os.environ if environ is None else environ
    chosen = environ.get("MUJOCO_GL", "").strip().lower()
    if chosen:
        if chosen in ("egl", "osmesa") and not environ.get("PYOPENGL_PLATFORM"):
            environ["PYOPENGL_PLATFORM"] = chosen
        return chosen
    if has_display(environ):
        return None
    platform = environ.get("PYOPENGL_PLATFORM", "").strip().lower()
    candidates = sorted(OFFSCREEN_BACKENDS, key=lambda backend: backend[0] != platform)
    if platform and platform not in ("egl", "osmesa"):
        candidates = []  # PyOpenGL is pinned to another platform: neither off-screen module would import
    for backend, _, _ in candidates:
        if backend_available(backend):
            environ["MUJOCO_GL"] = backend
            environ["PYOPENGL_PLATFORM"] = backend
            return backend
    # Nothing can render. Say so to MuJoCo and dm-control too: left unset, dm-control would import
    # GLFW, which warns about the missing display on every import, rendering or not.
    environ["MUJOCO_GL"] = DISABLED
    return None


def require_gl_backend(environ: MutableMapping[str, str] | None = None) -> str:
    """The back end MuJoCo will render with; raise :class:`GLBackendError` when it cannot start.

    Checks what can be checked without creating a context: the library of an off-screen back end
    loads, or a display exists for GLFW.
    """
    environ = os.environ if environ is None else environ
    chosen = environ.get("MUJOCO_GL", "").strip().lower()
    if chosen in _OFF:
        raise GLBackendError(
            f"rendering is off: MUJOCO_GL={chosen} (rmac_mj sets this when no "
            f"OpenGL back end loads).\n{INSTALL_HINT}"
        )
    for backend, stem, _sonames in OFFSCREEN_BACKENDS:
        if chosen == backend:
            if not backend_available(backend):
                raise GLBackendError(
                    f"MUJOCO_GL={backend} but lib{stem} cannot be loaded"
                    f"{' or finds no device' if backend == 'egl' else ''}."
                    f"\n{INSTALL_HINT}"
                )
            return backend
    if chosen in ("", "glfw", "enable", "enabled", "on", "true", "1") and not has_display(environ):
        raise GLBackendError(
            f"no display and no off-screen back end (MUJOCO_GL is "
            f"{chosen or 'unset'}).\n{INSTALL_HINT}"
        )
    return chosen or "glfw"


def open_renderer(model, width: int, height: int):
    """A ``mujoco.Renderer`` of ``model`` (an ``MjModel``) at ``width`` x ``height`` pixels.

    Use it as a context manager so its GL context is freed. Raises :class:`GLBackendError` (naming
    the system packages to install) when no GL back end can start.
    """
    _check_size(model, width, height)
    backend = require_gl_backend()
    import mujoco
    from mujoco.rendering.classic import gl_context

    context_class = getattr(gl_context, "GLContext", None)
    if context_class is None:
        raise GLBackendError(f"MuJoCo could not import its {backend} back end.\n{INSTALL_HINT}")
    if context_class.__module__.startswith("mujoco.glfw") and not has_display():
        # mujoco was imported before rmac_mj chose a back end (it reads MUJOCO_GL only then).
        raise GLBackendError(
            "mujoco was imported before an off-screen back end was chosen, and "
            "there is no display for its default (GLFW): set MUJOCO_GL=egl "
            f"before starting Python, or import rmac_mj first.\n{INSTALL_HINT}"
        )
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as error:  # context creation fails in many library-specific ways
        raise GLBackendError(
            f"the {backend} back end failed to start: {error}\n{INSTALL_HINT}"
        ) from error


def _check_size(model, width: int, height: int) -> None:
    for name, value, limit, attribute in (
        ("width", width, model.vis.global_.offwidth, "offwidth"),
        ("height", height, model.vis.global_.offheight, "offheight"),
    ):
        if (
            not isinstance(value, numbers.Integral)
            or isinstance(value, bool)
            or not 0 < value <= limit
        ):
            raise UserInputError(
                f"{name} must be an integer in [1, {limit}] (the model's <global "
                f"{attribute}>), got {value!r}"
            )
