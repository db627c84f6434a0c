"""The paper's comparison (section 6): learning experiments of consecutive trials, run in parallel.

A *learning experiment* is one agent learning for ``trials`` consecutive 3 s trials from [pi, 0]; the
protocol repeats it ``experiments`` times per algorithm with independent seeds. Experiments are
independent, so they run in worker processes (``jobs``) or on a Dask cluster (``scheduler``); each
worker returns its results and the driver writes them atomically as they arrive, so an interrupted run
loses only the experiments in flight and ``resume`` finishes the rest with identical results.

Seeding: experiment i of every algorithm draws its agent's stream from
``SeedSequence(seed, spawn_key=(i,))``, which equals ``SeedSequence(seed).spawn(n)[i]``, and its task's
seed from that sequence's child ``(i, 0)``. The results therefore do not depend on ``jobs``, on the
order of completion, or on resuming.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import json
import multiprocessing
import os
import pathlib
import signal
import time
from typing import Any, Callable, Iterable, Iterator

import numpy as np

from rmac_mj import tasks
from rmac_mj.agents import ALGORITHMS, config_class, config_from_dict, make_agent
from rmac_mj.errors import UserInputError
from rmac_mj.experiments import results
from rmac_mj.experiments.episode import action_space_of, run_trial, state_space_of
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
        if "random" in self.task_kwargs:
            raise ValueError("task_kwargs must not set 'random': the task's seed comes from `seed`")
        for name, overrides in self.agent_configs.items():
            if name not in ALGORITHMS:
                raise ValueError(f"agent_configs names unknown algorithm {name!r}")
            config_from_dict(config_class(name), overrides)  # raises on unknown or bad values

    @property
    def is_paper_protocol(self) -> bool:
        """True when the paper's protocol is run unchanged (both learners, default settings)."""
        default = Protocol()
        return (self.domain, self.task, self.task_kwargs, set(self.algorithms), self.experiments,
                self.trials, self.agent_configs) == (
            default.domain, default.task, default.task_kwargs, set(default.algorithms),
            default.experiments, default.trials, default.agent_configs)

    def as_dict(self) -> dict[str, Any]:
        return results.as_jsonable(self)


@dataclasses.dataclass(frozen=True)
class ExperimentSpec:
    """One learning experiment: ``algorithm`` number ``index`` of ``protocol``."""

    protocol: Protocol
    algorithm: str
    index: int


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
                      task_seed=np.int64(outcome["task_seed"]))


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


def _prepare(out: pathlib.Path, protocol: Protocol, resume: bool) -> None:
    config_file = out / "config.json"
    document = {"protocol": protocol.as_dict(), "code": results.code_version()}
    if config_file.exists():
        if not resume:
            raise ResumeRefused(f"{out} already holds a run; pass --resume to finish it, or choose "
                                "another --out")
        existing = json.loads(config_file.read_text())
        if existing.get("protocol") != document["protocol"]:
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


def _pending(out: pathlib.Path, protocol: Protocol) -> list[ExperimentSpec]:
    return [ExperimentSpec(protocol, algorithm, index)
            for index in range(protocol.experiments) for algorithm in protocol.algorithms
            if not curve_path(out, algorithm, index).exists()]


