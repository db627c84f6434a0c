"""Test-wide set-up: off-screen rendering must be chosen before mujoco is first imported."""

import os

if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"
