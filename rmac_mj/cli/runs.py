"""The commands that run experiments: ``reproduce`` (one protocol) and ``sweep`` (a grid of them)."""

from __future__ import annotations

import argparse
import json
import pathlib
from collections.abc import Sequence
from typing import Any

from rmac_mj.cli.arguments import (
    STARTED,
    Interrupted,
    UsageError,
    refuse_unwritable,
    say,
    user_input,
    writable_dir,
)
from rmac_mj.cli.run_options import PROTOCOL_OPTIONS, SWEEP_SIZE_OPTIONS
from rmac_mj.errors import UserInputError


def parse_overrides(assignments: Sequence[str]) -> dict[str, dict]:
    """``["rmac.exploration.sigma=0.5", ...]`` -> ``{"rmac": {"exploration": {"sigma": 0.5}}}``;
    a key its learner's config does not have is refused naming the closest one
    (``rmac.critic_capacity``: did you mean 'rmac.critic.capacity'?)."""
    from rmac_mj import constraints
    from rmac_mj.agents import ALGORITHMS, config_class
    from rmac_mj.sweeps.bounded_toml import nest

    flat: dict[str, Any] = {}
    for assignment in assignments:
        key, separator, text = assignment.partition("=")
        path = key.strip().split(".")
        if not separator or len(path) < 2 or not all(path):
            raise UsageError(f"--set expects ALGO.FIELD=VALUE, got {assignment!r}")
        if path[0] in ALGORITHMS:  # an unknown learner is refused with the others, by Protocol
            try:
                constraints.lookup(config_class(path[0]), path[1:], f"{path[0]}.")
            except constraints.InvalidParameterError as error:
                raise UsageError(f"--set {key.strip()}: {error}") from None
        try:
            flat[".".join(path)] = json.loads(text)
        except json.JSONDecodeError:
            flat[".".join(path)] = text  # a bare word, e.g. rate_split=actor
        except RecursionError:
            raise UsageError(f"--set {key.strip()}: its value is nested too deeply") from None
    return nest(flat)


def algorithms_to_run(args, overrides: dict[str, dict]) -> tuple[str, ...]:
    """--algorithms if given (by --config too); else the learners --set names (an ablation reruns only
    them); else the paper's learners (``Protocol``'s default)."""
    from rmac_mj.experiments.protocol import Protocol

    if args.algorithms is not None:
        return tuple(a.strip() for a in args.algorithms.split(",") if a.strip())
    if overrides:
        chosen = tuple(overrides)
        others = [a for a in Protocol().algorithms if a not in chosen]
        if others:
            say(
                f"--set names only {', '.join(chosen)}: running {'it' if len(chosen) == 1 else 'them'} "
                f"alone (give --algorithms to run {', '.join(others)} too)"
            )
        return chosen
    return Protocol().algorithms  # the paper's comparison: RMAC and S-AC


def nothing_to_resume(out: pathlib.Path, marker: str, command: str) -> UsageError:
    """The refusal of ``--resume`` where ``out`` holds no run (no ``marker`` file, written as a run
    starts): a mistyped --out must not start a fresh run of hours."""
    why = "it does not exist" if not out.exists() else f"it has no {marker}"
    return UsageError(
        f"--resume: {out} holds nothing to resume ({why}); start it with `{command}` without "
        "--resume, or give the --out of the run to finish"
    )


def resumed_environment(
    out: pathlib.Path, config: dict[str, Any], named: str | None, trust: bool
) -> None:
    """Refuse, before anything of it is imported, a resume of the run in ``out`` (its ``config``)
    on another environment than the run's. ``named`` (the command line's --env or its --config
    file's) must be the run's environment; one that is code of the user's (a module or file) runs
    only when named or ``trust``ed; and it must come from where it came from (a file's digest, a
    package's version: ``environment_origin``)."""
    from rmac_mj.envs import spec as env_spec

    env = config["protocol"].get("env")
    if env is None:
        return  # the suite's: the package's own code, of the version config.json checks
    with user_input(f"{out}/config.json: "):
        code_of_yours = env_spec.user_code(env)
    if named is not None:
        with user_input("--env: "):
            given = env_spec.canonical(named)
        if given != env:
            raise UsageError(
                f"the run in {out} ran on env {env!r}, not {given!r}: a run is one environment "
                f"(give --env {env}, or another --out)"
            )
    elif code_of_yours and not trust:
        raise UsageError(
            f"the run in {out} ran on env {env!r}, code of yours: a resume runs it only when "
            f"you name it. Add --env {env} (or --trust-env)"
        )
    problem = env_spec.origin_problem(config.get("environment_origin"), env_spec.origin(env))
    if problem is not None:
        raise UsageError(
            f"the run in {out} ran on env {env!r} as it was then, not as it is now ({problem}): "
            "a run is one environment; put it back, or start another run with another --out"
        )


