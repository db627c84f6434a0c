"""The bench's report for people: a table against the targets, and the same figures as the README's
Markdown table."""

from __future__ import annotations

from typing import Any

from rmac_mj import tasks
from rmac_mj.bench import planning as bench_planning

#: The suite's default task, which the benchmark measures unless told otherwise.
_DOMAIN, _TASK = tasks.DEFAULT_TASK
#: Targets as multiples of the raw control step: ratios within one run, never absolute times.
TARGETS = {"env_step_us": 1.5, "sac_step_us": 1.0, "rmac_step_us": 2.0, "llr_query_insert_us": 0.7}
#: Target of a real run's wall time, as a multiple of the raw physics time of its steps per worker.
RUN_TARGET = 3.5
#: Target of the full protocol's projected wall time (minutes).
PROTOCOL_TARGET_MIN = 10.0
PAPER_EXPERIMENTS, PAPER_TRIALS = 40, 600


#: The per-step figures of the report, in table order, with their labels ({n_sub}: physics steps per
#: control step of the measured task).
ROWS = (
    ("physics_step_us", "{raw_step}"),
    ("env_step_us", "{env_step}"),
    ("env_overhead_us", "  of which outside the physics"),
    ("glue_step_us", "glue per step (run_trial, agent boundary)"),
    ("outside_physics_learner_us", "overhead outside physics and learner"),
    ("llr_query_insert_us", "LLR query + insert (N=2000, K=20)"),
    ("sac_step_us", "S-AC learner step (act + update)"),
    ("rmac_step_us", "RMAC learner step (act + update)"),
    ("mlac_step_us", "MLAC learner step (act + update)"),
)


def _verdict(ratio: float, target: float | None) -> str:
    if target is None:
        return ""
    return f"<= {target:g} " + ("met" if ratio <= target else "MISSED")


def _rows(report: dict[str, Any]) -> list[tuple[str, float, str]]:
    """The per-step figures of ``report``: each row's label, microseconds and verdict against its
    target (in multiples of the raw control step)."""
    rows = []
    for key, label in ROWS:
        value = report[key]
        label = label.format(raw_step=_raw_label(report), env_step=_env_step_label(report))
        rows.append((label, value, _verdict(value / report["physics_step_us"], TARGETS.get(key))))
    return rows


def format_table(report: dict[str, Any]) -> str:
    """The report as a table: microseconds, multiples of the raw control step and of env.step."""
    physics, env = report["physics_step_us"], report["env_step_us"]
    lines = [
        _task_line(report),
        f"{'what':<44} {'us':>8} {'x raw step':>10} {'x env.step':>10}  target (x raw)",
        "-" * 90,
    ]
    for label, value, verdict in _rows(report):
        lines.append(
            f"{label:<44} {value:>8.1f} {value / physics:>10.2f} {value / env:>10.2f}  {verdict}"
        )
    lines.append("")
    measured = report.get("experiment_trials_measured", PAPER_TRIALS)
    per_trial = report["steps_per_trial"]
    for name, seconds in report["experiment_s"].items():
        note = "" if measured == PAPER_TRIALS else f", projected from {measured} trials"
        per_step = seconds / (PAPER_TRIALS * per_trial) * 1e6
        lines.append(
            f"one experiment of {PAPER_TRIALS} trials, {name:<5} {seconds:>6.1f} s: "
            f"{per_step:.0f} us per step = {per_step / physics:.1f} x raw{note}"
        )
    run = report["run"]
    lines.append(
        f"real run, measured: run_protocol, {run['experiments_per_learner']} experiment(s) "
        f"x {run['trials']} trials per learner on {run['workers']} workers, "
        f"{run['steps']} steps ({run['physics_s']:.2f} s of raw physics per worker):"
    )
    lines.append(
        f"  wall {run['wall_s']:.1f} s = {run['x_physics']:.1f} x the raw physics (target for "
        f"a whole run: <= {RUN_TARGET:g}; a short run pays more of the start-up below)"
    )
    if run["cpu_s"] is not None:
        lines.append(
            f"  CPU  {run['cpu_s']:.1f} s per worker = {run['cpu_x_physics']:.1f} x "
            "(the wall time on idle cores)"
        )
    lines.append(
        f"  inside experiments {run['in_experiments_s']:.1f} s per worker (wall) = "
        f"{run['in_experiments_x_physics']:.1f} x; the rest of the wall time is starting "
        "workers (imports, numba cache) and writing results"
    )
    projected = report["protocol_projected_min"]
    verdict = "met" if projected <= PROTOCOL_TARGET_MIN else "MISSED"
    lines.append(
        f"full protocol (40 + 40 experiments) on {report['machine']['cores']} cores: "
        f"{projected:.1f} min projected (target <= {PROTOCOL_TARGET_MIN:g}: {verdict})"
    )
    if "rehearsal" in report:
        lines.extend(bench_planning.format_lines(report["rehearsal"], physics))
    lines.append(
        f"machine: {report['machine']['cpu']}, {report['machine']['cores']} cores, "
        f"Python {report['machine']['python']}, MuJoCo {report['machine']['mujoco']}"
    )
    return "\n".join(lines)


