"""The paper's comparison (section 6): learning experiments of consecutive trials, run in parallel.

A *learning experiment* is one agent learning for ``trials`` consecutive trials of a task (the paper's:
3 s swing-ups of ``dc_pendulum`` from [pi, 0]; any registered ``domain``/``task`` runs the same way, its
trial length read from the environment); the protocol repeats it ``experiments`` times per algorithm with independent seeds. Experiments are
independent, so they run in worker processes (``jobs``) or on a Dask cluster (``scheduler``); each
worker returns its results and the driver writes them atomically as they arrive, so an interrupted run
loses only the experiments in flight and ``resume`` finishes the rest with identical results.

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

import contextlib
import csv
import dataclasses
import hashlib
import json
import multiprocessing
import os
import pathlib
import signal
import time
from typing import Any, Callable, Iterable, Iterator

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
      snapshot_trials: after which trials the agent is saved (the final one always is).
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
        object.__setattr__(self, "snapshot_trials", tuple(int(t) for t in self.snapshot_trials))
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
    """One learning experiment: ``algorithm`` number ``index`` of ``protocol``; ``demonstration``:
    the recorded prior knowledge when ``protocol.prior`` is a file (read once by the driver)."""

    protocol: Protocol
    algorithm: str
    index: int
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


def run_experiment(spec: ExperimentSpec) -> dict[str, Any]:
    """Run one learning experiment; return its curve, greedy evaluations and snapshots.

    Pure apart from the CPU: nothing is written, so it runs unchanged in a local worker process or on
    a remote Dask worker, and the caller decides where the results go.
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
    for trial in range(1, protocol.trials + 1):
        returns[trial - 1] = run_trial(env, agent, learn=True)
        if protocol.evaluate_every and trial % protocol.evaluate_every == 0:
            greedy_trials.append(trial)
            greedy_returns.append(run_trial(env, agent, learn=False))
        if trial in snapshot_trials:
            snapshots[trial] = snapshot_arrays(agent, state_space, action_space, trial=trial, **meta)
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
            raise ResumeRefused(f"{out} was written with a different config; refusing to mix results "
                                "(use another --out)")
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
    return [ExperimentSpec(protocol, algorithm, index, demonstration)
            for index in range(protocol.experiments) for algorithm in protocol.algorithms
            if not curve_path(out, algorithm, index).exists()]


