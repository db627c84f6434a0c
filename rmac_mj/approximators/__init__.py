"""Function approximators: local linear regression memories (:class:`LLRMemory`, section 4; a
learner's settings of one: :class:`LLRConfig`) and tile coding (:class:`TileCoder`,
:class:`LinearTileApproximator`, section 6.1), each with a compiled and a plain numpy back end
behind one interface.

Compiled learners reach an LLR memory through ``LLRMemory.kernel_state`` and the ``llr_*`` functions
of :mod:`rmac_mj.approximators.llr` (its own ``__all__``), which only compiled code needs.
"""

from rmac_mj.approximators.llr import LLRConfig, LLRMemory
from rmac_mj.approximators.local_fits import LocalFits
from rmac_mj.approximators.tile_coding import LinearTileApproximator, TileCoder, TileCodingConfig

__all__ = [
    "LLRConfig",
    "LLRMemory",
    "LocalFits",
    "LinearTileApproximator",
    "TileCoder",
    "TileCodingConfig",
]
