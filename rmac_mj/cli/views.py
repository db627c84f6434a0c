"""The commands that look at results, the task's reference or the code's speed: ``compare``,
``policy``, ``render``, ``optimal``, ``bench``."""

from __future__ import annotations

import json
import os
import pathlib
from collections.abc import Sequence

from rmac_mj.cli.arguments import UsageError, say, user_input


def shortest_distinct_suffixes(paths: Sequence[pathlib.Path]) -> list[str]:
    """Each path's shortest trailing run of components that no other (different) path ends with:
    ``a/run`` and ``b/run`` stay ``a/run`` and ``b/run``; ``x/ten`` and ``y/oldest`` become ``ten``
    and ``oldest``."""
    parts = [pathlib.Path(p).resolve().parts for p in paths]
    labels = []
    for mine in parts:
        others = [theirs for theirs in parts if theirs != mine]
        for k in range(1, len(mine) + 1):
            if all(theirs[-k:] != mine[-k:] for theirs in others):
                break
        labels.append(str(pathlib.PurePath(*mine[-k:])))
    return labels


def _settings_line(summary: dict) -> str:
    """How a run was made: its size in the units it was budgeted in (a budget of environment
    steps with the trials and steps each learner ran), seed and --set overrides."""
    from rmac_mj.agents import ALGORITHMS
    from rmac_mj.evaluation import report
    from rmac_mj.sweeps.bounded_toml import flatten

    protocol = summary.get("protocol", {})
    overrides = [
        f"{key}={json.dumps(value)}"
        for key, value in flatten(protocol.get("agent_configs") or {}).items()
    ]
    experiments = protocol.get("experiments", "?")
    if protocol.get("steps") is not None:
        learners = [a for a in ALGORITHMS if a in summary]
        size = (
            f"{experiments} experiments of {protocol['steps']} env steps (at most "
            f"{protocol.get('trials', '?')} trials; ran: {report.what_ran(summary, learners)})"
        )
    else:
        size = f"{experiments} experiments of {protocol.get('trials', '?')} trials"
    text = f"{size}, seed {protocol.get('seed', '?')}"
    return text + ("; --set " + " ".join(overrides) if overrides else "; default hyperparameters")


def _say_missing_learners(path, summary: dict) -> None:
    """Say, one line per learner, which learners the run lists but its summary holds no results
    for (they are left out of the figures and tables). A summary that holds none is refused when it
    is read (:class:`~rmac_mj.results.store.ResultStore`)."""
    protocol = summary.get("protocol")
    listed = protocol.get("algorithms") if isinstance(protocol, dict) else None
    if not isinstance(listed, list):
        return
    missing = [a for a in listed if a not in summary]
    for algorithm in missing:
        say(f"{path} has no results for {algorithm}, which its run lists: shown without it")


#: The figure formats ``compare`` writes; ``--out`` may end in one of them.
FIGURE_SUFFIXES = (".png", ".pdf")


def compare_figure_stems(out: str | None, first: pathlib.Path) -> tuple[pathlib.Path, pathlib.Path]:
    """The paths, without suffix, of compare's two figures: the learning curves and the
    performance profiles (``STEM`` and ``STEM_profiles``, each as .png and .pdf).

    ``out`` (``--out``): None, ``compare`` in ``first``, the first directory given; a folder (one
    that exists, or a path ending in ``/``), ``compare`` in it; a path ending in .png or .pdf, that
    path's stem; any other path, taken as the stem. UsageError for another suffix, which would be
    replaced."""
    if out is None:
        folder, stem = first, "compare"
    elif out.endswith(("/", os.sep)) or pathlib.Path(out).is_dir():
        folder, stem = pathlib.Path(out), "compare"
    else:
        path = pathlib.Path(out)
        if path.suffix and path.suffix.lower() not in FIGURE_SUFFIXES:
            raise UsageError(
                f"--out {out}: compare writes .png and .pdf figures; give a folder, a path "
                f"without suffix, or one ending in {' or '.join(FIGURE_SUFFIXES)}"
            )
        folder, stem = path.parent, path.stem
    return folder / stem, folder / f"{stem}_profiles"


def _task_of(summary: dict) -> str | None:
    """The task a run's summary is of, as people read it: its environment, the task's arguments
    and the trial's length (``dc_pendulum/swingup, 3 s trials``); None for a summary too old to
    say."""
    protocol = summary.get("protocol")
    if not isinstance(protocol, dict) or not ("env" in protocol or "domain" in protocol):
        return None
    name = protocol.get("env") or f"{protocol.get('domain')}/{protocol.get('task')}"
    arguments = protocol.get("task_kwargs") or {}
    seconds = summary.get("trial_seconds")
    return (
        name
        + (f" {json.dumps(arguments, sort_keys=True)}" if arguments else "")
        + (f", {seconds:g} s trials" if isinstance(seconds, (int, float)) else "")
    )


