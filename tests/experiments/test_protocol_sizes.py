"""The Python API refuses sizes beyond their limits with a ValueError naming the parameter, the limit
and its reason; the memory a run may use honours the process's address-space limit."""

from __future__ import annotations

import subprocess
import sys

import pytest

from rmac_mj import constraints
from rmac_mj.agents import Planning, Replay
from rmac_mj.experiments import Protocol, TaskFacts, check_memory


@pytest.mark.parametrize(
    "field, value, limit",
    [
        ("trials", 10**12, constraints.TRIALS),
        ("experiments", 10**9, constraints.EXPERIMENTS),
        ("evaluate_starts", 10**9, constraints.EVALUATE_STARTS),
        ("prior_trials", 10**9, constraints.PRIOR_TRIALS),
    ],
)
def test_a_protocol_refuses_a_size_beyond_its_limit(field, value, limit):
    with pytest.raises(ValueError) as refused:
        Protocol(**{field: value})
    message = str(refused.value)
    assert message.startswith(f"Protocol.{field} must be an integer in [")
    assert f", {limit.value}] ({limit.reason}), got {value}" in message


@pytest.mark.parametrize("config", [Planning, Replay])
def test_rehearsal_steps_are_capped(config):
    with pytest.raises(ValueError, match=constraints.REHEARSAL_STEPS.reason):
        config(steps=10**9)
    assert config(steps=200).steps == 200  # what the studies use


@pytest.mark.slow
def test_a_tiling_is_estimated_without_allocating_it():
    script = (
        "import resource\n"
        "resource.setrlimit(resource.RLIMIT_AS, (2 * 2**30, 2 * 2**30))\n"
        "from rmac_mj.agents import ActionSpace, StateSpace, memory_estimate\n"
        "from rmac_mj.experiments.admission import machine_memory\n"
        "S = StateSpace(low=[-3.2, -25.0], high=[3.2, 25.0], periodic=[True, False])\n"
        "U = ActionSpace(low=[-3.0], high=[3.0], cost=[1.0])\n"
        "print(memory_estimate('s-ac', S, U, {'tile_coding': {'num_tilings': 10**9}}))\n"
        "print(memory_estimate('s-ac', S, U, {'tile_coding': {'tiles': [10**20, 10**20]}}))\n"
        "print(machine_memory())\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300
    )
    tilings, tiles, available = (int(line) for line in result.stdout.split())
    # 10**9 tilings of 7 x 8 tiles, 6 numbers per tile (critic, actor, traces and their index)
    assert tilings >= 8 * 6 * 56 * 10**9
    assert tiles > 10**40  # exact integers, no overflow
    assert available == 2 * 2**30


def test_the_memory_check_counts_the_planning_model():
    from rmac_mj.agents import ActionSpace, StateSpace, memory_estimate

    S = StateSpace(low=[-3.2, -25.0], high=[3.2, 25.0], periodic=[True, False])
    U = ActionSpace(low=[-3.0], high=[3.0], cost=[1.0])
    for algorithm in ("rmac", "s-ac", "mlac"):
        without = memory_estimate(algorithm, S, U)
        planning = {"planning": {"steps": 30, "model_capacity": 10**8}}
        assert memory_estimate(algorithm, S, U, planning) > without + 10**8 * 8 * 7
    facts = TaskFacts()
    protocol = Protocol(
        algorithms=("s-ac",), agent_configs={"s-ac": {"planning": planning["planning"]}}
    )
    with pytest.raises(ValueError, match="needs about"):
        check_memory([protocol], 1, facts, available=4 * 2**30)
