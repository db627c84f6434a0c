"""Long work says what it is doing every INTERVAL seconds to whoever listens (the command line), and
nothing to a library user; the probes of an outside environment are such work."""

from __future__ import annotations

import textwrap
import threading
import time

import pytest

from rmac_mj import _heartbeat as heartbeat
from rmac_mj.cli import main
from rmac_mj.errors import EXIT_BAD_INPUT

#: The interval in these tests (the command's is 10 s).
INTERVAL = 0.05


@pytest.fixture
def quick(monkeypatch):
    monkeypatch.setattr(heartbeat, "INTERVAL", INTERVAL)


def test_a_listener_hears_the_innermost_work_and_how_far_it_is(quick):
    heard = []
    with heartbeat.listening(heard.append):
        with heartbeat.working("outer"):
            time.sleep(4 * INTERVAL)
            with heartbeat.working("inner", total=10, unit="steps") as work:
                work.done = 3
                time.sleep(4 * INTERVAL)
    assert any(line.startswith("outer: ") and "s so far" in line for line in heard), heard
    assert any(line.startswith("inner: ") and line.endswith(", 3 of 10 steps") for line in heard)
    assert not any(t.name == "rmac-mj heartbeat" for t in threading.enumerate())


def test_without_a_listener_nothing_is_said_and_no_thread_runs(quick):
    with heartbeat.working("alone") as work:
        assert not any(t.name == "rmac-mj heartbeat" for t in threading.enumerate())
        work.done = 1


SLOW = textwrap.dedent(
    """
    import time
    import dm_env
    import numpy as np
    from dm_env import specs

    class SlowReset(dm_env.Environment):
        def __init__(self):
            self.t = 0
        def control_timestep(self):
            return 0.05
        def observation_spec(self):
            return {"x": specs.BoundedArray((2,), float, [-1, -1], [1, 1])}
        def action_spec(self):
            return specs.BoundedArray((1,), float, -1, 1)
        def reset(self):
            time.sleep(0.2)  # 30 s in the field: a robot driven back to its start
            self.t = 0
            return dm_env.restart({"x": np.zeros(2)})
        def step(self, action):
            self.t += 1
            if self.t >= 5:
                return dm_env.truncation(0.0, {"x": np.zeros(2)})
            return dm_env.transition(0.0, {"x": np.zeros(2)})

    def make():
        return SlowReset()
    """
)


def test_probing_a_slow_environment_says_so_before_the_run(quick, tmp_path, capsys):
    path = tmp_path / "slow.py"
    path.write_text(SLOW)
    code = main(
        ["reproduce", "--env", f"{path}:make", "--algorithms", "s-ac", "--set", "s-ac.gamma=2"]
        + ["--no-optimal", "--no-progress", "--out", str(tmp_path / "out")]
    )  # refused once probed: the bad --set is checked after the environment
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == EXIT_BAD_INPUT and "gamma" in lines[-1], lines
    said = [line for line in lines[:-1] if "s so far" in line]
    assert said and all(line.startswith(f"rmac-mj: env '{path}:make': ") for line in said), lines
    assert any("random actions" in line for line in said), said


def test_another_voice_telling_of_the_same_wait_hushes_it(quick):
    heard, compiling = [], threading.Event()
    with heartbeat.listening(heard.append), heartbeat.quiet_while(compiling.is_set):
        with heartbeat.working("first trial"):
            compiling.set()  # the compile says how long it takes: once is enough
            time.sleep(6 * INTERVAL)
            assert heard == []
            compiling.clear()
            time.sleep(4 * INTERVAL)
    assert heard and all(line.startswith("first trial: ") for line in heard), heard
