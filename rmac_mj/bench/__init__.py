"""``rmac-mj bench``: where the microseconds of a control step go, as ratios to the raw physics step
(:func:`run` assembles the report, :func:`format_table` and :func:`format_markdown` write it against
the targets), each part measured on its own, and the cost of planning and replay
(:func:`rehearsal_costs`).
"""

from rmac_mj.bench.bench import run
from rmac_mj.bench.measurements import (
    check_task,
    env_step_us,
    experiment_s,
    learner_step_us,
    llr_query_insert_us,
    physics_step_us,
    real_run,
    step_costs,
)
from rmac_mj.bench.planning import rehearsal_costs
from rmac_mj.bench.tables import format_markdown, format_table

__all__ = [
    # The report
    "check_task",
    "format_markdown",
    "format_table",
    "run",
    # Its measurements
    "env_step_us",
    "experiment_s",
    "learner_step_us",
    "llr_query_insert_us",
    "physics_step_us",
    "real_run",
    "rehearsal_costs",
    "step_costs",
]