def settings_from_files(argv: Sequence[str] | None, args: argparse.Namespace) -> argparse.Namespace:
    """``reproduce``'s arguments with the protocol of the directory being resumed and of the
    ``--config`` file as defaults: what the command line gives explicitly overrides them (and a
    resumed directory then refuses what differs from its run, naming it). The file's settings that
    ``reproduce`` has no option for travel in ``args.config_protocol``, its hyperparameters in
    ``args.config_agent_configs`` (``--set`` applies on top). A resumed run started with
    ``--no-optimal`` is finished without the reference too."""
    from rmac_mj.cli import build_parser
    from rmac_mj.results.store import ResultStore
    from rmac_mj.sweeps import bounded_toml, sweep_file

    layers: list[tuple[dict[str, Any], dict[str, dict]]] = []
    without_references = False
    if args.trust_env and not args.resume:
        raise UsageError(
            "--trust-env applies to --resume: the environment the directory's run names"
        )
    resumed = None
    if args.resume:
        resumed = ResultStore(args.out).read_config()
        if resumed is None:
            raise nothing_to_resume(args.out, "config.json", "rmac-mj reproduce")
        stored = resumed["protocol"]
        layers.append((stored, stored.get("agent_configs", {})))
        # a run started with --no-optimal is finished without the reference too
        without_references = resumed.get("references") is False
    named = args.env
    if args.config is not None:
        # the command line's environment completes the file (its trial_steps, learner_state...)
        completion = {"env": args.env} if args.env is not None else None
        config = sweep_file.load_configuration(args.config, completion)
        layers.append((config.options, config.agent_configs))
        named = named or config.options.get("env")
    if resumed is not None:  # before anything the directory names is built
        resumed_environment(args.out, resumed, named, args.trust_env)
    if not layers:
        return args
    defaults: dict[str, Any] = {}
    extra: dict[str, Any] = {}
    agent_configs: dict[str, dict] = {}
    for options, configs in layers:
        for key, value in options.items():
            if key == "agent_configs":
                continue
            if key in PROTOCOL_OPTIONS:
                defaults[key] = ",".join(value) if key in ("algorithms", "prior_parts") else value
            else:
                extra[key] = value
        agent_configs = bounded_toml.merge(agent_configs, configs)
    if defaults.get("prior") is None or str(defaults["prior"]).endswith(".npz"):
        defaults.pop("prior_trials", None)  # a demonstrator's only
    if not defaults.get("prior_parts"):
        defaults.pop("prior_parts", None)  # none given: every part a learner takes
    args = build_parser(defaults).parse_args(argv)
    args.no_optimal = args.no_optimal or without_references
    args.config_protocol, args.config_agent_configs = extra, agent_configs
    return args


def run_options(args, **own: Any):
    """The :class:`~rmac_mj.experiments.runner.RunOptions` a run command's arguments give (its
    --jobs, --resume, --scheduler, --no-progress, --no-optimal where it has them), with ``own``."""
    from rmac_mj.experiments import RunOptions

    return RunOptions(
        jobs=args.jobs,
        resume=args.resume,
        scheduler=getattr(args, "scheduler", None),
        progress=not args.no_progress,
        references=not getattr(args, "no_optimal", True),
        log=say,
        started=STARTED,
        **own,
    )


