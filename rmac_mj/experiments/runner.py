"""The paper's comparison (section 6): learning experiments of consecutive trials, run in parallel.

A *learning experiment* is one agent learning for ``trials`` consecutive trials of a task (the paper's:
3 s swing-ups of ``dc_pendulum`` from [pi, 0]; any registered ``domain``/``task`` runs the same way, its
trial length read from the environment); the protocol repeats it ``experiments`` times per algorithm with independent seeds. Experiments are
independent, so they run in worker processes (``jobs``) or on a Dask cluster (``scheduler``); each
worker returns its results and the driver writes them atomically as they arrive, so an interrupted run
loses only the experiments in flight and ``resume`` finishes the rest with identical results. While an
experiment runs, its worker streams every trial's return to ``progress/<algorithm>/exp_<iii>.csv``
(flushed after each trial, for watching a run live); the ``curves/`` files stay the results of record.

Seeding: experiment i of every algorithm draws its agent's stream from
``SeedSequence(seed, spawn_key=(i,))``, which equals ``SeedSequence(seed).spawn(n)[i]``, and its task's
seed from that sequence's child ``(i, 0)``. The results therefore do not depend on ``jobs``, on the
order of completion, or on resuming.

Prior knowledge (``Protocol.prior``): each experiment's fresh agent is seeded before its first trial,
either from ``prior_trials`` trials of a named demonstrator (``experiments.demonstrators``) recorded
for that experiment from the sequence ``(i, 1)`` (the same demonstration for every learner of
experiment i), or from one recorded file (``experiments.prior``) that the driver reads and checks
once.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import datetime
import hashlib
import json
import math
import multiprocessing
import os
import pathlib
import signal
import sys
import time
from typing import Any, Callable, Iterable, Iterator, TextIO

import numpy as np

from rmac_mj import tasks
from rmac_mj.agents import ALGORITHMS, agent_class, config_class, config_from_dict, make_agent
from rmac_mj.agents.base import PRIOR_PARTS
from rmac_mj.errors import UserInputError
from rmac_mj.experiments import demonstrators, prior as prior_data, results
from rmac_mj.experiments.episode import action_space_of, run_trial, state_space_of, trial_seconds
from rmac_mj.experiments.snapshots import snapshot_arrays


@dataclasses.dataclass(frozen=True)
class Protocol:
    """What is run: the paper's protocol by default (section 6: 40 experiments of 600 trials).

    Attributes:
      domain, task: the environment, loaded with ``rmac_mj.tasks.load``.
      task_kwargs: task arguments (not ``random``, which comes from the seed).
      algorithms: algorithm keys, from ``rmac_mj.agents.ALGORITHMS``.
      experiments: learning experiments per algorithm.
      trials: consecutive learning trials per experiment.
      seed: root of every experiment's random stream.
      evaluate_every: after every this many learning trials, one greedy trial (no exploration, no
        learning) is recorded; 0 disables it.
      snapshot_trials: after which trials the agent is saved; stored sorted, without trials beyond
        ``trials``, and with the final trial, which is always saved.
      agent_configs: per algorithm, overrides of its hyperparameters (e.g. for ablations).
      prior: prior knowledge seeded into every fresh agent before its first trial: None (none, the
        paper's protocol), the name of a demonstrator of the task (``'demo'``, see
        ``experiments.demonstrators``), or the path of a recorded ``.npz`` file
        (``experiments.prior``). Every learner must take prior knowledge.
      prior_trials: trials of the demonstrator recorded per experiment (demonstrators only).
      prior_parts: which kinds of knowledge to seed (``base.PRIOR_PARTS``, e.g. ``('process',)`` for
        the recorded dynamics alone); empty: everything each learner takes.
    """

    domain: str = "dc_pendulum"
    task: str = "swingup"
    task_kwargs: dict[str, Any] = dataclasses.field(default_factory=dict)
    algorithms: tuple[str, ...] = ("rmac", "s-ac")
    experiments: int = 40
    trials: int = 600
    seed: int = 0
    evaluate_every: int = 0
    snapshot_trials: tuple[int, ...] = (1, 10, 50, 200)
    agent_configs: dict[str, dict[str, Any]] = dataclasses.field(default_factory=dict)
    prior: str | None = None
    prior_trials: int = 5
    prior_parts: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "algorithms", tuple(self.algorithms))
        if not self.algorithms:
            raise ValueError("algorithms must name at least one algorithm")
        for name in self.algorithms:
            if name not in ALGORITHMS:
                raise ValueError(f"unknown algorithm {name!r}; available: {', '.join(ALGORITHMS)}")
        if len(set(self.algorithms)) != len(self.algorithms):
            raise ValueError(f"algorithms must not repeat, got {self.algorithms}")
        for field in ("experiments", "trials"):
            value = getattr(self, field)
            if not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"{field} must be a positive integer, got {value!r}")
        if not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {self.seed!r}")
        if not isinstance(self.evaluate_every, (int, np.integer)) or self.evaluate_every < 0:
            raise ValueError(f"evaluate_every must be an integer >= 0, got {self.evaluate_every!r}")
        snapshot_trials = {int(t) for t in self.snapshot_trials}
        if any(t < 1 for t in snapshot_trials):
            raise ValueError(f"snapshot_trials must be positive trial numbers, got {self.snapshot_trials!r}")
        object.__setattr__(self, "snapshot_trials",
                           tuple(sorted({t for t in snapshot_trials if t <= self.trials} | {self.trials})))
        if self.domain not in tasks.TASKS_BY_DOMAIN:
            raise ValueError(f"unknown domain {self.domain!r}; available: "
                             f"{', '.join(sorted(tasks.TASKS_BY_DOMAIN))}")
        if self.task not in tasks.TASKS_BY_DOMAIN[self.domain]:
            raise ValueError(f"unknown task {self.task!r} of domain {self.domain!r}; available: "
                             f"{', '.join(tasks.TASKS_BY_DOMAIN[self.domain])}")
        if "random" in self.task_kwargs:
            raise ValueError("task_kwargs must not set 'random': the task's seed comes from `seed`")
        for name, overrides in self.agent_configs.items():
            if name not in ALGORITHMS:
                raise ValueError(f"agent_configs names unknown algorithm {name!r}")
            config_from_dict(config_class(name), overrides)  # raises on unknown or bad values
        self._check_prior()

    def _check_prior(self) -> None:
        object.__setattr__(self, "prior_parts", tuple(self.prior_parts))
        trials = self.prior_trials
        if isinstance(trials, bool) or not isinstance(trials, (int, np.integer)) or trials < 1:
            raise ValueError(f"prior_trials must be a positive integer, got {self.prior_trials!r}")
        unknown = sorted(set(self.prior_parts) - set(PRIOR_PARTS))
        if unknown:
            raise ValueError(f"prior_parts {unknown} unknown; choose from {', '.join(PRIOR_PARTS)}")
        if self.prior is None:
            if self.prior_parts:
                raise ValueError("prior_parts needs prior knowledge: set prior too")
            return
        if not isinstance(self.prior, str) or not self.prior:
            raise ValueError(f"prior must be a demonstrator name or a .npz path, got {self.prior!r}")
        if not self.prior.endswith(".npz"):
            demonstrators.get(self.domain, self.task, self.prior)  # raises, naming what exists
        refusing = [a for a in self.algorithms if not agent_class(a).prior_parts]
        if refusing:
            taking = [a for a in ALGORITHMS if agent_class(a).prior_parts]
            verb = "does" if len(refusing) == 1 else "do"
            raise ValueError(f"{', '.join(refusing)} {verb} not take prior knowledge: run only "
                             f"learners that do ({', '.join(taking)}), e.g. --algorithms "
                             f"{','.join(taking)}")
        for name in self.algorithms:
            lacking = sorted(set(self.prior_parts) - set(agent_class(name).prior_parts))
            if lacking:
                raise ValueError(f"{name} takes no {', '.join(lacking)} prior (it takes "
                                 f"{', '.join(agent_class(name).prior_parts)})")

    @property
    def prior_file(self) -> pathlib.Path | None:
        """The recorded prior knowledge file, when ``prior`` names one."""
        return pathlib.Path(self.prior) if self.prior and self.prior.endswith(".npz") else None

    @property
    def is_paper_protocol(self) -> bool:
        """True when the paper's protocol is run unchanged (both learners, default settings)."""
        default = Protocol()
        return (self.domain, self.task, self.task_kwargs, set(self.algorithms), self.experiments,
                self.trials, self.agent_configs, self.prior) == (
            default.domain, default.task, default.task_kwargs, set(default.algorithms),
            default.experiments, default.trials, default.agent_configs, default.prior)

    def as_dict(self) -> dict[str, Any]:
        return results.as_jsonable(self)


