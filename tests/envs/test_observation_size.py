"""An outside environment's observation is sized from its spec before it is probed."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from rmac_mj import constraints

WIDE = '''
import dm_env
import numpy as np
from dm_env import specs


class Wide(dm_env.Environment):
    """Two million numbers per observation (an image, say), none declared as the state."""

    SIZE = 2_000_000

    def reset(self):
        return dm_env.restart(np.zeros(self.SIZE))

    def step(self, action):
        return dm_env.transition(0.0, np.zeros(self.SIZE))

    def observation_spec(self):
        return specs.BoundedArray((self.SIZE,), float, -1.0, 1.0, name="pixels")

    def action_spec(self):
        return specs.BoundedArray((1,), float, -1.0, 1.0)


def make_wide():
    return Wide()
'''


@pytest.mark.slow
def test_a_two_million_number_observation_is_refused_before_it_is_probed(tmp_path):
    factory = tmp_path / "wide.py"
    factory.write_text(WIDE)
    script = textwrap.dedent(
        f"""
        import resource
        resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, 4 * 2**30))
        from rmac_mj.experiments.protocol import Protocol
        try:
            Protocol(env="{factory}:make_wide", algorithms=("s-ac",), trial_steps=10,
                     control_timestep=0.1)
        except ValueError as error:
            print(error)
        """
    )
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0 and "MemoryError" not in result.stderr, result.stderr
    message = result.stdout.strip()
    assert "the observation's size must be at most" in message and "got 2000000" in message
    assert constraints.OBSERVATION_SIZE.reason in message and "learner_state.keys" in message
