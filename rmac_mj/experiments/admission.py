"""What is checked and prepared before a run's first experiment: nothing runs that cannot finish.

:func:`resolve_agents` builds every learner once on the task's spaces (bad hyperparameters refused
in one line), :func:`check_memory` checks their memory estimates, :func:`warm_up` compiles the
kernels before the workers start.
"""

from __future__ import annotations

import decimal
import functools
import hashlib
import json
import os
import threading
import time
from collections.abc import Callable, Iterable
from typing import Any

from rmac_mj import _heartbeat as heartbeat
from rmac_mj import agents
from rmac_mj.agents import Agent, make_agent
from rmac_mj.agents.spaces import ActionSpace, StateSpace
from rmac_mj.errors import UserInputError, environment_failure_at
from rmac_mj.experiments import execution
from rmac_mj.experiments import prior_transitions as prior_data
from rmac_mj.experiments.protocol import Protocol
from rmac_mj.rollout import (
    action_space_of,
    env_step_seconds,
    learner_state_of,
    run_trial,
    state_space_of,
    trial_seconds,
)
from rmac_mj.tasks.common import LearnerStateSpec


class TaskFacts:
    """What the driver asks of each distinct task (its environment's description), its environment built
    once for all: the spaces the learners see, the trial's length and the learner's state."""

    def __init__(self) -> None:
        self._facts: dict[str, tuple[StateSpace, ActionSpace, float, LearnerStateSpec, float]] = {}

    def _of(
        self, protocol: Protocol
    ) -> tuple[StateSpace, ActionSpace, float, LearnerStateSpec, float]:
        key = json.dumps(protocol.environment_description(), sort_keys=True, default=repr)
        if key not in self._facts:
            env = protocol.make_environment()
            self._facts[key] = (
                state_space_of(env),
                action_space_of(env),
                trial_seconds(env),
                learner_state_of(env),
                env_step_seconds(env),
            )
        return self._facts[key]

    def of(self, protocol: Protocol) -> tuple[StateSpace, ActionSpace]:
        """The learner's state and action spaces on the protocol's task."""
        return self._of(protocol)[:2]

    def trial_seconds(self, protocol: Protocol) -> float:
        """Simulated seconds of one trial of the protocol's task."""
        return self._of(protocol)[2]

    def env_step_seconds(self, protocol: Protocol) -> float:
        """Simulated seconds of one environment step of the protocol's task (before any action
        repeat): what a budget in environment steps counts."""
        return self._of(protocol)[4]

    def learner_state(self, protocol: Protocol) -> LearnerStateSpec:
        """What the learner's state x is on the protocol's task (inferred for an outside one)."""
        return self._of(protocol)[3]


def read_prior_file(
    protocol: Protocol, spaces: TaskFacts
) -> tuple[prior_data.Demonstration | None, str | None]:
    """The protocol's recorded prior knowledge, checked against its task, and the file's SHA-256
    (stored in config.json, so that ``resume`` refuses a file that changed); (None, None) without."""
    path = protocol.prior_file
    if path is None:
        return None, None
    demonstration = prior_data.load_demonstration(path, *spaces.of(protocol))
    return demonstration, hashlib.sha256(path.read_bytes()).hexdigest()


def configured_agent(protocol: Protocol, algorithm: str, spaces: TaskFacts) -> Agent:
    """The learner ``algorithm`` with the protocol's config for it, built on the protocol's task
    (seed 0): how a config is checked against what only the task reveals. ValueError or TypeError
    from the learner when its config cannot build there."""
    config = protocol.agent_configs.get(algorithm)
    return make_agent(algorithm, *spaces.of(protocol), config=config, seed=0)


def resolve_agents(protocol: Protocol, spaces: TaskFacts) -> dict[str, dict[str, Any]]:
    """Each learner's resolved hyperparameters (``Agent.config_dict``) on the protocol's task; a
    learner its config cannot build there is refused as a :class:`UserInputError` naming it."""
    from rmac_mj import _cache

    resolved = {}
    for algorithm in protocol.algorithms:
        try:
            with _cache.compile_notice_muted():  # a second or two; the warm-up says it all
                agent = configured_agent(protocol, algorithm, spaces)
        except (ValueError, TypeError) as error:
            raise UserInputError(f"{algorithm} on {protocol.environment_name}: {error}") from None
        resolved[algorithm] = agent.config_dict()
    return resolved


