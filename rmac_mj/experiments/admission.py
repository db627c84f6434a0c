"""What is checked and prepared before a run's first experiment: nothing runs that cannot finish.

:func:`resolve_agents` builds every learner once on the task's spaces (bad hyperparameters refused
in one line), :func:`check_memory` checks their memory estimates, :func:`warm_up` compiles the
kernels before the workers start.
"""

from __future__ import annotations

import decimal
import hashlib
import json
import multiprocessing
import os
import threading
import time
from collections.abc import Callable, Iterable
from typing import Any

from rmac_mj import _heartbeat as heartbeat
from rmac_mj import agents
from rmac_mj.agents import make_agent
from rmac_mj.agents.spaces import ActionSpace, StateSpace
from rmac_mj.errors import UserInputError, environment_failure_at
from rmac_mj.experiments import prior_transitions as prior_data
from rmac_mj.experiments.execution import ctrl_c_ignored_by_new_processes
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


def resolve_agents(protocol: Protocol, spaces: TaskFacts) -> dict[str, dict[str, Any]]:
    """Each learner's resolved hyperparameters (``Agent.config_dict``) on the protocol's task; a
    learner its config cannot build there is refused as a :class:`UserInputError` naming it."""
    from rmac_mj import _cache

    state_space, action_space = spaces.of(protocol)
    resolved = {}
    for algorithm in protocol.algorithms:
        try:
            with _cache.compile_notice_muted():  # a second or two; the warm-up says it all
                agent = make_agent(
                    algorithm,
                    state_space,
                    action_space,
                    config=protocol.agent_configs.get(algorithm),
                    seed=0,
                )
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
    """:func:`warm_up` of one learner in a compiler process, silent: the driver says it."""
    from rmac_mj import _cache

    with _cache.compile_notice_muted():
        warm_up(protocol, (algorithm,))


def warm_up_side_by_side(pairs: list[tuple[Protocol, str]], jobs: int) -> None:
    """:func:`warm_up` of each (protocol, learner) in ``pairs`` in its own process, ``jobs`` at a
    time (spawned: numba's compiler holds the interpreter, so threads would take turns): the
    learners' kernels compile side by side into the shared disk cache. Learners that share kernels
    (RMAC and MLAC: the LLR memories) may both compile those; the wall time is still the
    slowest one's."""
    context = multiprocessing.get_context("spawn")
    with ctrl_c_ignored_by_new_processes():  # Ctrl-C stops them from here, without tracebacks
        pool = context.Pool(processes=min(jobs, len(pairs)))
    try:
        for result in [pool.apply_async(_warm_up_one, pair) for pair in pairs]:
            result.get()
        pool.close()
    finally:
        pool.terminate()
        pool.join()


#: Seconds between two lines of the warm-up's progress while numba compiles.
COMPILE_PROGRESS_SECONDS = 10.0


def warm_up_announced(
    protocols: Iterable[Protocol],
    log: Callable[[str], None] | None,
    interval: float = COMPILE_PROGRESS_SECONDS,
    jobs: int = 1,
) -> None:
    """:func:`warm_up` once per distinct task, learner and back end (the kernels do not depend on
    the other settings), saying so when numba really compiles (the first run only): which learners'
    kernels, then every ``interval`` seconds how long it has taken so far, then the total.

    In a process that started with an empty kernel cache, with ``jobs`` > 1, the learners compile
    side by side (:func:`warm_up_side_by_side`, one process each): the run waits for the slowest
    learner's compile, not for their sum. With some kernels cached (a later run, the common case) they load
    here, one after another, in about a second: no process to start."""
    from rmac_mj import _cache

    seen, chosen = set(), []
    for protocol in protocols:
        key = json.dumps(
            [
                protocol.environment_description(),
                protocol.algorithms,
                [protocol.agent_configs.get(a, {}).get("backend") for a in protocol.algorithms],
            ],
            sort_keys=True,
            default=repr,
        )
        if key not in seen:
            seen.add(key)
            chosen.append(protocol)
    learners = ", ".join(dict.fromkeys(a for p in chosen for a in p.algorithms))
    compile_started = time.perf_counter()
    compiling, done = threading.Event(), threading.Event()

    def first_compile() -> None:
        compiling.set()
        if log is not None:
            log(
                f"compiling the kernels of {learners}, first run only (cached in "
                f"{_cache.numba_cache_location()})"
            )

    def tick() -> None:  # numba holds the interpreter for seconds at a time: a line now and then
        while not done.wait(interval):
            if compiling.is_set():
                log(
                    f"compiling the kernels of {learners}: "
                    f"{time.perf_counter() - compile_started:.0f} s so far"
                )

    pairs = [(p, a) for p in chosen for a in p.algorithms]
    side_by_side = jobs > 1 and len(pairs) > 1 and _cache.started_with_empty_cache()
    if side_by_side:
        first_compile()  # the cache is empty: numba compiles, in the processes started below
    ticker = threading.Thread(target=tick, name="rmac-mj compile progress", daemon=True)
    if log is not None:
        ticker.start()
    try:
        if side_by_side:
            with heartbeat.quiet_while(compiling.is_set):
                warm_up_side_by_side(pairs, jobs)
        else:
            # while numba compiles, its progress above is the one voice of the first trials
            with _cache.on_first_compile(first_compile), heartbeat.quiet_while(compiling.is_set):
                for protocol in chosen:
                    warm_up(protocol)
    finally:
        done.set()
        if ticker.is_alive():
            ticker.join()
    if log is not None and compiling.is_set():
        log(f"kernels compiled in {time.perf_counter() - compile_started:.0f} s")