def _one_task(summaries: dict[str, dict]) -> None:
    """Refuse, naming each run's task, runs of different tasks: their returns do not compare."""
    tasks = {label: _task_of(summary) for label, summary in summaries.items()}
    if len({task for task in tasks.values() if task is not None}) > 1:
        shown = "; ".join(f"{label}: {task}" for label, task in tasks.items() if task is not None)
        raise UsageError(
            f"the runs are of different tasks ({shown}): their returns do not compare; "
            "compare runs of one task"
        )


def compare(args) -> int:
    from rmac_mj.agents import ALGORITHMS
    from rmac_mj.evaluation import report
    from rmac_mj.figures import plots
    from rmac_mj.results.store import ResultStore

    directories = []
    for directory in args.dirs:
        if any(directory.resolve() == seen.resolve() for seen in directories):
            say(f"{directory} is given twice; it is shown once")
            continue
        directories.append(directory)
    out, profiles_out = compare_figure_stems(args.out, directories[0])
    summaries = {}
    for directory, label in zip(directories, shortest_distinct_suffixes(directories)):
        store = ResultStore(directory)
        summaries[label] = store.read_summary()
        if "trial_seconds" not in summaries[label]:
            raise UsageError(f"{store.summary_path} has no trial_seconds (the task's trial length)")
        _say_missing_learners(store.summary_path, summaries[label])
    _one_task(summaries)
    optimal = next(
        (s["optimal_return"] for s in summaries.values() if s.get("optimal_return")), None
    )
    floors = {s.get("exploration_floor") for s in summaries.values()}
    try:
        paths = plots.plot_learning_curves(
            summaries,
            out,
            optimal_return=optimal,
            smooth=args.smooth,
            x_axis=args.x_axis.replace("-", "_"),
            exploration_floor=floors.pop() if len(floors) == 1 else None,
        )
    except ValueError as error:  # e.g. env-steps of a run written before they were counted
        raise UsageError(str(error)) from None
    for label, summary in summaries.items():
        print(f"== {label}: {_settings_line(summary)}")
        print(report.summary_table(summary))
    if len(summaries) > 1:
        print("== across the runs")
        print("\n".join(report.across_runs(summaries)))
    paths += plots.plot_performance_profiles(
        {
            (label, a): s[a]["final_return_per_experiment"]
            for label, s in summaries.items()
            for a in ALGORITHMS
            if a in s and "final_return_per_experiment" in s[a]
        },
        profiles_out,
    )
    print("figures:", ", ".join(map(str, paths)))
    return 0


def _declared_labels(learner_state, meta: dict):
    """``learner_state`` with the axis labels the snapshot's run declared for the same state (an
    environment given again by --env has its state inferred: "observation[2]" for a declared
    "speed [rad/s]")."""
    import dataclasses

    declared = (meta.get("environment") or {}).get("learner_state") or {}
    if list(declared.get("keys") or []) == list(learner_state.keys) and len(
        declared.get("labels") or []
    ) == len(learner_state.labels):
        return dataclasses.replace(
            learner_state,
            labels=tuple(declared["labels"]),
            action_labels=tuple(declared.get("action_labels") or learner_state.action_labels),
        )
    return learner_state


def _load_snapshots(args) -> tuple[list[tuple], list]:
    """``args.snapshots`` loaded, each as (agent, meta), and each one's environment."""
    from rmac_mj.results.snapshots import load_snapshot, snapshot_environment

    snapshots, envs = [], []
    for path in args.snapshots:
        with user_input(f"{path}: "):
            agent, meta = load_snapshot(path)
        snapshots.append((agent, meta))
        envs.append(
            snapshot_environment(
                agent,
                meta,
                args.domain,
                args.task,
                args.env,
                trust_env=args.trust_env,
                log=say,
            )
        )
    return snapshots, envs


def _shared_learner_state(args, snapshots: list[tuple], envs: list):
    """The learner state every snapshot learned on, labelled as the first declares it; UsageError
    where they differ."""
    from rmac_mj.rollout import learner_state_of

    learner_state = _declared_labels(learner_state_of(envs[0]), snapshots[0][1])
    for path, env in zip(args.snapshots[1:], envs[1:]):
        if learner_state_of(env) != learner_state:
            raise UsageError(
                f"{path} learned on another state ({learner_state_of(env).labels}) than "
                f"{args.snapshots[0]} ({learner_state.labels}); draw them one by one"
            )
    return learner_state


