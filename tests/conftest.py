"""Test-wide set-up: the GL back end must be chosen before mujoco is first imported."""

import rmac_mj  # noqa: F401  (rmac_mj/__init__.py selects the back end; see rmac_mj._gl)