def memory_estimate(protocol: Protocol, algorithm: str, spaces: TaskFacts) -> int:
    """Bytes one experiment of ``algorithm`` needs, estimated from its config before anything is
    allocated (``rmac_mj.agents.memory_estimate``: the learner class's own estimate); a config
    its task's units make invalid (neighbours beyond the capacity the task sets) is refused as a
    :class:`UserInputError` naming the learner, as :func:`resolve_agents` refuses it."""
    try:
        estimate = agents.memory_estimate(
            algorithm, *spaces.of(protocol), config=protocol.agent_configs.get(algorithm)
        )
    except (ValueError, TypeError) as error:
        raise UserInputError(f"{algorithm} on {protocol.environment_name}: {error}") from None
    return int(estimate)


def machine_memory() -> int | None:
    """The memory a run may use, in bytes: the machine's physical memory, or this process's
    address-space limit (``ulimit -v``) where that is lower; None where the system says neither."""
    try:
        physical = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        physical = None
    try:
        import resource

        limit = resource.getrlimit(resource.RLIMIT_AS)[0]
        if limit == resource.RLIM_INFINITY or limit <= 0:
            limit = None
    except (ImportError, OSError, ValueError, AttributeError):  # no such limit on this system
        limit = None
    if limit is None or physical is None:
        return physical if limit is None else limit
    return min(physical, limit)


def _gb(size: int) -> str:
    """``size`` bytes in GB, for messages: "2.5 GB", "3.2e+12 GB", and beyond a float's range
    (a tiling of a 1000-dimensional state) "1.0e+400 GB" from the integer's own digits."""
    if size < 1e18:
        return f"{size / 1e9:.1f} GB"
    return f"{decimal.Decimal(int(size)) / 10**9:.1e} GB"


def check_memory(
    protocols: Iterable[Protocol],
    workers: int,
    spaces: TaskFacts,
    available: int | None = None,
    algorithms: Iterable[str] | None = None,
) -> None:
    """Refuse, in one line, learners that cannot fit: ``workers`` experiments of the largest at once
    (plus this driver's one of it, for the warm-up) must fit the machine's memory (``available``,
    default :func:`machine_memory`). ``algorithms``: only these of each protocol's learners."""
    available = machine_memory() if available is None else available
    if available is None:
        return
    largest, name = 0, None
    for protocol in protocols:
        for algorithm in protocol.algorithms if algorithms is None else algorithms:
            size = memory_estimate(protocol, algorithm, spaces)
            if size > largest:
                largest, name = size, (algorithm, protocol)
    if name is None or (workers + 1) * largest <= available:
        return
    algorithm, protocol = name
    overrides = protocol.agent_configs.get(algorithm)
    raise UserInputError(
        f"{algorithm}{f' with {json.dumps(overrides)}' if overrides else ''} needs about "
        f"{_gb(largest)} per experiment; {workers} worker{'s' * (workers != 1)} and the driver need "
        f"{_gb((workers + 1) * largest)}, more than this machine's {_gb(available)}: use smaller "
        "memories or fewer --jobs"
    )


def warm_up(protocol: Protocol, algorithms: Iterable[str] | None = None) -> None:
    """Compile the kernels of ``protocol``'s learners (or of ``algorithms``), or load them from
    numba's disk cache: one learning and one greedy trial of a throw-away agent of each learner, in
    this process. numba compiles only what these trials call: the kernels of the learners chosen,
    with their options.

    Run before the worker processes start, so that they load the compiled kernels from the cache
    instead of each compiling them at once.
    """
    env = protocol.make_environment(task_seed=0)
    for algorithm in protocol.algorithms if algorithms is None else algorithms:
        agent = make_agent(
            algorithm,
            state_space_of(env),
            action_space_of(env),
            config=protocol.agent_configs.get(algorithm),
            seed=0,
        )
        where = f"a first trial of {algorithm} before the experiments"
        with (
            environment_failure_at(where),
            heartbeat.working(f"{protocol.environment_name}: {where}"),
        ):
            run_trial(env, agent, learn=True)
            run_trial(env, agent, learn=False)


def _warm_up_one(protocol: Protocol, algorithm: str) -> None:
    """:func:`warm_up` of one learner in a worker, silent: the driver says it."""
    from rmac_mj import _cache

    with _cache.compile_notice_muted():
        warm_up(protocol, (algorithm,))


def _kernel_key(protocol: Protocol, algorithm: str) -> str:
    """What decides a learner's kernels: its task and back end (not its other settings)."""
    backend = protocol.agent_configs.get(algorithm, {}).get("backend")
    return json.dumps(
        [protocol.environment_description(), algorithm, backend], sort_keys=True, default=repr
    )


#: Seconds between two lines of the warm-up's progress while numba compiles.
COMPILE_PROGRESS_SECONDS = 10.0


