"""Sweeps: a TOML file of ``reproduce`` settings read and checked before anything runs
(:func:`load_sweep`, :func:`load_configuration`), its grid of runs in one pool (:func:`run_sweep`,
each configuration a result directory with the same seeds), their table and figures, and the
``ALGO.FIELD`` keys of settings.
"""

from rmac_mj.sweeps.bounded_toml import as_toml, flatten, merge, nest
from rmac_mj.sweeps.figure import plot_sweep
from rmac_mj.sweeps.sweep import COLUMNS, SweepResumeRefused, format_table, run_sweep, sweep_rows
from rmac_mj.sweeps.sweep_checks import SweepFileError
from rmac_mj.sweeps.sweep_file import (
    Configuration,
    SingleConfiguration,
    Sweep,
    load_configuration,
    load_sweep,
)

__all__ = [
    # Sweep files
    "Configuration",
    "SingleConfiguration",
    "Sweep",
    "SweepFileError",
    "load_configuration",
    "load_sweep",
    # Running a sweep, its table and figures
    "COLUMNS",
    "SweepResumeRefused",
    "format_table",
    "plot_sweep",
    "run_sweep",
    "sweep_rows",
    # ALGO.FIELD keys and nested tables
    "as_toml",
    "flatten",
    "merge",
    "nest",
]