def _ignore_interrupts() -> None:
    """Worker initialiser: Ctrl-C reaches the whole process group; only the driver handles it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _local_outcomes(specs: list, jobs: int, run: Callable = run_experiment) -> Iterator:
    if jobs == 1 or len(specs) <= 1:
        for spec in specs:
            yield run(spec)
        return
    # "spawn": workers start clean (no inherited GL contexts or numba state); the numba cache makes
    # their start-up cheap. On an interrupt the driver terminates the workers: only the experiments
    # in flight are lost.
    context = multiprocessing.get_context("spawn")
    pool = context.Pool(processes=min(jobs, len(specs)), initializer=_ignore_interrupts)
    try:
        yield from pool.imap_unordered(run, specs, chunksize=1)
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
                 figures: bool = True,
                 floor: Callable[[Protocol, str], float | None] | None = None) -> dict[str, Any]:
    """Run (or finish, with ``resume``) ``protocol`` into ``out``; return the summary document.

    Args:
      jobs: local worker processes (default: the machine's cores); ignored with ``scheduler``.
      scheduler: address of a Dask distributed scheduler to run the experiments on instead.
      optimal: returns the near-optimal return for the summary and Fig. 2, or None.
      floor: returns a learner's exploration floor (the near-optimal policy's return under that
        learner's exploration) for the summary and Fig. 2, or None.
    """
    out = pathlib.Path(out)
    jobs = (os.cpu_count() or 1) if jobs is None else jobs
    if jobs < 1:
        raise ValueError(f"jobs must be a positive integer, got {jobs!r}")
    _prepare(out, protocol, resume)
    pending = _pending(out, protocol)
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
    return finalise(out, protocol, wall_time_s=wall, optimal=optimal, figures=figures, floor=floor)


def run_tagged(item: tuple[Any, ExperimentSpec]) -> tuple[Any, dict[str, Any]]:
    """``(tag, run_experiment(spec))`` for ``item = (tag, spec)``: lets one pool serve several runs."""
    tag, spec = item
    return tag, run_experiment(spec)


def run_protocols(runs: Iterable[tuple[Protocol, str | os.PathLike]], jobs: int | None = None,
                  resume: bool = False, scheduler: str | None = None, progress: bool = True,
                  optimal: Callable[[Protocol], float | None] | None = None,
                  floor: Callable[[Protocol, str], float | None] | None = None,
                  figures: bool = True) -> list[dict[str, Any]]:
    """Run several ``(protocol, out)`` pairs through ONE worker pool (or one Dask cluster).

    Each ``out`` becomes exactly what :func:`run_protocol` writes (config.json, curves, snapshots,
    summary.json, returns.csv, Fig. 2) and is resumable the same way; all pending experiments of all
    runs are queued together, and a run is summarised as soon as its last experiment is saved. The
    arguments mean what they mean for :func:`run_protocol`. Returns each run's summary, in order.
    """
    runs = [(protocol, pathlib.Path(out)) for protocol, out in runs]
    jobs = (os.cpu_count() or 1) if jobs is None else jobs
    if jobs < 1:
        raise ValueError(f"jobs must be a positive integer, got {jobs!r}")
    for protocol, out in runs:
        _prepare(out, protocol, resume)
    pending = [(k, spec) for k, (protocol, out) in enumerate(runs) for spec in _pending(out, protocol)]
    left = {k: 0 for k in range(len(runs))}
    for k, _ in pending:
        left[k] += 1
    total = sum(p.experiments * len(p.algorithms) for p, _ in runs)
    bar = None
    if progress and pending:
        from tqdm.auto import tqdm
        bar = tqdm(total=total, initial=total - len(pending), unit="experiment", dynamic_ncols=True,
                   desc=f"{len(runs)} runs")
    summaries: list[dict[str, Any] | None] = [None] * len(runs)
    outcomes = (_dask_outcomes(pending, scheduler, run_tagged) if scheduler
                else _local_outcomes(pending, jobs, run_tagged))
    try:
        with contextlib.closing(outcomes):  # on an interrupt, stop the workers at once
            for k, outcome in outcomes:
                protocol, out = runs[k]
                save_outcome(out, outcome)
                left[k] -= 1
                if bar is not None:
                    bar.update(1)
                    bar.set_postfix_str(f"{sum(n == 0 for n in left.values())}/{len(runs)} runs done")
                if left[k] == 0:
                    summaries[k] = finalise(out, protocol, optimal=optimal, figures=figures,
                                            floor=floor)
    finally:
        if bar is not None:
            bar.close()
    return [summary if summary is not None else
            finalise(out, protocol, optimal=optimal, figures=figures, floor=floor)
            for summary, (protocol, out) in zip(summaries, runs)]


def finalise(out: pathlib.Path, protocol: Protocol, wall_time_s: float | None = None,
             optimal: Callable[[Protocol], float | None] | None = None,
             figures: bool = True,
             floor: Callable[[Protocol, str], float | None] | None = None) -> dict[str, Any]:
    """Summarise the finished curves in ``out``: summary.json, returns.csv and Fig. 2."""
    optimal_return = optimal(protocol) if optimal is not None else None
    floors = {a: floor(protocol, a) for a in protocol.algorithms} if floor is not None else {}
    shared_floor = set(floors.values())  # one line in Fig. 2 when every learner explores alike
    summary: dict[str, Any] = {"paper_protocol": protocol.is_paper_protocol,
                               "optimal_return": optimal_return,
                               "exploration_floor": shared_floor.pop() if len(shared_floor) == 1
                               else None,
                               "trial_seconds": results.TRIAL_SECONDS,
                               "protocol": protocol.as_dict()}
    rows = []
    for algorithm in protocol.algorithms:
        returns, greedy, greedy_trials, wall = load_curves(out, protocol, algorithm)
        summary[algorithm] = results.summarise(returns, greedy, greedy_trials, optimal_return)
        summary[algorithm]["experiment_wall_s_mean"] = float(wall.mean())
        summary[algorithm]["exploration_floor"] = floors.get(algorithm)
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
                                   optimal_return=optimal_return,
                                   exploration_floor=summary["exploration_floor"])
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
        lines.append(f"{algorithm:>8} {row['experiments']:>11d} {row['final_return_mean']:>13.1f} "
                     f"{ci:>19} {row['minutes_to_90pct']:>10.1f} "
                     f"{row['mean_return_first_10min']:>12.1f} {row['stuck_experiments']:>5d}")
    if summary.get("optimal_return") is not None:
        lines.append(f"near-optimal return (dynamic programming): {summary['optimal_return']:.1f}")
    return "\n".join(lines)

