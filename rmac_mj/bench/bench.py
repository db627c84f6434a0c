"""``rmac-mj bench``: where the microseconds of a control step go, as ratios to the raw physics.

Every figure is measured on one task (``--domain/--task``, default the paper's swing-up), or on an
outside environment (``--env``, ``rmac_mj.envs``): what using the learners on it costs beyond the
environment itself (:mod:`rmac_mj.bench.measurements`; the planning and replay figures are
:mod:`rmac_mj.bench.planning`'s). This module assembles the report (the keys of ``--json``);
:mod:`rmac_mj.bench.tables` writes it for people against the targets, ratios within one run:

    env.step           <= 1.5 x raw    RMAC learner step  <= 2 x raw    S-AC learner step <= 1 x raw
    LLR query + insert <= 0.7 x raw    a real run of both learners (``run_protocol`` on 2 workers)
    <= 3.5 x the raw physics time of its steps;  full protocol (40 + 40 x 600 trials) <= 10 min wall
"""

from __future__ import annotations

import os
import platform
from typing import Any

import mujoco

from rmac_mj.bench import planning as bench_planning
from rmac_mj.bench.measurements import (
    check_task,
    env_step_us,
    experiment_s,
    learner_step_us,
    llr_query_insert_us,
    measured_environment,
    measured_protocol,
    physics_step_us,
    real_run,
    step_costs,
)
from rmac_mj.bench.tables import (
    PAPER_EXPERIMENTS,
    PAPER_TRIALS,
    PROTOCOL_TARGET_MIN,
    ROWS,
    RUN_TARGET,
    TARGETS,
    format_markdown,
    format_table,
)
from rmac_mj.rollout import n_sub_steps, state_space_of, steps_per_trial

__all__ = [
    "PAPER_EXPERIMENTS",
    "PAPER_TRIALS",
    "PROTOCOL_TARGET_MIN",
    "ROWS",
    "RUN_TARGET",
    "TARGETS",
    "check_task",
    "env_step_us",
    "experiment_s",
    "format_markdown",
    "format_table",
    "learner_step_us",
    "llr_query_insert_us",
    "physics_step_us",
    "real_run",
    "run",
    "step_costs",
]


def _cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as handle:
            for line in handle:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def run(
    quick: bool = False, algorithms: tuple[str, ...] = ("s-ac", "rmac"), jobs: int = 2, **where: Any
) -> dict[str, Any]:
    """Measure everything on a task of the suite or an outside environment (``where``: ``domain``
    and ``task``, or ``env`` with its ``learner_state`` and ``action_repeat``, see
    :func:`~rmac_mj.bench.measurements.measured_protocol`); return the report (the keys of
    ``--json``)."""
    calls, repeats = (200, 5) if quick else (1000, 9)
    trials = 30 if quick else PAPER_TRIALS
    on = dict(where)
    env = measured_environment(**where)
    report: dict[str, Any] = {
        **on,
        "environment": measured_protocol(**where).environment_name,
        "control_timestep_s": env.control_timestep(),
        "n_sub_steps": n_sub_steps(env) if hasattr(env, "physics") else None,
        "state_dim": state_space_of(env).dim,
    }
    report.update(step_costs(calls, repeats, **on))
    report.update(
        {
            "llr_query_insert_us": llr_query_insert_us(calls, repeats, **on),
            "sac_step_us": learner_step_us("s-ac", repeats, **on),
            "rmac_step_us": learner_step_us("rmac", repeats, **on),
            "mlac_step_us": learner_step_us("mlac", repeats, **on),
        }
    )
    physics = report["physics_step_us"]
    report["env_overhead_us"] = report["env_step_us"] - physics
    report["outside_physics_learner_us"] = report["env_overhead_us"] + report["glue_step_us"]
    report["x_physics_step"] = {key: report[key] / physics for key, _ in ROWS}
    walls = {name: experiment_s(name, trials, **on) * PAPER_TRIALS / trials for name in algorithms}
    cores = os.cpu_count() or 1
    report["experiment_s"] = walls
    report["experiment_trials_measured"] = trials
    report["steps_per_trial"] = steps_per_trial(env)
    # Experiments are independent and run one per core; the projection assumes perfect scaling.
    report["protocol_projected_min"] = PAPER_EXPERIMENTS * sum(walls.values()) / cores / 60.0
    report["run"] = real_run(1 if quick else 2, 10 if quick else 100, jobs, physics, **on)
    report["rehearsal"] = bench_planning.rehearsal_costs(
        repeats=3 if quick else 5,
        trials=1 if quick else 2,
        steps=(0, 20) if quick else bench_planning.STEPS,
        **on,
    )
    report["machine"] = {
        "cores": cores,
        "cpu": _cpu_name(),
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
    }
    return report
