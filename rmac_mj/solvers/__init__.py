"""The near-optimal return the learners are measured against, and the exploration floor.

A task declares its solver (``tasks.knowledge(domain, task).optimum``): grid dynamic programming
(:class:`OptimalConfig`, :class:`OptimalResult`) or trajectory optimisation by iLQR from several
starts (:class:`TrajoptConfig`, :class:`TrajoptResult`). ``optimum_result(domain, task)`` solves once,
then reads the cache; ``optimum_return`` is its return per trial.
"""

from rmac_mj.solvers.dynamic_programming import OptimalResult
from rmac_mj.solvers.dynamic_programming_config import OptimalConfig
from rmac_mj.solvers.exploration_floor import ExplorationFloor
from rmac_mj.solvers.optimum import (
    SOLVERS,
    Optimum,
    has_optimum,
    optimum_result,
    optimum_return,
    run_exploration_floor,
    run_optimum,
)
from rmac_mj.solvers.problem import TrialProblem, problem_identity
from rmac_mj.solvers.trajopt import TrajoptConfig, TrajoptResult

__all__ = [
    # A task's near-optimal return and exploration floor
    "SOLVERS",
    "Optimum",
    "has_optimum",
    "optimum_result",
    "optimum_return",
    "run_exploration_floor",
    "run_optimum",
    # The solvers' settings and results
    "ExplorationFloor",
    "OptimalConfig",
    "OptimalResult",
    "TrajoptConfig",
    "TrajoptResult",
    # The problem every solver shares
    "TrialProblem",
    "problem_identity",
]
