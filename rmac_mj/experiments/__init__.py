"""Running a protocol: what is run (:class:`Protocol`, the paper's section 6 and its checks), the
runner that runs protocols into result directories (:func:`run_protocol`, experiments in worker
processes or on Dask, then the summary and figures), one experiment assembled from its seeds and its
learning loop (:func:`build_experiment`, :func:`run_experiment`), prior knowledge recorded and read
(:func:`record`, :class:`Demonstration`), the near-optimal return beside a run, and the public panel.
"""

from rmac_mj.experiments.admission import TaskFacts, check_memory, resolve_agents
from rmac_mj.experiments.execution import BackendError, connect_dask
from rmac_mj.experiments.experiment import (
    Experiment,
    build_experiment,
    demonstration_for,
    experiment_seeds,
    fresh_learners,
)
from rmac_mj.experiments.experiment_loop import ExperimentSpec, run_experiment
from rmac_mj.experiments.near_optimal_service import NearOptimalService, near_optimal
from rmac_mj.experiments.panel import PanelTask, panel_rows, run_panel
from rmac_mj.experiments.prior_transitions import (
    Demonstration,
    load_demonstration,
    record,
    save_demonstration,
)
from rmac_mj.experiments.progress import Progress, TrialFeed
from rmac_mj.experiments.protocol import Protocol
from rmac_mj.experiments.runner import (
    RunOptions,
    finished_experiments,
    run_protocol,
    run_protocols,
)

__all__ = [
    # What is run, and running it
    "Protocol",
    "RunOptions",
    "finished_experiments",
    "run_protocol",
    "run_protocols",
    # One experiment
    "Experiment",
    "ExperimentSpec",
    "build_experiment",
    "demonstration_for",
    "experiment_seeds",
    "fresh_learners",
    "run_experiment",
    # Prior knowledge: recorded transitions
    "Demonstration",
    "load_demonstration",
    "record",
    "save_demonstration",
    # Before and beside a run: admission, workers, progress, the near-optimal return
    "BackendError",
    "NearOptimalService",
    "Progress",
    "TaskFacts",
    "TrialFeed",
    "check_memory",
    "connect_dask",
    "near_optimal",
    "resolve_agents",
    # The public panel
    "PanelTask",
    "panel_rows",
    "run_panel",
]