def _raw_label(report: dict[str, Any]) -> str:
    """What the unit of a report is (reports written before it was recorded: MuJoCo's steps)."""
    return report.get(
        "raw_step", f"raw MuJoCo control step ({report.get('n_sub_steps', '?')} x mj_step)"
    )


def _env_step_label(report: dict[str, Any]) -> str:
    if report.get("env") is not None:
        return "env.step (the environment + rmac_mj.envs)"
    return "env.step (dm-control Environment + task)"


def _task_line(report: dict[str, Any]) -> str:
    name = (
        report.get("environment") or f"{report.get('domain', _DOMAIN)}/{report.get('task', _TASK)}"
    )
    substeps = (
        f" = {report['n_sub_steps']} physics steps" if report.get("n_sub_steps") is not None else ""
    )
    return (
        f"{name}: control step {report.get('control_timestep_s', float('nan')):g} s{substeps}, "
        f"state n={report.get('state_dim', '?')}"
    )


def format_markdown(report: dict[str, Any]) -> str:
    """The per-step figures and the real run as a Markdown table (the README's speed table)."""
    physics = report["physics_step_us"]
    machine = report["machine"]
    lines = [
        f"`rmac-mj bench` on {machine['cpu']} ({machine['cores']} cores), Python "
        f"{machine['python']}, MuJoCo {machine['mujoco']}; {_task_line(report)}:",
        "",
        "| what | us | x raw control step | target |",
        "|---|---|---|---|",
    ]
    for label, value, verdict in _rows(report):
        lines.append(f"| {label.strip()} | {value:.1f} | {value / physics:.2f} | {verdict} |")
    per_trial = report["steps_per_trial"]
    for name, seconds in report["experiment_s"].items():
        per_step = seconds / (PAPER_TRIALS * per_trial) * 1e6
        lines.append(
            f"| one {PAPER_TRIALS}-trial experiment, {name}, per step | {per_step:.0f} | "
            f"{per_step / physics:.1f} | |"
        )
    run = report["run"]
    cpu = "" if run["cpu_s"] is None else f"; CPU per worker {run['cpu_x_physics']:.1f} x"
    lines.append(
        f"| real run: {run['experiments_per_learner']} + {run['experiments_per_learner']} "
        f"experiments x {run['trials']} trials on {run['workers']} workers | "
        f"{run['wall_s']:.1f} s wall | {run['x_physics']:.1f}{cpu} | "
        f"whole run: <= {RUN_TARGET:g} |"
    )
    lines.append(
        f"| full protocol, projected | {report['protocol_projected_min']:.1f} min | | "
        f"<= {PROTOCOL_TARGET_MIN:g} min |"
    )
    if "rehearsal" in report:
        lines.extend(bench_planning.format_markdown(report["rehearsal"], physics))
    return "\n".join(lines)