def _map_view(args, learner_state, env):
    """What the maps show (a ``MapView``): the state they slice through (--at, else the start
    state), the two dimensions on their axes (--dims), those dimensions' given ranges (--xlim,
    --ylim) and the grid (--resolution)."""
    from rmac_mj.figures.policy_plots import MapView
    from rmac_mj.rollout import state_of

    n = len(learner_state.low)
    if args.at is not None:
        if len(args.at) != n:
            raise UsageError(f"--at needs {n} numbers (the state's dimensions), got {len(args.at)}")
        anchor = args.at
    else:
        anchor = state_of(env.reset().observation, learner_state)
    if n < 2:
        raise UsageError(f"policy maps need at least two state dimensions; the state has {n}")
    i, j = args.dims
    if not (0 <= i < n and 0 <= j < n and i != j):
        raise UsageError(
            f"--dims must name two different state dimensions in [0, {n}), got {i},{j}"
        )
    limits = {d: lim for d, lim in ((i, args.xlim), (j, args.ylim)) if lim is not None}
    for option, lim in (("--xlim", args.xlim), ("--ylim", args.ylim)):
        if lim is not None and not lim[0] < lim[1]:
            raise UsageError(f"{option} needs LO < HI, got {lim[0]:g},{lim[1]:g}")
    return MapView(anchor, (i, j), limits, args.resolution)


def policy(args) -> int:
    from rmac_mj.figures import policy_plots

    snapshots, envs = _load_snapshots(args)
    learner_state = _shared_learner_state(args, snapshots, envs)
    view = _map_view(args, learner_state, envs[0])
    first = args.snapshots[0]
    stem = args.out or first.with_name(
        first.stem + ("_policy" if len(snapshots) == 1 else "_policies")
    )
    paths = policy_plots.plot_policies(
        snapshots, stem, learner_state, view, envs=None if args.no_trajectory else envs
    )
    print("figure:", ", ".join(map(str, paths)))
    return 0


def optimal(args) -> int:
    from rmac_mj.agents import Exploration
    from rmac_mj.solvers import optimum

    if args.env is not None:
        from rmac_mj import tasks

        having = ", ".join(f"{d}/{t}" for d, t in tasks.ALL_TASKS if optimum.has_optimum(d, t))
        raise UsageError(
            f"no near-optimal return for {args.env}: an outside environment declares "
            f"none (the suite's tasks that do: {having})"
        )
    with user_input():
        if not optimum.has_optimum(args.domain, args.task):
            optimum.optimum_result(args.domain, args.task)  # raises, naming the tasks that have one
    result = optimum.optimum_result(args.domain, args.task, refresh=args.refresh, announce=say)
    print(result.describe())
    from rmac_mj import tasks
    from rmac_mj.agents.task_knowledge import with_task_units
    from rmac_mj.rollout import action_space_of, state_space_of

    env = tasks.load(args.domain, args.task)
    # The learners' default exploration (section 6.1), in the task's action range.
    paper = with_task_units(Exploration(), state_space_of(env), action_space_of(env))
    floor = optimum.exploration_floor(
        args.domain,
        args.task,
        paper.sigma,
        paper.period,
        paper.phase,
        refresh=args.refresh,
        announce=say,
    )
    if floor is not None:  # a reference with a policy to explore with (the dynamic programme)
        print(floor.describe())
    return 0


def render(args) -> int:
    chosen = [x for x in (args.snapshot, args.progression, args.compare) if x is not None]
    if len(chosen) != 1:
        raise UsageError("give exactly one of SNAPSHOT, --progression DIR or --compare DIR")
    from rmac_mj.videos import result_videos

    options = result_videos.VideoOptions(
        width=args.width,
        height=args.height,
        overlay=not args.no_overlay,
        frames_per_step=args.frames_per_step,
        env=args.env,
        trust_env=args.trust_env,
        log=say,
    )
    if args.snapshot is not None:
        path = result_videos.render_snapshot(
            args.snapshot, args.out, options, domain=args.domain, task=args.task
        )
    elif args.domain is not None or args.task is not None:
        raise UsageError("--domain/--task apply to a single SNAPSHOT only")
    elif args.progression is not None:
        path = result_videos.render_progression(
            args.progression, args.out, experiment=args.experiment, options=options
        )
    else:
        path = result_videos.render_comparison(
            args.compare, args.out, experiment=args.experiment, options=options
        )
    print("video:", path)
    return 0


def bench(args) -> int:
    from rmac_mj.bench import bench

    if args.cold:
        from rmac_mj.bench import cold_start

        report = cold_start.run(quick=not args.quick, domain=args.domain, task=args.task)
        print(cold_start.format_table(report))
        if args.json:
            from rmac_mj.results.files import write_json

            write_json(args.json, report)
            print("json:", args.json)
        return 0

    where = (
        {"domain": args.domain, "task": args.task}
        if args.env is None
        else {
            "domain": args.domain,
            "task": args.task,
            "env": args.env,
            "learner_state": args.learner_state,
            "action_repeat": args.action_repeat,
        }
    )
    with user_input():
        bench.check_task(**where)
    report = bench.run(quick=args.quick, **where)
    print(bench.format_markdown(report) if args.markdown else bench.format_table(report))
    if args.json:
        from rmac_mj.results.files import write_json

        write_json(args.json, report)
        print("json:", args.json)
    return 0