def prior_options(args) -> dict[str, Any]:
    """The Protocol's prior knowledge fields that --prior, --prior-trials and --prior-parts give."""
    if args.prior is None and (args.prior_trials is not None or args.prior_parts is not None):
        raise UsageError("--prior-trials and --prior-parts need --prior")
    if args.prior is not None and args.prior.endswith(".npz") and args.prior_trials is not None:
        raise UsageError("--prior-trials counts demonstrator trials; a recorded file is used whole")
    prior = {}
    if args.prior is not None:
        prior["prior"] = args.prior
        if args.prior_trials is not None:
            prior["prior_trials"] = args.prior_trials
        if args.prior_parts is not None:
            prior["prior_parts"] = tuple(
                p.strip() for p in args.prior_parts.split(",") if p.strip()
            )
            if not prior["prior_parts"]:
                raise UsageError("--prior-parts must name at least one part")
    return prior


def protocol_of(args):
    """The Protocol ``reproduce``'s arguments describe (with a --config file's or a resumed run's
    settings, :func:`settings_from_files`); UsageError naming what is wrong with it."""
    from rmac_mj.experiments.protocol import Protocol
    from rmac_mj.sweeps import bounded_toml

    prior = prior_options(args)
    overrides = parse_overrides(args.set)
    agent_configs = bounded_toml.merge(getattr(args, "config_agent_configs", {}), overrides)
    # Each option's value is the Protocol field of its name, but those read their own way here.
    own_way = ("algorithms", "prior", "prior_trials", "prior_parts")
    given = {field: getattr(args, field) for field in PROTOCOL_OPTIONS if field not in own_way}
    with user_input():
        return Protocol(
            **given,
            algorithms=algorithms_to_run(args, overrides),
            agent_configs=agent_configs,
            **{**getattr(args, "config_protocol", {}), **prior},
        )


def show_finished(out: pathlib.Path, protocol, resume: str) -> None:
    """Say that ``out`` already holds this run, finished, and print its summary."""
    from rmac_mj.evaluation import report
    from rmac_mj.results.store import ResultStore

    try:
        finished = ResultStore(out).read_summary()
    except UserInputError as error:  # damaged since it was written: --resume writes it again
        raise UsageError(f"{error}; {resume} writes it again") from None
    say(
        f"{out} already holds this run, finished; its summary (run with another --out to repeat it):"
    )
    print(report.summary_table(finished, protocol.algorithms))
    print(f"results in {out}/ (summary.json, returns.csv, fig2_learning_curves.png)")


def interrupted(out: pathlib.Path, protocol, resume: str) -> Interrupted:
    """What a Ctrl-C of ``reproduce`` leaves in ``out``: finished experiments, checkpoints or
    nothing, and the command that finishes the run."""
    from rmac_mj.experiments import runner
    from rmac_mj.results.store import ResultStore

    saved = runner.finished_experiments(out, protocol)
    again = f"finish it with: {resume}"
    if saved:
        return Interrupted(
            f"{saved} finished experiment{' is' if saved == 1 else 's are'} saved in {out}; {again}"
        )
    checkpointed = {a: ResultStore(out).checkpointed(a) for a in protocol.algorithms}
    held = [
        f"{a} experiment {i} after trial {t}"
        for a, found in checkpointed.items()
        for i, t in sorted(found.items())
    ]
    if held:
        return Interrupted(
            f"no experiment had finished; kept to continue from: {', '.join(held)}; {again}"
        )
    if ResultStore(out).read_config() is None:  # nothing begun: nothing to resume
        return Interrupted("no experiment had started, nothing is saved")
    return Interrupted(f"no experiment had finished, nothing is saved; {again}")


def run_reproduced(args, protocol, out: pathlib.Path, resume: str) -> dict[str, Any]:
    """Run ``protocol`` into ``out`` as ``reproduce``'s arguments say; a lost scheduler or a Ctrl-C
    becomes one line saying what is saved and how to finish (``resume``)."""
    from rmac_mj.experiments import execution, runner

    try:
        return runner.run_protocol(protocol, out, run_options(args, smooth=args.smooth))
    except execution.BackendError as error:  # e.g. the scheduler lost: what finished is saved
        saved = runner.finished_experiments(out, protocol)
        if not saved:
            raise
        raise UsageError(
            f"{error}; {saved} finished experiment{'s' * (saved != 1)} saved in {out}: "
            f"finish with {resume} (with --scheduler or --jobs)"
        ) from None
    except KeyboardInterrupt:
        raise interrupted(out, protocol, resume) from None