class _CompileNotes:
    """What a run says while numba compiles (the first run only): which learners' kernels, every
    ``interval`` seconds how long so far, then how long each learner's took and the total."""

    def __init__(
        self, learners: dict[str, str], log: Callable[[str], None] | None, interval: float
    ):
        self.left, self.log, self.interval = dict(learners), log, interval
        self.started: float | None = None
        self.last = 0.0

    def _say(self, message: str) -> None:
        self.last = time.perf_counter()
        if self.log is not None:
            self.log(message)

    def _names(self) -> str:
        return ", ".join(dict.fromkeys(self.left.values()))

    def compiling(self) -> bool:
        return self.started is not None and bool(self.left)

    def begin(self) -> None:
        from rmac_mj import _cache

        self.started = time.perf_counter()
        self._say(
            f"compiling the kernels of {self._names()}, first run only (cached in "
            f"{_cache.numba_cache_location()})"
        )

    def so_far(self) -> None:
        if self.compiling():
            self._say(
                f"compiling the kernels of {self._names()}: "
                f"{time.perf_counter() - self.started:.0f} s so far"
            )

    def tick(self) -> None:
        """:meth:`so_far`, if ``interval`` seconds passed since the last line."""
        if time.perf_counter() - self.last >= self.interval:
            self.so_far()

    def compiled(self, key: str) -> None:
        """One learner's kernels are compiled (side by side): its experiments may start."""
        learner, seconds = self.left.pop(key), time.perf_counter() - self.started
        if self.left:
            self._say(
                f"kernels of {learner} compiled in {seconds:.0f} s ({self._names()} still compiling)"
            )
        else:
            self._say(f"kernels compiled in {seconds:.0f} s")

    def end(self) -> None:
        """All compiled (one after another, here)."""
        if self.compiling():
            self.left.clear()
            self._say(f"kernels compiled in {time.perf_counter() - self.started:.0f} s")


def warm_up_announced(
    protocols: Iterable[Protocol],
    log: Callable[[str], None] | None,
    interval: float = COMPILE_PROGRESS_SECONDS,
    jobs: int = 1,
    learner_of: Callable[[Any], tuple[Protocol, str]] | None = None,
) -> execution.Prerequisites | None:
    """:func:`warm_up` once per distinct task, learner and back end (the kernels do not depend on
    the other settings), saying so when numba really compiles (the first run only): which learners'
    kernels, then every ``interval`` seconds how long it has taken so far, then the total.

    In a process that started with an empty kernel cache, with ``jobs`` > 1 and ``learner_of``
    (an item of the run's: its protocol and learner), the compiles are left to the workers: returned
    as :class:`~rmac_mj.experiments.execution.Prerequisites` of the items, one worker per learner,
    so that each learner's experiments start as soon as its own kernels are compiled, side by side
    with the others' compiles. Otherwise the kernels load (or compile) here, one learner after
    another, and None is returned: with some kernels cached (a later run, the common case) that
    takes about a second and starts no process."""
    from rmac_mj import _cache

    pairs: dict[str, tuple[Protocol, str]] = {}
    for protocol in protocols:
        for algorithm in protocol.algorithms:
            pairs.setdefault(_kernel_key(protocol, algorithm), (protocol, algorithm))
    notes = _CompileNotes({key: a for key, (_, a) in pairs.items()}, log, interval)
    if jobs > 1 and len(pairs) > 1 and learner_of is not None and _cache.started_with_empty_cache():
        notes.begin()  # the cache is empty: numba compiles, in the workers
        return execution.Prerequisites(
            {key: functools.partial(_warm_up_one, *pair) for key, pair in pairs.items()},
            needs=lambda item: _kernel_key(*learner_of(item)),
            done=notes.compiled,
            poll=notes.tick,
        )
    _warm_up_here(list(pairs.values()), notes)
    return None


def _warm_up_here(pairs: list[tuple[Protocol, str]], notes: _CompileNotes) -> None:
    """:func:`warm_up` of each (protocol, learner) in this process, with ``notes`` said from a
    thread (numba holds the interpreter for seconds at a time: a line now and then)."""
    from rmac_mj import _cache

    done = threading.Event()

    def tick() -> None:
        while not done.wait(notes.interval):
            notes.so_far()

    ticker = threading.Thread(target=tick, name="rmac-mj compile progress", daemon=True)
    if notes.log is not None:
        ticker.start()
    try:
        # while numba compiles, its progress is the one voice of the first trials
        with _cache.on_first_compile(notes.begin), heartbeat.quiet_while(notes.compiling):
            for protocol, algorithm in pairs:
                warm_up(protocol, (algorithm,))
    finally:
        done.set()
        if ticker.is_alive():
            ticker.join()
    notes.end()
