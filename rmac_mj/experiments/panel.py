"""The public panel: seven tasks nobody tuned for, each learner at equal interaction, against goals.

Each :class:`PanelTask` is one ``reproduce`` protocol and a goal read from its greedy curve;
:func:`run_panel` runs them into ``OUT/<task>/`` through one pool, :func:`panel_rows` scores them
(interquartile means, :mod:`rmac_mj.evaluation.statistics`).
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
from collections.abc import Sequence
from typing import Any

import numpy as np

from rmac_mj.evaluation import statistics
from rmac_mj.experiments import runner
from rmac_mj.experiments.protocol import Protocol
from rmac_mj.results.store import ResultStore

#: Experiments per learner and task (at least 5, so that the summaries show intervals).
EXPERIMENTS = 5


@dataclasses.dataclass(frozen=True)
class PanelTask:
    """One task of the panel.

    Attributes:
      name: its directory under the panel's OUT.
      protocol: the ``Protocol`` fields of its run (but ``algorithms``, ``experiments``, ``seed``).
      goal: the greedy return to reach (at or above), and ``goal_trial``, the learning trial by which
        (its greedy evaluation after that trial is scored).
      goal_text: the goal as people read it.
    """

    name: str
    protocol: dict[str, Any]
    goal: float
    goal_trial: int
    goal_text: str

    def make_protocol(
        self, algorithms: Sequence[str], experiments: int, seed: int, trials: int | None = None
    ) -> Protocol:
        """The task's protocol for ``algorithms``; ``trials``: a shorter run (a smoke test)."""
        fields = dict(self.protocol)
        if trials is not None:
            fields["trials"] = trials
            fields["evaluate_every"] = 1
            fields["evaluate_starts"] = min(fields.get("evaluate_starts", 0), 1)
        return Protocol(
            algorithms=tuple(algorithms),
            experiments=experiments,
            seed=seed,
            snapshot_trials=(),
            **fields,
        )


#: dm-control's tasks: an action repeat of 5 (cartpole's 0.01 s and pendulum's 0.02 s become 0.05 s
#: and 0.1 s per decision), no action cost in their rewards.
_DM_CONTROL = {"learner_state": {"action_cost": [0.0]}, "action_repeat": 5}

#: The panel, with its budgets and goals (docs/panel.md). Trials end at the task's time limit (none
#: of these terminates but MountainCar, at its flag), so a budget in trials is one in environment
#: steps. Each run is somewhat longer than its goal's budget, so the curves show what follows.
TASKS: tuple[PanelTask, ...] = (
    PanelTask(
        "dc_pendulum",
        {"domain": "dc_pendulum", "task": "swingup", "trials": 20, "evaluate_every": 5},
        goal=-823.0,
        goal_trial=5,
        goal_text="greedy >= -823 (within 10% of the optimum -748) by trial 5 (500 steps)",
    ),
    PanelTask(
        "two_link_arm",
        {"domain": "two_link_arm", "task": "reach", "trials": 50, "evaluate_every": 5},
        goal=-41.415,
        goal_trial=30,
        goal_text="greedy >= -41.4 (within 10% of -37.65) by trial 30",
    ),
    PanelTask(
        "pendulum_v1",
        {
            "env": "gymnasium:Pendulum-v1",
            "trials": 25,
            "evaluate_every": 5,
            "evaluate_starts": 10,
            "learner_state": {"action_cost": [0.001]},
        },
        goal=-170.0,
        goal_trial=15,
        goal_text="greedy >= -170 (mean of 10 starts) at 3k steps (trial 15)",
    ),
    PanelTask(
        "cartpole_balance",
        {
            "env": "dm_control:cartpole/balance",
            "trials": 10,
            "evaluate_every": 1,
            "evaluate_starts": 3,
            **_DM_CONTROL,
        },
        goal=950.0,
        goal_trial=5,
        goal_text="greedy >= 950 (mean of 3 starts) at 5k env steps (trial 5)",
    ),
    PanelTask(
        "cartpole_swingup",
        {
            "env": "dm_control:cartpole/swingup",
            "trials": 100,
            "evaluate_every": 10,
            "evaluate_starts": 3,
            **_DM_CONTROL,
        },
        goal=850.0,
        goal_trial=50,
        goal_text="greedy >= 850 (mean of 3 starts) at 50k env steps (trial 50)",
    ),
    PanelTask(
        "mountaincar",
        {
            "env": "gymnasium:MountainCarContinuous-v0",
            "trials": 20,
            "evaluate_every": 5,
            "evaluate_starts": 5,
            "control_timestep": 0.05,
            "learner_state": {"action_cost": [0.1]},
        },
        goal=90.0,
        goal_trial=10,
        goal_text="greedy >= 90 (mean of 5 starts) in every experiment within 10 episodes",
    ),
    PanelTask(
        "pendulum_swingup",
        {
            "env": "dm_control:pendulum/swingup",
            "trials": 100,
            "evaluate_every": 10,
            "evaluate_starts": 3,
            **_DM_CONTROL,
        },
        goal=600.0,
        goal_trial=100,
        goal_text="greedy >= 600 (mean of 3 starts, a sparse reward) at 100k env steps (trial 100)",
    ),
)
TASKS_BY_NAME = {task.name: task for task in TASKS}