@dataclasses.dataclass(frozen=True)
class ExperimentSpec:
    """One learning experiment: ``algorithm`` number ``index`` of ``protocol``.

    ``stream_to``: the result directory whose ``progress/<algorithm>/exp_<iii>.csv`` receives every trial
    as it ends (:func:`progress_path`); None streams nothing. ``demonstration``: the recorded prior
    knowledge when ``protocol.prior`` is a file (read once by the driver).
    """

    protocol: Protocol
    algorithm: str
    index: int
    stream_to: str | None = None
    demonstration: prior_data.Demonstration | None = None


def experiment_seeds(seed: int, index: int) -> tuple[np.random.SeedSequence, int]:
    """The agent's seed sequence and the task's integer seed of experiment ``index``."""
    agent_seq = np.random.SeedSequence(seed, spawn_key=(index,))
    task_seed = int(np.random.SeedSequence(seed, spawn_key=(index, 0)).generate_state(1)[0])
    return agent_seq, task_seed


def make_environment(protocol: Protocol, task_seed: int | None = None):
    kwargs = dict(protocol.task_kwargs)
    if task_seed is not None:
        kwargs["random"] = task_seed
    return tasks.load(protocol.domain, protocol.task, task_kwargs=kwargs)


def demonstration_for(protocol: Protocol, index: int) -> prior_data.Demonstration:
    """``prior_trials`` trials of demonstrator ``protocol.prior`` for experiment ``index``, recorded
    deterministically from the sequence ``(index, 1)``: its child 0 seeds the recording's task, the
    sequence itself the demonstrator's action noise."""
    demonstrator = demonstrators.get(protocol.domain, protocol.task, protocol.prior)
    sequence = np.random.SeedSequence(protocol.seed, spawn_key=(index, 1))
    task_seed = int(np.random.SeedSequence(protocol.seed, spawn_key=(index, 1, 0))
                    .generate_state(1)[0])
    env = make_environment(protocol, task_seed)
    return prior_data.record(env, demonstrator.controller(env), protocol.prior_trials,
                             seed=np.random.default_rng(sequence),
                             action_noise=demonstrator.action_noise)


