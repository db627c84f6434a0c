"""The driver: run protocols into result directories, experiments in parallel, then summarise.

Experiments run in workers or on Dask (:mod:`~rmac_mj.experiments.execution`) and are saved as they
arrive (:class:`~rmac_mj.results.store.ResultStore`), so ``resume`` finishes an interrupted run with
identical results; a finished run is summarised against its near-optimal return
(:mod:`~rmac_mj.experiments.near_optimal_service`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import functools
import itertools
import json
import os
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any

import numpy as np

from rmac_mj.evaluation import metrics
from rmac_mj.experiments import admission, execution
from rmac_mj.experiments import prior_transitions as prior_data
from rmac_mj.experiments.experiment import fresh_learners
from rmac_mj.experiments.experiment_loop import ExperimentSpec, run_experiment
from rmac_mj.experiments.near_optimal_service import NearOptimal, NearOptimalService, near_optimal
from rmac_mj.experiments.progress import Progress, TrialFeed
from rmac_mj.experiments.protocol import Protocol
from rmac_mj.results import files
from rmac_mj.results.records import ExperimentResult
from rmac_mj.results.snapshots import snapshot_state_problem
from rmac_mj.results.store import ResultStore


@dataclasses.dataclass(frozen=True)
class RunOptions:
    """How protocols are run (:func:`run_protocol`, :func:`run_protocols`), the same for each.

    Args:
      jobs: local worker processes (default: the machine's cores); ignored with ``scheduler``.
      resume: finish the run in each directory (same settings; more experiments may be added).
      scheduler: address of a Dask distributed scheduler to run the experiments on instead.
      progress: show progress (bars on a terminal, periodic plain lines otherwise) on stderr: the
        trials done overall and per learner, with each learner's recent mean return.
      references: ask the task for its near-optimal return and each learner's exploration floor
        (``optimum.run_optimum``, ``run_exploration_floor``; computed once, about 30 s of CPU
        on the paper's pendulum, then cached) for the summary and Fig. 2 (the command line's default; off here).
      figures: draw Fig. 2 and the performance profiles of each finished run.
      log: called with a one-line message before anything slow that shows no progress (compiling the
        kernels the first time); None says nothing.
      started: ``time.perf_counter()`` when the caller started (default: when the run starts); the
        wall time in the summary counts from there, summed over every part of a resumed run.
      smooth: Fig. 2's running mean, in trials (1: none).
    """

    jobs: int | None = None
    resume: bool = False
    scheduler: str | None = None
    progress: bool = True
    references: bool = False
    figures: bool = True
    log: Callable[[str], None] | None = None
    started: float | None = None
    smooth: int = 1

    def __post_init__(self):
        if self.jobs is not None and self.jobs < 1:
            raise ValueError(f"jobs must be a positive integer, got {self.jobs!r}")

    @property
    def workers(self) -> int:
        """The local worker processes: ``jobs``, or the machine's cores."""
        return (os.cpu_count() or 1) if self.jobs is None else self.jobs


class WallClock:
    """The wall time of this part of a run, counted from ``started`` (the process's start: compilation,
    the near-optimal return and the figures included), kept in ``wall_times.json`` beside the earlier
    parts, so that a resumed run reports the total over all of them. It is written after every saved
    experiment; a killed part loses only the time since its last one."""

    def __init__(self, store: ResultStore, started: float, resume: bool):
        self.store = store
        self.started = started
        self.earlier: list[dict[str, Any]] = store.read_wall_times() if resume else []
        self.part = {
            "started": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "wall_s": 0.0,
            "experiments": 0,
        }

    def record(self, experiments: int = 0) -> None:
        self.part["wall_s"] = time.perf_counter() - self.started
        self.part["experiments"] += experiments
        self.store.write_wall_times([*self.earlier, self.part])

    @property
    def parts(self) -> list[float]:
        return [float(part.get("wall_s", 0.0)) for part in [*self.earlier, self.part]]


def finished_experiments(out: str | os.PathLike, protocol: Protocol) -> int:
    """How many of ``protocol``'s experiments have their results in ``out``."""
    store = ResultStore(out)
    return sum(
        sum(1 for i in store.finished(a) if i < protocol.experiments) for a in protocol.algorithms
    )


def run_tagged(
    item: tuple[Any, ExperimentSpec], on_trial: Callable[..., None] | None = None
) -> tuple[Any, ExperimentResult]:
    """``(tag, run_experiment(spec))`` for ``item = (tag, spec)``: lets one pool serve several runs.
    ``on_trial`` is called as ``on_trial((tag, algorithm, index), trial, return, env_steps)``."""
    tag, spec = item

    def report(algorithm: str, index: int, trial: int, value: float, env_steps: int) -> None:
        on_trial((tag, algorithm, index), trial, value, env_steps)

    return tag, run_experiment(spec, report if on_trial is not None else None)


class _Run:
    """One protocol being run into one directory. It is begun (its directory locked, checked or made,
    its config written, on a resume its saved experiments checked) before its first experiment
    starts: at once when the directory exists, else when its first experiment is handed out."""

    def __init__(
        self,
        protocol: Protocol,
        out: str | os.PathLike,
        document: dict[str, Any],
        demonstration: prior_data.Demonstration | None,
        resume: bool,
    ):
        self.protocol, self.store = protocol, ResultStore(out)
        self.document, self.demonstration, self.resume = document, demonstration, resume
        self.finished: dict[str, set[int]] = {a: set() for a in protocol.algorithms}
        self.clock: WallClock | None = None
        self.summary: dict[str, Any] | None = None

    @property
    def begun(self) -> bool:
        return self.clock is not None

    def begin(self, started: float, log: Callable[[str], None] | None) -> None:
        """Lock the directory, write or check its config and, resuming, trust only the saved
        experiments whose files are whole and agree with the config (the others run again)."""
        if self.begun:
            return
        self.store.lock().acquire()
        self.store.begin(self.document, self.resume)
        protocol = self.protocol
        learners = None  # built once, when a saved experiment is to be checked
        for algorithm in protocol.algorithms:
            for index in sorted(
                i for i in self.store.finished(algorithm) if i < protocol.experiments
            ):
                if learners is None:
                    learners = fresh_learners(protocol)
                problem = self.store.experiment_problem(
                    protocol,
                    algorithm,
                    index,
                    functools.partial(snapshot_state_problem, learner=learners[algorithm]),
                )
                if problem is None:
                    self.finished[algorithm].add(index)
                    continue
                if log is not None:
                    log(f"{algorithm} experiment {index} is run again: {problem}")
                self.store.discard(algorithm, index)
        self.clock = WallClock(self.store, started, self.resume)

    @property
    def left(self) -> int:
        return sum(
            self.protocol.experiments - len(self.finished[a]) for a in self.protocol.algorithms
        )

    def pending(self, tag: int, stream: bool) -> Iterator[tuple[int, ExperimentSpec]]:
        """The experiments not yet saved, drawn one at a time (experiment-major, as their seeds)."""
        stream_to = str(self.store.root) if stream else None
        for index in range(self.protocol.experiments):
            for algorithm in self.protocol.algorithms:
                if index not in self.finished[algorithm]:
                    yield (
                        tag,
                        ExperimentSpec(
                            self.protocol,
                            algorithm,
                            index,
                            stream_to=stream_to,
                            demonstration=self.demonstration,
                        ),
                    )

    def save(self, result: ExperimentResult) -> None:
        """Save a finished experiment and count it in the run's wall time."""
        self.store.save(result)
        self.finished[result.algorithm].add(result.index)
        self.clock.record(experiments=1)

    def finalise(
        self, options: RunOptions, facts: admission.TaskFacts, computed: NearOptimal | None
    ) -> dict[str, Any]:
        """Summarise the run (:func:`finalise`) and let go of its directory."""
        self.begin(options.started, options.log)  # a run with nothing left may not be begun
        try:
            self.summary = finalise(
                self.store, self.protocol, options, clock=self.clock, facts=facts, computed=computed
            )
        finally:
            self.store.lock().release()
        return self.summary


def run_protocol(
    protocol: Protocol, out: str | os.PathLike, options: RunOptions = RunOptions()
) -> dict[str, Any]:
    """Run (or finish, with ``options.resume``) ``protocol`` into ``out``; return the summary
    document. ``options``: how (:class:`RunOptions`)."""
    return run_protocols([(protocol, out)], options)[0]


def run_protocols(
    runs: Iterable[tuple[Protocol, str | os.PathLike]], options: RunOptions = RunOptions()
) -> list[dict[str, Any]]:
    """Run several ``(protocol, out)`` pairs through ONE worker pool (or one Dask cluster).

    Each ``out`` becomes exactly what :func:`run_protocol` writes (config.json, curves, snapshots,
    summary.json, returns.csv, Fig. 2, wall_times.json) and is resumable the same way; all pending
    experiments of all runs are queued together, and a run is summarised as soon as its last
    experiment is saved. ``options`` are each run's (:class:`RunOptions`); the progress display
    sums the learners' trials over the runs. Returns each run's summary, in order.
    """
    if options.started is None:
        options = dataclasses.replace(options, started=time.perf_counter())
    facts = admission.TaskFacts()
    state = _admitted(runs, options, facts)
    client = execution.connect_dask(options.scheduler) if options.scheduler else None
    # With one local process (--jobs 1) the run uses one core: the references wait for the end.
    service = NearOptimalService(
        [run.protocol if options.references else None for run in state],
        options.log,
        background=options.references and (client is not None or options.workers > 1),
    )
    try:
        for (
            run
        ) in state:  # what exists is begun now: locked, checked (a sweep's others as they start)
            if run.store.root.exists() and any(run.store.root.iterdir()):
                run.begin(options.started, options.log)
        return _run_all(state, client, options, service, facts)
    finally:
        service.close()
        for run in state:
            run.store.lock().release()
        if client is not None:
            client.close()


def _admitted(
    runs: Iterable[tuple[Protocol, str | os.PathLike]],
    options: RunOptions,
    facts: admission.TaskFacts,
) -> list[_Run]:
    """Each run checked before anything runs (its prior file read, the memory it needs) with the
    config document its directory is to hold."""
    code, state = files.code_version(), []
    resolved: dict[str, dict[str, Any]] = {}
    for protocol, out in runs:
        demonstration, prior_sha256 = admission.read_prior_file(protocol, facts)
        planned = sum(protocol.experiments for _ in protocol.algorithms)
        workers = 1 if options.scheduler else min(options.workers, planned)
        admission.check_memory([protocol], workers, facts)
        key = json.dumps(protocol.as_dict(), sort_keys=True)
        if key not in resolved:
            resolved[key] = admission.resolve_agents(protocol, facts)
        document = {
            "protocol": protocol.as_dict(),
            "code": code,
            "agents": resolved[key],
            "references": options.references,
        }  # a resume computes them only if the run did
        if prior_sha256 is not None:
            document["prior_sha256"] = prior_sha256
        if protocol.environment_origin is not None:  # a resume must run on the same environment
            document["environment_origin"] = protocol.environment_origin
        _keep_measured_bounds(protocol, document, options.log)
        state.append(_Run(protocol, out, document, demonstration, options.resume))
    return state


def _keep_measured_bounds(
    protocol: Protocol, document: dict[str, Any], log: Callable[[str], None] | None
) -> None:
    """What the run chose where the specs say nothing: said once, kept in config.json."""
    measured = protocol.measured_bounds
    if not measured:
        return
    document["measured_bounds"] = measured
    if log is not None:
        log(
            f"{protocol.environment_name}: no bounds in the specs for "
            f"{', '.join(measured)}; measured from random actions ("
            + ", ".join(f"{k} [{lo:.3g}, {hi:.3g}]" for k, (lo, hi) in measured.items())
            + "; choose them with --learner-state or a [learner_state] table)"
        )


def _run_all(
    state: list[_Run],
    client,
    options: RunOptions,
    service: NearOptimalService,
    facts: admission.TaskFacts,
) -> list[dict[str, Any]]:
    """Every pending experiment of every run, through one pool or cluster; each run summarised as
    soon as its last experiment is saved."""
    busy = [run for run in state if run.left]
    compiles = None  # or left to the workers: each learner's experiments after its own compile
    if busy and client is None:
        compiles = admission.warm_up_announced(
            [run.protocol for run in busy],
            options.log,
            jobs=options.workers,
            learner_of=lambda item: (item[1].protocol, item[1].algorithm),
        )
    display = Progress(
        [run.protocol for run in state],
        [{a: len(run.finished[a]) for a in run.finished} for run in state],
        options.progress and bool(busy),
    )
    feed = TrialFeed(display)
    outcomes = _outcomes(state, client, options, display, feed, compiles)
    try:
        with contextlib.closing(outcomes):  # on an interrupt, stop the workers at once
            for k, result in outcomes:
                run = state[k]
                run.save(result)
                key = (k, result.algorithm, result.index)
                feed.finished(key)
                display.experiment(key, result.returns)
                if not run.left:
                    run.finalise(options, facts, service.result(k))
    finally:
        display.close()
    return [
        run.summary if run.summary is not None else run.finalise(options, facts, service.result(k))
        for k, run in enumerate(state)
    ]


def _outcomes(
    state: list[_Run],
    client,
    options: RunOptions,
    display: Progress,
    feed: TrialFeed,
    compiles: execution.Prerequisites | None = None,
) -> Iterator[tuple[int, ExperimentResult]]:
    """The runs' pending experiments handed to local workers (``client`` None) or to Dask, as
    ``(run, result)`` in the order they finish; a run is begun as its first experiment starts, a
    learner's experiments after its ``compiles`` (local workers only)."""

    def on_start(item: tuple[int, ExperimentSpec]) -> None:
        k, spec = item
        state[k].begin(options.started, options.log)  # its directory is made as its first starts
        if spec.stream_to is not None:  # a trial log left by an interrupted run is rewritten
            path = state[k].store.progress_path(spec.algorithm, spec.index)
            path.unlink(missing_ok=True)
            feed.watch((k, spec.algorithm, spec.index), path)

    # the workers stream their trials to progress/ (a Dask worker may not see the directory)
    local = client is None
    pending = itertools.chain.from_iterable(
        run.pending(k, stream=local) for k, run in enumerate(state)
    )
    if not local:
        return execution.dask_outcomes(pending, run_tagged, client, on_start=on_start)
    return execution.local_outcomes(
        pending,
        run_tagged,
        options.workers,
        on_trial=display.trial,
        poll=feed.poll if display.enabled else None,
        on_start=on_start,
        prerequisites=compiles,
    )


def finalise(
    store: ResultStore,
    protocol: Protocol,
    options: RunOptions = RunOptions(),
    clock: WallClock | None = None,
    facts: admission.TaskFacts | None = None,
    computed: NearOptimal | None = None,
) -> dict[str, Any]:
    """Summarise the finished curves in ``store``: returns.csv, Fig. 2, then summary.json.

    The wall time in the summary is, with ``clock``, the total over every part of the run up to the
    end of the figures (``wall_time_parts_s`` lists the parts); ``facts`` are the tasks' facts
    already asked (:class:`admission.TaskFacts`). With ``options.references``, the task's
    near-optimal reference and each learner's exploration floor are asked for (``options.log``
    hears about a first computation and its progress), unless ``computed`` gives them
    (:func:`near_optimal`); ``options.figures`` and ``options.smooth`` say what is drawn.
    """
    store.summary_path.unlink(missing_ok=True)  # until the new one is written: not finished
    if computed is None and options.references:
        computed = near_optimal(protocol, options.log)
    optimal_return, floors = computed if computed is not None else (None, {})
    summary = _run_facts(protocol, optimal_return, floors, facts or admission.TaskFacts())
    rows = []
    for algorithm in protocol.algorithms:
        curves = store.load_curves(algorithm, protocol.experiments)
        summary[algorithm] = metrics.summarise(
            curves.returns,
            curves.greedy_returns,
            curves.greedy_trials,
            optimal_return,
            trial_seconds=summary["trial_seconds"],
            wall_times=curves.wall_times,
            cpu_times=curves.cpu_times,
            env_steps=curves.env_steps,
            env_step_seconds=summary["env_step_seconds"],
        ).as_dict()
        summary[algorithm]["exploration_floor"] = floors.get(algorithm)
        rows.extend(_return_rows(algorithm, curves))
    finals = {a: summary[a]["final_return_per_experiment"] for a in protocol.algorithms}
    summary["final_return_tests"] = metrics.compare_final_returns(finals)
    summary["probability_of_improvement"] = metrics.improvement(finals)
    store.write_returns(rows)
    if options.figures:
        _draw_figures(store, summary, finals, options.smooth)
    if clock is not None:
        clock.record()
        summary["wall_time_s"] = sum(clock.parts)
        summary["wall_time_parts_s"] = clock.parts
    store.write_summary(summary)
    return summary


def _run_facts(
    protocol: Protocol, optimal_return: float | None, floors: dict, facts: admission.TaskFacts
) -> dict[str, Any]:
    """The summary's entries about the run as a whole: the protocol, the task's reference and
    floor, its timing and the learners' state."""
    shared_floor = set(floors.values())  # one line in Fig. 2 when every learner explores alike
    return {
        "paper_protocol": protocol.is_paper_protocol,
        "optimal_return": optimal_return,
        "exploration_floor": shared_floor.pop() if len(shared_floor) == 1 else None,
        "trial_seconds": facts.trial_seconds(protocol),
        "env_step_seconds": facts.env_step_seconds(protocol),
        "plot_hints": dataclasses.asdict(protocol.knowledge.plot_hints),
        # What x was (inferred, for an outside environment): its provenance.
        "learner_state": dataclasses.asdict(facts.learner_state(protocol)),
        "protocol": protocol.as_dict(),
    }


def _return_rows(algorithm: str, curves) -> Iterator[tuple]:
    """returns.csv's rows of one learner: (algorithm, experiment, trial, return, env steps)."""
    return (
        (algorithm, i, t + 1, float(r), "" if not np.isfinite(n) else int(n))
        for i, (curve, counted) in enumerate(zip(curves.returns, curves.env_steps))
        for t, (r, n) in enumerate(zip(curve, counted))
        if np.isfinite(r)
    )


def _draw_figures(
    store: ResultStore, summary: dict[str, Any], finals: dict[str, Any], smooth: int
) -> None:
    """Fig. 2 (the learning curves) and the performance profiles of the finished run."""
    from rmac_mj.figures import plots

    plots.plot_learning_curves(
        {store.root.name or str(store.root): summary},
        store.figure_stem,
        optimal_return=summary["optimal_return"],
        smooth=smooth,
        exploration_floor=summary["exploration_floor"],
    )
    plots.plot_performance_profiles({("", a): finals[a] for a in finals}, store.profiles_stem)
