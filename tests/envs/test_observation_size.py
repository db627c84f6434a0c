"""An outside environment's observation is sized from its spec before it is probed, and a large one
is probed in about the time its numbers take (its (cos, sin) pairs found by sorting)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from rmac_mj import constraints
from rmac_mj.envs import observations
from rmac_mj.envs.observation_map import ObservationLayout

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


def _brute_force_pairs(block, low, high):
    """Every pair tried, by the definition of a (cos, sin) pair: bounds within [-1, 1], squares
    summing to 1 on every sample, an angle that moves."""
    tolerance, size = observations.UNIT_TOLERANCE, block.shape[1]
    pairs = []
    for i in range(size):
        for j in range(i + 1, size):
            if any(lo < -1 - tolerance for lo in (low[i], low[j])) or any(
                hi > 1 + tolerance for hi in (high[i], high[j])
            ):
                continue
            c, s = block[:, i], block[:, j]
            if np.all(np.abs(c * c + s * s - 1.0) <= tolerance) and np.ptp(np.arctan2(s, c)) > 1e-6:
                pairs.append((i, j))
    return pairs


def _layout(low, high):
    return ObservationLayout(sizes={"k": len(low)}, low={"k": low}, high={"k": high})


def test_the_cos_sin_pairs_found_by_sorting_are_every_pair_tried():
    rng = np.random.default_rng(0)
    for _ in range(200):
        samples, size = int(rng.integers(1, 30)), int(rng.integers(2, 20))
        block = rng.uniform(-1.2, 1.2, (samples, size))
        for _ in range(int(rng.integers(0, 4))):  # planted angles, some still, some mirrored
            i, j = rng.choice(size, 2, replace=False)
            angle = rng.uniform(-np.pi, np.pi, samples) * rng.choice([1.0, 0.0])
            block[:, i], block[:, j] = np.cos(angle), np.sin(angle) * rng.choice([1.0, -1.0])
        if rng.random() < 0.2:
            block = np.round(block)  # zeros and ones: many pairs on one sample
        if rng.random() < 0.3:
            block = block.astype(np.float32).astype(float)
        low = np.where(rng.random(size) < 0.2, -2.0, np.nan)
        high = np.where(rng.random(size) < 0.2, 2.0, 1.0)
        expected = _brute_force_pairs(block, low, high)
        elements = [element for pair in expected for element in pair]
        if len(set(elements)) < len(elements):  # an element in two pairs: which angle is it?
            with pytest.raises(ValueError, match="overlapping"):
                observations.unit_pairs(_layout(low, high), block)
            continue
        found = observations.unit_pairs(_layout(low, high), block)
        assert [(i, j) for _, i, j in found] == expected


def test_the_pairs_of_a_large_observation_are_not_tried_one_by_one(monkeypatch):
    """100,000 elements are 5e9 pairs: tried one by one, the probe took hours."""
    size = 20_000
    rng = np.random.default_rng(1)
    block = rng.uniform(-1.0, 1.0, (30, size))
    angle = rng.uniform(-np.pi, np.pi, 30)
    block[:, 10], block[:, 15_000] = np.cos(angle), np.sin(angle)
    tried = []
    exact = observations._is_unit_pair
    monkeypatch.setattr(
        observations, "_is_unit_pair", lambda *args: tried.append(args[-2:]) or exact(*args)
    )
    layout = _layout(np.full(size, -1.0), np.full(size, 1.0))
    assert observations.unit_pairs(layout, block) == [("k", 10, 15_000)]
    assert len(tried) < 10