def _ignore_interrupts() -> None:
    """Worker initialiser: Ctrl-C reaches the whole process group; only the driver handles it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _local_outcomes(specs: list[ExperimentSpec], jobs: int) -> Iterator[dict[str, Any]]:
    if jobs == 1 or len(specs) <= 1:
        for spec in specs:
            yield run_experiment(spec)
        return
    # "spawn": workers start clean (no inherited GL contexts or numba state); the numba cache makes
    # their start-up cheap. On an interrupt the driver terminates the workers: only the experiments
    # in flight are lost.
    context = multiprocessing.get_context("spawn")
    pool = context.Pool(processes=min(jobs, len(specs)), initializer=_ignore_interrupts)
    try:
        yield from pool.imap_unordered(run_experiment, specs, chunksize=1)
        pool.close()
    finally:
        pool.terminate()
        pool.join()


def _dask_outcomes(specs: list[ExperimentSpec], scheduler: str) -> Iterator[dict[str, Any]]:
    try:
        from distributed import Client, as_completed
    except ImportError as error:  # pragma: no cover - depends on the optional extra
        raise RuntimeError("--scheduler needs Dask: pip install 'rmac-mj[distributed]'") from error
    with Client(scheduler) as client:
        futures = [client.submit(run_experiment, spec, pure=False) for spec in specs]
        try:
            for future in as_completed(futures):
                yield future.result()
        finally:
            client.cancel(futures)


class _Progress:
    """A bar for the whole run and one per learner: experiments and trials done, trials per second,
    time left. Trials advance by whole experiments, as each one finishes."""

    def __init__(self, protocol: Protocol, done: dict[str, int], enabled: bool):
        self.trials = protocol.trials
        self.experiments = {"all": protocol.experiments * len(protocol.algorithms),
                            **{a: protocol.experiments for a in protocol.algorithms}}
        self.done = {"all": sum(done.values()), **done}
        self.bars = {}
        if not enabled:
            return
        from tqdm.auto import tqdm
        for position, key in enumerate(["all", *protocol.algorithms]):
            self.bars[key] = tqdm(total=self.experiments[key] * self.trials,
                                  initial=self.done[key] * self.trials,
                                  desc="all learners" if key == "all" else f"{key:>12}",
                                  unit="trial", position=position, dynamic_ncols=True)
            self._postfix(key)

    def _postfix(self, key: str) -> None:
        self.bars[key].set_postfix_str(f"{self.done[key]}/{self.experiments[key]} experiments")

    def update(self, algorithm: str) -> None:
        for key in ("all", algorithm):
            self.done[key] += 1
            if key in self.bars:
                self._postfix(key)
                self.bars[key].update(self.trials)

    def close(self) -> None:
        for bar in self.bars.values():
            bar.close()


def run_protocol(protocol: Protocol, out: str | os.PathLike, jobs: int | None = None,
                 resume: bool = False, scheduler: str | None = None, progress: bool = True,
                 optimal: Callable[[Protocol], float | None] | None = None,
                 figures: bool = True) -> dict[str, Any]:
    """Run (or finish, with ``resume``) ``protocol`` into ``out``; return the summary document.

    Args:
      jobs: local worker processes (default: the machine's cores); ignored with ``scheduler``.
      scheduler: address of a Dask distributed scheduler to run the experiments on instead.
      optimal: returns the near-optimal return for the summary and Fig. 2, or None.
    """
    out = pathlib.Path(out)
    jobs = (os.cpu_count() or 1) if jobs is None else jobs
    if jobs < 1:
        raise ValueError(f"jobs must be a positive integer, got {jobs!r}")
    demonstration, prior_sha256 = _read_prior_file(protocol)
    _prepare(out, protocol, resume, prior_sha256)
    pending = _pending(out, protocol, demonstration)
    done = {a: protocol.experiments - sum(s.algorithm == a for s in pending) for a in protocol.algorithms}
    bars = _Progress(protocol, done, progress and bool(pending))
    started = time.perf_counter()
    outcomes = _dask_outcomes(pending, scheduler) if scheduler else _local_outcomes(pending, jobs)
    try:
        with contextlib.closing(outcomes):  # on an interrupt, stop the workers at once
            for outcome in outcomes:
                save_outcome(out, outcome)
                bars.update(outcome["algorithm"])
    finally:
        bars.close()
    wall = time.perf_counter() - started
    return finalise(out, protocol, wall_time_s=wall, optimal=optimal, figures=figures)


def _read_prior_file(protocol: Protocol) -> tuple[prior_data.Demonstration | None, str | None]:
    """The protocol's recorded prior knowledge, checked against its task, and the file's SHA-256
    (stored in config.json, so that ``resume`` refuses a file that changed); (None, None) without."""
    path = protocol.prior_file
    if path is None:
        return None, None
    env = make_environment(protocol)
    demonstration = prior_data.load_demonstration(path, state_space_of(env), action_space_of(env))
    return demonstration, hashlib.sha256(path.read_bytes()).hexdigest()


def finalise(out: pathlib.Path, protocol: Protocol, wall_time_s: float | None = None,
             optimal: Callable[[Protocol], float | None] | None = None,
             figures: bool = True) -> dict[str, Any]:
    """Summarise the finished curves in ``out``: summary.json, returns.csv and Fig. 2."""
    optimal_return = optimal(protocol) if optimal is not None else None
    seconds = trial_seconds(make_environment(protocol))
    summary: dict[str, Any] = {"paper_protocol": protocol.is_paper_protocol,
                               "optimal_return": optimal_return,
                               "trial_seconds": seconds,
                               "protocol": protocol.as_dict()}
    rows = []
    for algorithm in protocol.algorithms:
        returns, greedy, greedy_trials, wall = load_curves(out, protocol, algorithm)
        summary[algorithm] = results.summarise(returns, greedy, greedy_trials, optimal_return,
                                               trial_seconds=seconds)
        summary[algorithm]["experiment_wall_s_mean"] = float(wall.mean())
        rows.extend((algorithm, i, t + 1, float(r)) for i, curve in enumerate(returns)
                    for t, r in enumerate(curve))
    if wall_time_s is not None:
        summary["wall_time_s"] = wall_time_s
    results.write_json(out / "summary.json", summary)

    def write_csv(handle):
        import io
        text = io.TextIOWrapper(handle, newline="", encoding="utf-8")
        writer = csv.writer(text)
        writer.writerow(["algorithm", "experiment", "trial", "return"])
        writer.writerows(rows)
        text.flush()
        text.detach()
    results.write_atomic(out / "returns.csv", write_csv)
    if figures:
        from rmac_mj.experiments import plots
        plots.plot_learning_curves({out.name or str(out): summary}, out / "fig2_learning_curves",
                                   optimal_return=optimal_return)
    return summary


def summary_table(summary: dict[str, Any], algorithms: Iterable[str] | None = None) -> str:
    """The end-of-run table: one row per learner."""
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
    return "\n".join(lines)