def run_experiment(spec: ExperimentSpec,
                   on_trial: Callable[[str, int, int, float], None] | None = None) -> dict[str, Any]:
    """Run one learning experiment; return its curve, greedy evaluations and snapshots.

    Nothing is written but the live trial log in ``spec.stream_to`` (if any), so it runs unchanged in
    a local worker process or on a remote Dask worker, and the caller decides where the results go.
    ``on_trial(algorithm, index, trial, return)`` is called after every learning trial.
    """
    protocol = spec.protocol
    agent_seq, task_seed = experiment_seeds(protocol.seed, spec.index)
    env = make_environment(protocol, task_seed)
    state_space, action_space = state_space_of(env), action_space_of(env)
    agent = make_agent(spec.algorithm, state_space, action_space,
                       config=protocol.agent_configs.get(spec.algorithm),
                       seed=np.random.default_rng(agent_seq))
    demonstration = spec.demonstration
    if protocol.prior is not None:
        if demonstration is None:
            demonstration = demonstration_for(protocol, spec.index)
        agent.seed_from(**demonstration.arrays(), parts=protocol.prior_parts or None)
    meta = {"domain": protocol.domain, "task": protocol.task, "task_kwargs": protocol.task_kwargs,
            "experiment": spec.index, "seed": protocol.seed}
    returns = np.empty(protocol.trials)
    greedy_trials, greedy_returns, snapshots = [], [], {}
    snapshot_trials = set(protocol.snapshot_trials) | {protocol.trials}
    start = time.perf_counter()
    log_path = (progress_path(spec.stream_to, spec.algorithm, spec.index)
                if spec.stream_to is not None else None)
    with _TrialLog(log_path) as log:
        for trial in range(1, protocol.trials + 1):
            returns[trial - 1] = run_trial(env, agent, learn=True)
            greedy = None
            if protocol.evaluate_every and trial % protocol.evaluate_every == 0:
                greedy = run_trial(env, agent, learn=False)
                greedy_trials.append(trial)
                greedy_returns.append(greedy)
            if trial in snapshot_trials:
                snapshots[trial] = snapshot_arrays(agent, state_space, action_space, trial=trial, **meta)
            log.write(trial, returns[trial - 1], greedy)
            if on_trial is not None:
                on_trial(spec.algorithm, spec.index, trial, float(returns[trial - 1]))
    return {
        "algorithm": spec.algorithm,
        "index": spec.index,
        "returns": returns,
        "greedy_trials": np.asarray(greedy_trials, dtype=int),
        "greedy_returns": np.asarray(greedy_returns, dtype=float),
        "snapshots": snapshots,
        "wall_time_s": time.perf_counter() - start,
        "task_seed": task_seed,
        "demonstration_returns": (demonstration.trial_returns() if demonstration is not None
                                  else np.zeros(0)),
    }


# ----------------------------------------------------------------------------------------------------
# Result directory layout.

def curve_path(out: pathlib.Path, algorithm: str, index: int) -> pathlib.Path:
    return out / "curves" / algorithm / f"exp_{index:03d}.npz"


def progress_path(out: str | os.PathLike, algorithm: str, index: int) -> pathlib.Path:
    """The live trial log of an experiment (see :class:`_TrialLog`)."""
    return pathlib.Path(out) / "progress" / algorithm / f"exp_{index:03d}.csv"


def wall_times_path(out: pathlib.Path) -> pathlib.Path:
    """The wall time of every part of a run (the first and each ``--resume``): ``{"parts": [...]}``."""
    return out / "wall_times.json"


class _TrialLog:
    """The live log of one experiment: a CSV (``trial,return,greedy_return``) flushed after every trial,
    so ``tail -f`` or pandas can follow a run. Not atomic and rewritten when a resumed run repeats the
    experiment: it is a view of a run in progress, not a result."""

    HEADER = "trial,return,greedy_return\n"

    def __init__(self, path: pathlib.Path | None):
        self.path, self.handle = path, None

    def __enter__(self) -> "_TrialLog":
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.handle = open(self.path, "w", encoding="utf-8")
            self.handle.write(self.HEADER)
            self.handle.flush()
        return self

    def write(self, trial: int, value: float, greedy: float | None) -> None:
        if self.handle is not None:
            text = "" if greedy is None else repr(float(greedy))
            self.handle.write(f"{trial},{float(value)!r},{text}\n")
            self.handle.flush()

    def __exit__(self, *exc) -> None:
        if self.handle is not None:
            self.handle.close()


def snapshot_dir(out: pathlib.Path, algorithm: str, index: int) -> pathlib.Path:
    return pathlib.Path(out) / "snapshots" / algorithm / f"exp_{index:03d}"


def snapshot_path(out: pathlib.Path, algorithm: str, index: int, trial: int) -> pathlib.Path:
    return snapshot_dir(out, algorithm, index) / f"trial_{trial:04d}.npz"


def save_outcome(out: pathlib.Path, outcome: dict[str, Any]) -> None:
    """Write an experiment's snapshots, then its curve: the curve file marks the experiment done."""
    algorithm, index = outcome["algorithm"], outcome["index"]
    for trial, arrays in outcome["snapshots"].items():
        results.write_npz(snapshot_path(out, algorithm, index, trial), **arrays)
    results.write_npz(curve_path(out, algorithm, index), returns=outcome["returns"],
                      greedy_trials=outcome["greedy_trials"],
                      greedy_returns=outcome["greedy_returns"],
                      wall_time_s=np.float64(outcome["wall_time_s"]),
                      task_seed=np.int64(outcome["task_seed"]),
                      demonstration_returns=outcome.get("demonstration_returns", np.zeros(0)))


