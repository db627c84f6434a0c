"""rmac-mj: actor-critic control with reference model learning on MuJoCo.

Reproduces Grondman et al., "Actor-Critic Control with Reference Model Learning": the DC-motor pendulum
(``rmac_mj.models``, ``rmac_mj.tasks``), LLR and tile-coding approximators (``rmac_mj.approximators``),
the RMAC and S-AC learners (``rmac_mj.agents``) and the experiments that compare them
(``rmac_mj.experiments``).
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