def tasks_named(names: Sequence[str] | None) -> tuple[PanelTask, ...]:
    """The panel's tasks of ``names`` (None: all), in the panel's order; ValueError naming an
    unknown one."""
    if names is None:
        return TASKS
    unknown = [name for name in names if name not in TASKS_BY_NAME]
    if unknown:
        raise ValueError(
            f"unknown panel task {', '.join(map(repr, unknown))}; the panel's: "
            f"{', '.join(TASKS_BY_NAME)}"
        )
    return tuple(task for task in TASKS if task.name in names)


def run_panel(
    out: str | os.PathLike,
    algorithms: Sequence[str],
    experiments: int = EXPERIMENTS,
    seed: int = 0,
    tasks: Sequence[str] | None = None,
    trials: int | None = None,
    options: runner.RunOptions | None = None,
) -> list[dict[str, Any]]:
    """Run the panel's tasks for ``algorithms`` into ``out/<task>/`` (one worker pool for all);
    return their summaries. ``trials``: every task this short (a smoke test, not the panel);
    ``options``: how the tasks are run (:class:`runner.RunOptions`)."""
    options = options or runner.RunOptions()
    chosen = tasks_named(tasks)
    runs = [
        (task.make_protocol(algorithms, experiments, seed, trials), pathlib.Path(out) / task.name)
        for task in chosen
    ]
    return runner.run_protocols(runs, options)


def _score(greedy: np.ndarray) -> dict[str, Any]:
    estimate = statistics.iqm_interval(greedy).as_dict()
    return {"iqm": estimate["value"], "ci95": estimate["ci95"], "mean": float(np.mean(greedy))}


def panel_rows(task: PanelTask, directories: Sequence[str | os.PathLike]) -> list[dict[str, Any]]:
    """One row per learner found in ``directories`` (result directories of ``task``'s protocol,
    e.g. the panel's and a separate SAC run): the greedy return at the goal's trial (IQM, its 95%
    stratified-bootstrap interval, the mean), the experiments that reached the goal, the environment
    steps taken by then, the CPU per experiment and per learning control step (the CPU of the whole
    experiment, its greedy evaluations included, over the control steps it learned from)."""
    rows = []
    for directory in directories:
        store = ResultStore(directory)
        config = store.read_config()
        if config is None:
            continue
        protocol = config["protocol"]
        for algorithm in protocol["algorithms"]:
            saved = sorted(i for i in store.finished(algorithm) if i < protocol["experiments"])
            if not saved:
                continue
            curves = store.load_curves(algorithm, None)
            trials = list(curves.greedy_trials)
            if task.goal_trial not in trials:
                continue
            at = trials.index(task.goal_trial)
            greedy = curves.greedy_returns[:, at]
            reached = int(np.sum(greedy >= task.goal))
            counted = curves.env_steps
            steps = counted[:, task.goal_trial - 1] if counted is not None else None
            cpu = (
                float(np.mean(curves.cpu_times)) if np.all(np.isfinite(curves.cpu_times)) else None
            )
            control_steps = (
                float(np.mean(counted[:, -1])) / protocol.get("action_repeat", 1)
                if counted is not None and np.all(np.isfinite(counted[:, -1]))
                else None
            )
            rows.append(
                {
                    "learner": algorithm,
                    "directory": str(directory),
                    "experiments": len(saved),
                    "greedy": _score(greedy),
                    "reached": reached,
                    "goal_trial": task.goal_trial,
                    "env_steps": (
                        None
                        if steps is None or not np.all(np.isfinite(steps))
                        else float(np.mean(steps))
                    ),
                    "cpu_s_per_experiment": cpu,
                    "ms_per_control_step": (
                        None if cpu is None or not control_steps else 1000 * cpu / control_steps
                    ),
                    "greedy_trials": trials,
                    "greedy_per_experiment": curves.greedy_returns.tolist(),
                    "code": config.get("code", {}).get("commit"),
                }
            )
    return rows


def format_rows(task: PanelTask, rows: list[dict[str, Any]]) -> str:
    """The rows of :func:`panel_rows` as a Markdown table."""
    sac = [
        r["cpu_s_per_experiment"]
        for r in rows
        if r["learner"] == "sb3-sac" and r["cpu_s_per_experiment"]
    ]
    lines = [
        f"{task.name}: {task.goal_text}",
        "",
        f"| learner | experiments | greedy at trial {task.goal_trial} (IQM [95% CI]) | reached goal | env steps "
        "| CPU s / experiment | CPU vs SAC | ms / control step |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        low, high = row["greedy"]["ci95"]
        ci = f"[{low:.1f}, {high:.1f}]" if low is not None else "[n/a]"
        cpu = row["cpu_s_per_experiment"]
        ratio = f"{cpu / sac[0]:.3f}" if sac and cpu else ""
        steps = f"{row['env_steps']:.0f}" if row["env_steps"] is not None else "n/a"
        ms = "" if row["ms_per_control_step"] is None else f"{row['ms_per_control_step']:.2f}"
        lines.append(
            f"| {row['learner']} | {row['experiments']} | {row['greedy']['iqm']:.1f} {ci} | "
            f"{row['reached']}/{row['experiments']} | {steps} | "
            f"{'' if cpu is None else f'{cpu:.1f}'} | {ratio} | {ms} |"
        )
    return "\n".join(lines)