def show_summary(summary: dict[str, Any], protocol, out: pathlib.Path) -> None:
    """The finished run's table and its wall time over all its parts."""
    from rmac_mj.evaluation import report

    print(report.summary_table(summary, protocol.algorithms))
    parts = summary["wall_time_parts_s"]
    total = summary["wall_time_s"]
    detail = (
        f" over {len(parts)} parts ({' + '.join(f'{p:.1f}' for p in parts)} s)"
        if len(parts) > 1
        else ""
    )
    print(
        f"wall time {total:.1f} s{detail}, all included (start-up, compiling, experiments, "
        f"reference, figures); results in {out}/ (summary.json, returns.csv, fig2_learning_curves.png)"
    )


def reproduce(args) -> int:
    from rmac_mj.results.store import ResultStore

    protocol = protocol_of(args)
    out = writable_dir(args.out)
    if args.jobs is not None and args.scheduler:
        raise UsageError("--jobs and --scheduler exclude each other")
    # What finishes this run as it was started (a run without the reference stays without it).
    resume = f"rmac-mj reproduce --resume --out {out}{' --no-optimal' if args.no_optimal else ''}"
    if not args.resume and ResultStore(out).holds_finished(protocol):
        show_finished(out, protocol, resume)
        return 0
    summary = run_reproduced(args, protocol, out, resume)
    show_summary(summary, protocol, out)
    return 0


def sweep(args) -> int:
    from rmac_mj.sweeps import sweep as sweeps
    from rmac_mj.sweeps import sweep_file

    if args.jobs is not None and args.scheduler:
        raise UsageError("--jobs and --scheduler exclude each other")
    if args.resume and not (args.out / "sweep.json").is_file():
        raise nothing_to_resume(args.out, "sweep.json", f"rmac-mj sweep {args.file}")
    # the whole file is validated before anything runs; its size is said first
    sizes = {
        key: getattr(args, key) for key in SWEEP_SIZE_OPTIONS if getattr(args, key) is not None
    }
    plan = sweep_file.load_sweep(args.file, announce=say, sizes=sizes)
    out = writable_dir(args.out)
    say(f"running into {out}/")
    try:
        rows = sweeps.run_sweep(plan, out, run_options(args))
    except KeyboardInterrupt:
        given = "".join(f" --{key} {value}" for key, value in sizes.items())
        again = f"rmac-mj sweep {args.file}{given} --resume --out {out}"
        raise Interrupted(
            f"finished experiments are saved in {out}; finish the sweep with: {again}"
            f"{' --no-optimal' if args.no_optimal else ''}"
        ) from None
    print(sweeps.format_table(plan, rows))
    print(
        f"results in {out}/ (sweep.csv, sweep_<metric>.png, sweep.json, one directory per "
        "configuration)"
    )
    return 0


def panel(args) -> int:
    from rmac_mj.experiments import panel as panels

    algorithms = tuple(a.strip() for a in args.algorithms.split(",") if a.strip())
    names = None if args.tasks is None else [t.strip() for t in args.tasks.split(",") if t.strip()]
    with user_input():
        chosen = panels.tasks_named(names)
        refuse_unwritable(args.out)  # before the protocols, which measure the tasks' boxes
        for task in chosen:  # every protocol is checked before anything runs
            task.make_protocol(algorithms, args.experiments, args.seed, args.trials)
    if args.resume and not any((args.out / task.name / "config.json").is_file() for task in chosen):
        raise nothing_to_resume(args.out, "task's run (<task>/config.json)", "rmac-mj panel")
    out = writable_dir(args.out)
    try:
        panels.run_panel(
            out,
            algorithms,
            args.experiments,
            args.seed,
            names,
            trials=args.trials,
            options=run_options(args),
        )
    except KeyboardInterrupt:
        raise Interrupted(
            f"finished experiments are saved in {out}; finish the panel with: "
            f"rmac-mj panel --out {out} --resume (and the same options)"
        ) from None
    for task in chosen:
        if args.trials is None:
            print(panels.format_rows(task, panels.panel_rows(task, [out / task.name])))
            print()
    print(
        f"results in {out}/<task>/ (one reproduce directory per task: summary.json, returns.csv, "
        "fig2_learning_curves.png)"
    )
    return 0