def load_curves(out: pathlib.Path, protocol: Protocol, algorithm: str):
    """(returns (experiments, trials), greedy (experiments, evals), greedy_trials, wall times)."""
    returns, greedy, wall = [], [], []
    greedy_trials = np.zeros(0, dtype=int)
    for index in range(protocol.experiments):
        with np.load(curve_path(out, algorithm, index), allow_pickle=False) as data:
            returns.append(data["returns"])
            greedy.append(data["greedy_returns"])
            greedy_trials = data["greedy_trials"]
            wall.append(float(data["wall_time_s"]))
    return np.array(returns), np.array(greedy), greedy_trials, np.array(wall)


# ----------------------------------------------------------------------------------------------------
# The driver.

class ResumeRefused(UserInputError):
    """The result directory holds a different run; its results must not be mixed with this one's."""


def _differences(old: Any, new: Any, path: str = "") -> list[str]:
    """``"field: A in the directory, B now"`` for every setting that differs (nested fields dotted)."""
    if isinstance(old, dict) and isinstance(new, dict):
        found = []
        for key in [*old, *(k for k in new if k not in old)]:
            found += _differences(old.get(key), new.get(key), f"{path}{key}.")
        return found
    if old == new:
        return []
    return [f"{path.rstrip('.')}: {json.dumps(old)} in the directory, {json.dumps(new)} now"]


def _prepare(out: pathlib.Path, protocol: Protocol, resume: bool,
             prior_sha256: str | None = None) -> None:
    config_file = out / "config.json"
    document = {"protocol": protocol.as_dict(), "code": results.code_version()}
    if prior_sha256 is not None:
        document["prior_sha256"] = prior_sha256
    if config_file.exists():
        if not resume:
            raise ResumeRefused(f"{out} already holds a run; pass --resume to finish it, or choose "
                                "another --out")
        existing = json.loads(config_file.read_text())
        if (existing.get("protocol"), existing.get("prior_sha256")) != (
                document["protocol"], document.get("prior_sha256")):
            differences = _differences(existing.get("protocol", {}), document["protocol"])
            if existing.get("prior_sha256") != document.get("prior_sha256"):
                differences.append("the prior knowledge file's contents (sha256)")
            raise ResumeRefused(f"{out} was written with a different config ({'; '.join(differences)}); "
                                "refusing to mix results (give the same settings, or another --out)")
        old, new = existing.get("code", {}), document["code"]
        if (old.get("package"), old.get("commit")) != (new.get("package"), new.get("commit")):
            raise ResumeRefused(f"{out} was written by another code version ({old.get('commit')}, "
                                f"now {new.get('commit')}); refusing to mix results")
        for stale in out.rglob(".*.tmp"):  # files a killed run was writing; never renamed into place
            stale.unlink()
        return
    out.mkdir(parents=True, exist_ok=True)
    results.write_json(config_file, {**document, "provenance": results.provenance()})


def _pending(out: pathlib.Path, protocol: Protocol,
             demonstration: prior_data.Demonstration | None = None) -> list[ExperimentSpec]:
    return [ExperimentSpec(protocol, algorithm, index, demonstration=demonstration)
            for index in range(protocol.experiments) for algorithm in protocol.algorithms
            if not curve_path(out, algorithm, index).exists()]


def finished_experiments(out: str | os.PathLike, protocol: Protocol) -> int:
    """How many of ``protocol``'s experiments have their results in ``out``."""
    return protocol.experiments * len(protocol.algorithms) - len(_pending(pathlib.Path(out), protocol))


def warm_up(protocol: Protocol) -> None:
    """Compile the kernels ``protocol``'s learners use, or load them from numba's disk cache: one
    learning and one greedy trial of a throw-away agent of each learner, in this process.

    Run before the worker processes start, so that they load the compiled kernels from the cache
    instead of each compiling them at once (tens of seconds the first time, about a second after).
    """
    env = make_environment(protocol, task_seed=0)
    for algorithm in protocol.algorithms:
        agent = make_agent(algorithm, state_space_of(env), action_space_of(env),
                           config=protocol.agent_configs.get(algorithm), seed=0)
        run_trial(env, agent, learn=True)
        run_trial(env, agent, learn=False)


def _warm_up_announced(protocols: list[Protocol], log: Callable[[str], None] | None) -> None:
    """:func:`warm_up` every protocol, saying so when numba really compiles (the first run only)."""
    from rmac_mj import _cache

    def compiling() -> None:
        if log is not None:
            log(f"compiling kernels, first run only (cached in {_cache.numba_cache_location()})")
    compile_started = time.perf_counter()
    with _cache.on_first_compile(compiling):
        for protocol in protocols:
            warm_up(protocol)
    if log is not None and _cache.kernel_stats()["compiled"]:
        log(f"kernels compiled in {time.perf_counter() - compile_started:.0f} s")


