"""rmac-mj: actor-critic control with reference model learning on MuJoCo.

Reproduces Grondman et al., "Actor-Critic Control with Reference Model Learning": the DC-motor pendulum
(``rmac_mj.models``, ``rmac_mj.tasks``), LLR and tile-coding approximators (``rmac_mj.approximators``),
the RMAC and S-AC learners (``rmac_mj.agents``) and the experiments that compare them
(``rmac_mj.experiments``).
"""

__version__ = "0.1.0"

import os as _os

# dm-control chooses its GL back end when first imported; on a machine without a display, prefer the
# off-screen EGL back end to the GLFW default (which only warns there). See rmac_mj.experiments.render.
if "MUJOCO_GL" not in _os.environ and not _os.environ.get("DISPLAY"):
    _os.environ["MUJOCO_GL"] = "egl"
