"""The result directory of a run and the files in it: :class:`ResultStore` (its layout, and every read
and write of it), the records it saves and loads (:class:`ExperimentResult`, :class:`Curves`), the
refusals of a resume, its lock, atomic writes of plain files, and snapshots of learners:
``load_snapshot(path)`` gives back a learner a run saved, ready to act in the user's own loop.
"""

from rmac_mj.results.documents import DamagedDirectory, ResumeRefused
from rmac_mj.results.files import provenance, write_atomic, write_csv, write_json, write_npz
from rmac_mj.results.integrity import DirectoryBusy, DirectoryLock
from rmac_mj.results.records import Curves, ExperimentResult, TrialLog
from rmac_mj.results.snapshots import load_snapshot, save_snapshot, snapshot_environment
from rmac_mj.results.store import ResultStore

__all__ = [
    # The result directory
    "Curves",
    "DamagedDirectory",
    "DirectoryBusy",
    "DirectoryLock",
    "ExperimentResult",
    "ResultStore",
    "ResumeRefused",
    "TrialLog",
    # Snapshots of learners
    "load_snapshot",
    "save_snapshot",
    "snapshot_environment",
    # Plain files, written atomically, with their provenance
    "provenance",
    "write_atomic",
    "write_csv",
    "write_json",
    "write_npz",
]