def _ignore_interrupts() -> None:
    """Worker initialiser: Ctrl-C reaches the whole process group; only the driver handles it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


#: Seconds between two looks at the live trial logs of the experiments in flight.
_POLL_SECONDS = 0.5


def _local_outcomes(specs: list, jobs: int,
                    on_trial: Callable[..., None] | None = None,
                    poll: Callable[[], None] | None = None,
                    run: Callable = run_experiment) -> Iterator:
    """Outcomes ``run(spec)`` of ``specs`` in the order they finish. Serially (``jobs == 1``) ``run``
    is called as ``run(spec, on_trial)`` and ``on_trial`` sees every trial; in worker processes the
    driver calls ``poll()`` while it waits."""
    if jobs == 1 or len(specs) <= 1:
        for spec in specs:
            yield run(spec, on_trial)
        return
    # "spawn": workers start clean (no inherited GL contexts or numba state); the numba cache (filled
    # by warm_up) makes their start-up cheap. On an interrupt the driver terminates the workers: only
    # the experiments in flight are lost.
    context = multiprocessing.get_context("spawn")
    pool = context.Pool(processes=min(jobs, len(specs)), initializer=_ignore_interrupts)
    try:
        outcomes = pool.imap_unordered(run, specs, chunksize=1)
        for _ in specs:
            while True:
                try:
                    outcome = outcomes.next(timeout=_POLL_SECONDS)
                    break
                except multiprocessing.TimeoutError:
                    if poll is not None:
                        poll()
            yield outcome
        pool.close()
    finally:
        pool.terminate()
        pool.join()


def _dask_outcomes(specs: list, scheduler: str, run: Callable = run_experiment) -> Iterator:
    try:
        from distributed import Client, as_completed
    except ImportError as error:  # pragma: no cover - depends on the optional extra
        raise RuntimeError("--scheduler needs Dask: pip install 'rmac-mj[distributed]'") from error
    with Client(scheduler) as client:
        futures = [client.submit(run, spec, pure=False) for spec in specs]
        try:
            for future in as_completed(futures):
                yield future.result()
        finally:
            client.cancel(futures)


def _is_terminal(stream: TextIO) -> bool:
    isatty = getattr(stream, "isatty", None)
    try:
        return bool(isatty and isatty())
    except ValueError:  # a closed stream
        return False


class _Progress:
    """Trials done, overall and per learner, with the mean return of each learner's last trials.

    One display for one run or for several (a sweep): the learners' bars count the trials of all runs.
    On a terminal: tqdm bars (trials per second, time left). Otherwise (nohup, a Slurm log, a pipe):
    a plain line every ``interval`` seconds and at the end, without carriage returns or escape codes.
    Trials advance as the experiments report them (:meth:`trial`), and by the rest of an experiment
    when it finishes (:meth:`experiment`). An experiment is named by its key ``(run, algorithm,
    index)``, ``run`` being its position in ``protocols``.
    """

    #: Trials over which the live mean return is taken, per learner.
    RECENT = 10

    def __init__(self, protocols: list[Protocol], pending: list[tuple[int, ExperimentSpec]],
                 enabled: bool, stream: TextIO | None = None, interval: float = 10.0):
        self.algorithms = list(dict.fromkeys(a for p in protocols for a in p.algorithms))
        self.trials = {k: p.trials for k, p in enumerate(protocols)}
        self.runs = len(protocols)
        left = collections.Counter(spec.algorithm for _, spec in pending)
        runs_left = collections.Counter(k for k, _ in pending)
        self.runs_done = self.runs - len(runs_left)
        self.experiments = {a: sum(p.experiments for p in protocols if a in p.algorithms)
                            for a in self.algorithms}
        self.done = {a: self.experiments[a] - left[a] for a in self.algorithms}
        total_trials = {a: sum(p.experiments * p.trials for p in protocols if a in p.algorithms)
                        for a in self.algorithms}
        self.total_trials = {"all": sum(total_trials.values()), **total_trials}
        self.trials_done = {a: total_trials[a] - sum(self.trials[k] for k, spec in pending
                                                     if spec.algorithm == a)
                            for a in self.algorithms}
        self.experiments["all"] = sum(self.experiments[a] for a in self.algorithms)
        self.done["all"] = sum(self.done[a] for a in self.algorithms)
        self.trials_done["all"] = sum(self.trials_done[a] for a in self.algorithms)
        self.runs_left = runs_left
        self.credited: dict[tuple[int, str, int], int] = {}  # trials counted of experiments in flight
        self.recent = {a: collections.deque(maxlen=self.RECENT) for a in self.algorithms}
        self.stream = sys.stderr if stream is None else stream
        self.enabled = enabled
        # tqdm.auto draws widgets in a notebook, whose stderr is no terminal either
        self.plain = enabled and not (_is_terminal(self.stream) or "ipykernel" in sys.modules)
        self.interval = interval
        self.started = time.monotonic()
        self.first_trials = self.trials_done["all"]
        self.last_line = -math.inf
        self.bars = {}
        if not enabled:
            return
        if self.plain:
            self._line()
            return
        from tqdm.auto import tqdm
        for position, key in enumerate(["all", *self.algorithms]):
            label = ("all learners" if self.runs == 1 else f"{self.runs} runs") if key == "all" else key
            self.bars[key] = tqdm(total=self.total_trials[key], initial=self.trials_done[key],
                                  file=self.stream, desc=f"{label:>12}", unit="trial",
                                  position=position, dynamic_ncols=True)
            self.bars[key].set_postfix_str(self._postfix(key))

    def _recent_mean(self, algorithm: str) -> str:
        recent = self.recent[algorithm]
        return f"last {len(recent)} trials {np.mean(recent):.0f}" if recent else "no trial yet"

    def _postfix(self, key: str) -> str:
        text = f"{self.done[key]}/{self.experiments[key]} experiments"
        if key != "all":
            return f"{text}, {self._recent_mean(key)}"
        return text if self.runs == 1 else f"{text}, {self.runs_done}/{self.runs} runs done"

    def trial(self, key: tuple[int, str, int], trial: int, value: float) -> None:
        """Experiment ``key`` finished learning trial ``trial`` with return ``value``."""
        previous = self.credited.get(key, 0)
        if trial <= previous:
            return
        self.credited[key] = trial
        self.recent[key[1]].append(value)
        self._advance(key[1], trial - previous)

    def experiment(self, key: tuple[int, str, int], returns: np.ndarray | None = None) -> None:
        """Experiment ``key`` finished (and is saved); ``returns``: its learning curve, whose trials
        not yet reported join the recent mean."""
        run, algorithm, _ = key
        previous = self.credited.pop(key, 0)
        if returns is not None:
            self.recent[algorithm].extend(np.asarray(returns, dtype=float)[previous:][-self.RECENT:])
        self.done["all"] += 1
        self.done[algorithm] += 1
        self.runs_left[run] -= 1
        if self.runs_left[run] == 0:
            self.runs_done += 1
        self._advance(algorithm, self.trials[run] - previous)

    def _advance(self, algorithm: str, trials: int) -> None:
        for key in ("all", algorithm):
            self.trials_done[key] += trials
            if key in self.bars:
                self.bars[key].set_postfix_str(self._postfix(key), refresh=False)
                self.bars[key].update(trials)
        self.tick()

    def tick(self) -> None:
        """In plain mode, print a line if ``interval`` seconds passed since the last one."""
        if self.plain and time.monotonic() - self.last_line >= self.interval:
            self._line()

    def _line(self) -> None:
        elapsed = time.monotonic() - self.started
        total = self.total_trials["all"]
        done = self.trials_done["all"]
        rate = (done - self.first_trials) / elapsed if elapsed > 0 else 0.0
        eta = f", about {_duration((total - done) / rate)} left" if rate > 0 and done < total else ""
        runs = "" if self.runs == 1 else f", {self.runs_done}/{self.runs} runs"
        parts = [f"[{_duration(elapsed)}] {done}/{total} trials ({self.done['all']}/"
                 f"{self.experiments['all']} experiments{runs}), {rate:.0f} trials/s{eta}"]
        for algorithm in self.algorithms:
            parts.append(f"{algorithm} {self.trials_done[algorithm]}/"
                         f"{self.total_trials[algorithm]} trials, {self._recent_mean(algorithm)}")
        print(" | ".join(parts), file=self.stream, flush=True)
        self.last_line = time.monotonic()

    def close(self) -> None:
        if self.plain:  # the final state
            self._line()
        for bar in self.bars.values():
            bar.close()


def _duration(seconds: float) -> str:
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds} s"
    minutes, seconds = divmod(seconds, 60)
    if minutes < 60:
        return f"{minutes} min {seconds:02d} s"
    return f"{minutes // 60} h {minutes % 60:02d} min"


class _TrialFeed:
    """Follows the live trial logs that worker processes write (``progress/``) for the progress display."""

    def __init__(self, outs: list[pathlib.Path], pending: list[tuple[int, ExperimentSpec]],
                 progress: _Progress):
        self.files = {(k, s.algorithm, s.index): progress_path(outs[k], s.algorithm, s.index)
                      for k, s in pending}
        self.offsets: dict[tuple[int, str, int], int] = {}
        self.progress = progress

    def poll(self) -> None:
        for key, path in self.files.items():
            try:
                with open(path, "rb") as handle:
                    handle.seek(self.offsets.get(key, 0))
                    chunk = handle.read()
            except FileNotFoundError:
                continue
            end = chunk.rfind(b"\n") + 1  # complete lines only; the rest is still being written
            if not end:
                continue
            self.offsets[key] = self.offsets.get(key, 0) + end
            for line in chunk[:end].decode("utf-8").splitlines():
                trial, value, _ = line.split(",")
                if trial != "trial":
                    self.progress.trial(key, int(trial), float(value))
        self.progress.tick()

    def finished(self, key: tuple[int, str, int]) -> None:
        self.files.pop(key, None)


class _WallClock:
    """The wall time of this part of a run, counted from ``started`` (the process's start: compilation,
    the near-optimal reference and the figures included), kept in ``wall_times.json`` beside the earlier
    parts, so that a resumed run reports the total over all of them. It is written after every saved
    experiment; a killed part loses only the time since its last one."""

    def __init__(self, out: pathlib.Path, started: float, resume: bool):
        self.path = wall_times_path(out)
        self.started = started
        self.earlier: list[dict[str, Any]] = []
        if resume and self.path.is_file():
            with contextlib.suppress(ValueError, KeyError, TypeError):
                self.earlier = [dict(part) for part in json.loads(self.path.read_text())["parts"]]
        self.part = {"started": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                     "wall_s": 0.0, "experiments": 0}

    def record(self, experiments: int = 0) -> None:
        self.part["wall_s"] = time.perf_counter() - self.started
        self.part["experiments"] += experiments
        results.write_json(self.path, {"parts": [*self.earlier, self.part]})

    @property
    def parts(self) -> list[float]:
        return [float(part.get("wall_s", 0.0)) for part in [*self.earlier, self.part]]


def run_protocol(protocol: Protocol, out: str | os.PathLike, jobs: int | None = None,
                 resume: bool = False, scheduler: str | None = None, progress: bool = True,
                 optimal: Callable[[Protocol], float | None] | None = None,
                 figures: bool = True, log: Callable[[str], None] | None = None,
                 started: float | None = None, smooth: int = 1,
                 floor: Callable[[Protocol, str], float | None] | None = None) -> dict[str, Any]:
    """Run (or finish, with ``resume``) ``protocol`` into ``out``; return the summary document.

    Args:
      jobs: local worker processes (default: the machine's cores); ignored with ``scheduler``.
      scheduler: address of a Dask distributed scheduler to run the experiments on instead.
      progress: show progress (bars on a terminal, periodic plain lines otherwise) on stderr: the
        trials done overall and per learner, with each learner's recent mean return.
      optimal: returns the near-optimal return for the summary and Fig. 2, or None.
      log: called with a one-line message before anything slow that shows no progress (compiling the
        kernels the first time); None says nothing.
      started: ``time.perf_counter()`` when the caller started (default: now); the wall time in the
        summary counts from there, summed over every part of a resumed run.
      smooth: Fig. 2's running mean, in trials (1: none).
      floor: returns a learner's exploration floor (the near-optimal policy's return under that
        learner's exploration) for the summary and Fig. 2, or None.
    """
    return run_protocols([(protocol, out)], jobs=jobs, resume=resume, scheduler=scheduler,
                         progress=progress, optimal=optimal, floor=floor, figures=figures, log=log,
                         started=started, smooth=smooth)[0]


def _read_prior_file(protocol: Protocol) -> tuple[prior_data.Demonstration | None, str | None]:
    """The protocol's recorded prior knowledge, checked against its task, and the file's SHA-256
    (stored in config.json, so that ``resume`` refuses a file that changed); (None, None) without."""
    path = protocol.prior_file
    if path is None:
        return None, None
    env = make_environment(protocol)
    demonstration = prior_data.load_demonstration(path, state_space_of(env), action_space_of(env))
    return demonstration, hashlib.sha256(path.read_bytes()).hexdigest()


def run_tagged(item: tuple[Any, ExperimentSpec],
               on_trial: Callable[..., None] | None = None) -> tuple[Any, dict[str, Any]]:
    """``(tag, run_experiment(spec))`` for ``item = (tag, spec)``: lets one pool serve several runs.
    ``on_trial`` is called as ``on_trial((tag, algorithm, index), trial, return)``."""
    tag, spec = item

    def report(algorithm: str, index: int, trial: int, value: float) -> None:
        on_trial((tag, algorithm, index), trial, value)
    return tag, run_experiment(spec, report if on_trial is not None else None)


def run_protocols(runs: Iterable[tuple[Protocol, str | os.PathLike]], jobs: int | None = None,
                  resume: bool = False, scheduler: str | None = None, progress: bool = True,
                  optimal: Callable[[Protocol], float | None] | None = None,
                  floor: Callable[[Protocol, str], float | None] | None = None,
                  figures: bool = True, log: Callable[[str], None] | None = None,
                  started: float | None = None, smooth: int = 1) -> list[dict[str, Any]]:
    """Run several ``(protocol, out)`` pairs through ONE worker pool (or one Dask cluster).

    Each ``out`` becomes exactly what :func:`run_protocol` writes (config.json, curves, snapshots,
    summary.json, returns.csv, Fig. 2, wall_times.json) and is resumable the same way; all pending
    experiments of all runs are queued together, and a run is summarised as soon as its last
    experiment is saved. The arguments mean what they mean for :func:`run_protocol`; the progress
    display sums the learners' trials over the runs. Returns each run's summary, in order.
    """
    started = time.perf_counter() if started is None else started
    runs = [(protocol, pathlib.Path(out)) for protocol, out in runs]
    jobs = (os.cpu_count() or 1) if jobs is None else jobs
    if jobs < 1:
        raise ValueError(f"jobs must be a positive integer, got {jobs!r}")
    pending, clocks = [], []
    for k, (protocol, out) in enumerate(runs):
        demonstration, prior_sha256 = _read_prior_file(protocol)
        _prepare(out, protocol, resume, prior_sha256)
        clocks.append(_WallClock(out, started, resume))
        pending.extend((k, spec) for spec in _pending(out, protocol, demonstration))
    if pending and not scheduler:
        _warm_up_announced([runs[k][0] for k in sorted({k for k, _ in pending})], log)
        # the workers stream their trials to progress/; a Dask worker may not see `out`
        pending = [(k, dataclasses.replace(spec, stream_to=str(runs[k][1]))) for k, spec in pending]
        for k, spec in pending:  # a trial log left by an interrupted run is rewritten from the start
            progress_path(runs[k][1], spec.algorithm, spec.index).unlink(missing_ok=True)
    left = collections.Counter(k for k, _ in pending)
    display = _Progress([protocol for protocol, _ in runs], pending, progress and bool(pending))
    feed = _TrialFeed([out for _, out in runs], pending, display)
    summaries: list[dict[str, Any] | None] = [None] * len(runs)
    outcomes = (_dask_outcomes(pending, scheduler, run_tagged) if scheduler
                else _local_outcomes(pending, jobs, on_trial=display.trial,
                                     poll=feed.poll if display.enabled else None, run=run_tagged))
    try:
        with contextlib.closing(outcomes):  # on an interrupt, stop the workers at once
            for k, outcome in outcomes:
                protocol, out = runs[k]
                save_outcome(out, outcome)
                key = (k, outcome["algorithm"], outcome["index"])
                feed.finished(key)
                display.experiment(key, outcome["returns"])
                clocks[k].record(experiments=1)
                left[k] -= 1
                if left[k] == 0:
                    summaries[k] = finalise(out, protocol, optimal=optimal, figures=figures,
                                            floor=floor, clock=clocks[k], smooth=smooth)
    finally:
        display.close()
    return [summary if summary is not None else
            finalise(out, protocol, optimal=optimal, figures=figures, floor=floor, clock=clock,
                     smooth=smooth)
            for summary, (protocol, out), clock in zip(summaries, runs, clocks)]


def finalise(out: pathlib.Path, protocol: Protocol, wall_time_s: float | None = None,
             optimal: Callable[[Protocol], float | None] | None = None,
             figures: bool = True, clock: _WallClock | None = None, smooth: int = 1,
             floor: Callable[[Protocol, str], float | None] | None = None) -> dict[str, Any]:
    """Summarise the finished curves in ``out``: returns.csv, Fig. 2, then summary.json.

    The wall time in the summary is ``wall_time_s``, or with ``clock`` the total over every part of
    the run up to the end of the figures (``wall_time_parts_s`` lists the parts). ``floor`` gives
    each learner's exploration floor (or None).
    """
    optimal_return = optimal(protocol) if optimal is not None else None
    floors = {a: floor(protocol, a) for a in protocol.algorithms} if floor is not None else {}
    shared_floor = set(floors.values())  # one line in Fig. 2 when every learner explores alike
    seconds = trial_seconds(make_environment(protocol))
    summary: dict[str, Any] = {"paper_protocol": protocol.is_paper_protocol,
                               "optimal_return": optimal_return,
                               "exploration_floor": shared_floor.pop() if len(shared_floor) == 1
                               else None,
                               "trial_seconds": seconds,
                               "protocol": protocol.as_dict()}
    rows = []
    for algorithm in protocol.algorithms:
        returns, greedy, greedy_trials, wall = load_curves(out, protocol, algorithm)
        summary[algorithm] = results.summarise(returns, greedy, greedy_trials, optimal_return,
                                               trial_seconds=seconds)
        summary[algorithm]["experiment_wall_s_mean"] = float(wall.mean())
        summary[algorithm]["exploration_floor"] = floors.get(algorithm)
        rows.extend((algorithm, i, t + 1, float(r)) for i, curve in enumerate(returns)
                    for t, r in enumerate(curve))
    summary["final_return_tests"] = results.compare_final_returns(
        {a: summary[a]["final_return_per_experiment"] for a in protocol.algorithms})

    results.write_csv(out / "returns.csv", ["algorithm", "experiment", "trial", "return"], rows)
    if figures:
        from rmac_mj.experiments import plots
        plots.plot_learning_curves({out.name or str(out): summary}, out / "fig2_learning_curves",
                                   optimal_return=optimal_return, smooth=smooth,
                                   exploration_floor=summary["exploration_floor"])
    if clock is not None:
        clock.record()
        summary["wall_time_s"] = sum(clock.parts)
        summary["wall_time_parts_s"] = clock.parts
    elif wall_time_s is not None:
        summary["wall_time_s"] = wall_time_s
    results.write_json(out / "summary.json", summary)
    return summary


def summary_table(summary: dict[str, Any], algorithms: Iterable[str] | None = None) -> str:
    """The end-of-run table: one row per learner, then whether their final returns differ
    significantly, and a warning when too few experiments make the intervals meaningless."""
    algorithms = [a for a in (algorithms or ALGORITHMS) if a in summary]
    header = (f"{'learner':>8} {'experiments':>11} {'final return':>13} {'95% CI':>19} "
              f"{'min to 90%':>10} {'first 10 min':>12} {'stuck':>5}")
    lines = [header, "-" * len(header)]
    for algorithm in algorithms:
        row = summary[algorithm]
        low, high = row["final_return_ci95"]
        ci = f"[{low:.0f}, {high:.0f}]" if low is not None else "n/a"
        stuck = "n/a" if row.get("stuck_experiments") is None else str(row["stuck_experiments"])
        lines.append(f"{algorithm:>8} {row['experiments']:>11d} {row['final_return_mean']:>13.1f} "
                     f"{ci:>19} {row['minutes_to_90pct']:>10.1f} "
                     f"{row['mean_return_first_10min']:>12.1f} {stuck:>5}")
    if summary.get("optimal_return") is not None:
        lines.append(f"near-optimal return: {summary['optimal_return']:.1f}")
    if summary.get("trial_seconds") is not None:
        lines.append(f"one trial = {summary['trial_seconds']:g} s of simulated time")
    tests = results.compare_final_returns(
        {a: summary[a]["final_return_per_experiment"] for a in algorithms
         if "final_return_per_experiment" in summary[a]})
    lines.extend(results.describe_test(test) for test in tests)
    fewest = min((summary[a]["experiments"] for a in algorithms), default=None)
    if fewest is not None and fewest < results.FEW_EXPERIMENTS:
        lines.append(results.few_experiments_note(fewest))
    return "\n".join(lines)
