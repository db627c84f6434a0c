"""rmac-mj: Grondman et al.'s "Actor-Critic Control with Reference Model Learning" on MuJoCo.

The models and tasks (``rmac_mj.models``, ``rmac_mj.tasks``), the approximators, the learners
(``rmac_mj.agents``) and the experiments that compare them; importing it chooses the GL back end and
the numba cache before anything imports ``mujoco`` or numba.
"""

__version__ = "0.1.0"

from rmac_mj._cache import configure_numba_cache as _configure_numba_cache
from rmac_mj._gl import select_gl_backend as _select_gl_backend

# numba reads NUMBA_CACHE_DIR when first imported: before anything imports it, make sure the compiled
# kernels have a writable cache (the user cache when the package directory is read-only). See _cache.
_configure_numba_cache()

# MuJoCo and dm-control choose their GL back end when first imported: before anything imports them,
# pick an off-screen one (EGL, then OSMesa) on a machine without a display. See rmac_mj._gl.
_select_gl_backend()
