"""Running a protocol: the protocol, its experiments, admission, execution, progress, the runner."""

import sys as _sys

from rmac_mj import rollout as _rollout

# The trial loop's older path: ``rmac_mj.experiments.episode`` is :mod:`rmac_mj.rollout`.
_sys.modules.setdefault(__name__ + ".episode", _rollout)
episode = _rollout
