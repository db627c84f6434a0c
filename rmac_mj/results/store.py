"""The result directory of a run (:class:`ResultStore`): its layout, and every read and write of it.

The runner, the sweep, rendering, ``compare`` and the scripts go through it, never building paths.
Files are written atomically (:mod:`rmac_mj.results.files`), snapshots before the curve, so a killed
run leaves only whole files. The records it saves and loads are in :mod:`~rmac_mj.results.records`,
its JSON documents are read by :mod:`~rmac_mj.results.documents`, and whether it holds the run asked
for is decided by :mod:`~rmac_mj.results.documents`.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
import re
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from rmac_mj.envs.spec import origin_problem
from rmac_mj.errors import MissingInputError
from rmac_mj.results import documents, files, integrity
from rmac_mj.results.documents import ResumeRefused, added_experiments
from rmac_mj.results.records import Curves, ExperimentResult
from rmac_mj.results.snapshots import (
    FORMAT,
    LEARNER_KEYS_BEFORE_FORMAT_3,
    with_learner_keys_of_today,
)

_EXPERIMENT_FILE = re.compile(r"exp_(\d{3,})\.npz")
_TRIAL_FILE = re.compile(r"trial_(\d+)\.npz")


def _experiment_name(index: int) -> str:
    return f"exp_{index:03d}"


class ResultStore:
    """One result directory; ``root`` need not exist yet. Its layout::

        OUT/config.json                              what was run (protocol, code, provenance)
        OUT/curves/<algorithm>/exp_<iii>.npz         an experiment's results; marks it done
        OUT/snapshots/<algorithm>/exp_<iii>/trial_<tttt>.npz   the agent after that trial
        OUT/progress/<algorithm>/exp_<iii>.csv       the live trial log of a running experiment
        OUT/checkpoints/<algorithm>/exp_<iii>.npz    an unfinished experiment, to continue from
        OUT/returns.csv, summary.json, fig2_learning_curves.{png,pdf}, wall_times.json
        OUT/performance_profiles.{png,pdf}

    An experiment counts as done only once everything it wrote is in place; a run holds
    ``OUT/.lock`` while it writes, and a resumed run checks every saved experiment against the
    config. A directory written before format 3 (``config.json`` without ``format``) keys two
    learners by their former names (:data:`~rmac_mj.results.snapshots.LEARNER_KEYS_BEFORE_FORMAT_3`):
    the store reads it under today's keys, so a figure or table never labels one learner with
    another's name.
    """

    def __init__(self, root: str | os.PathLike):
        self.root = pathlib.Path(root)
        self._lock: integrity.DirectoryLock | None = None
        self._stored_keys: dict[str, str] | None = None

    def __repr__(self) -> str:
        return f"ResultStore({str(self.root)!r})"

    # -- paths ---------------------------------------------------------------------------------------
    @property
    def config_path(self) -> pathlib.Path:
        return self.root / "config.json"

    @property
    def summary_path(self) -> pathlib.Path:
        return self.root / "summary.json"

    @property
    def returns_path(self) -> pathlib.Path:
        return self.root / "returns.csv"

    @property
    def figure_stem(self) -> pathlib.Path:
        """Fig. 2 without suffix (.png and .pdf are written)."""
        return self.root / "fig2_learning_curves"

    @property
    def profiles_stem(self) -> pathlib.Path:
        """The performance profiles of the final returns, without suffix (.png and .pdf)."""
        return self.root / "performance_profiles"

    @property
    def wall_times_path(self) -> pathlib.Path:
        """The wall time of every part of a run (the first and each ``--resume``): ``{"parts": [...]}``."""
        return self.root / "wall_times.json"

    def curve_path(self, algorithm: str, index: int) -> pathlib.Path:
        return self.root / "curves" / self._stored(algorithm) / f"{_experiment_name(index)}.npz"

    def snapshot_dir(self, algorithm: str, index: int) -> pathlib.Path:
        return self.root / "snapshots" / self._stored(algorithm) / _experiment_name(index)

    def snapshot_path(self, algorithm: str, index: int, trial: int) -> pathlib.Path:
        return self.snapshot_dir(algorithm, index) / f"trial_{trial:04d}.npz"

    def checkpoint_path(self, algorithm: str, index: int) -> pathlib.Path:
        """The checkpoint of an unfinished experiment (:mod:`rmac_mj.experiments.checkpoint`)."""
        return (
            self.root / "checkpoints" / self._stored(algorithm) / f"{_experiment_name(index)}.npz"
        )

    def checkpointed(self, algorithm: str) -> dict[int, int]:
        """Experiment index -> learning trials done, of ``algorithm``'s unfinished experiments that
        hold a checkpoint."""
        folder = self.root / "checkpoints" / self._stored(algorithm)
        found = {}
        for path in folder.glob("exp_*.npz") if folder.is_dir() else ():
            match = _EXPERIMENT_FILE.fullmatch(path.name)
            trials = integrity.npz_length(path, "curve/returns") if match else None
            if trials:
                found[int(match.group(1))] = trials
        return found

    def write_snapshot_arrays(
        self, algorithm: str, index: int, trial: int, arrays: dict[str, np.ndarray]
    ) -> None:
        """Write one snapshot (the arrays of ``snapshots.snapshot_arrays``)."""
        files.write_npz(self.snapshot_path(algorithm, index, trial), **arrays)

    def read_snapshot_arrays(self, algorithm: str, index: int, trial: int) -> dict[str, np.ndarray]:
        """The arrays of one snapshot as written."""
        with np.load(self.snapshot_path(algorithm, index, trial), allow_pickle=False) as data:
            return {key: data[key] for key in data.files}

    def progress_path(self, algorithm: str, index: int) -> pathlib.Path:
        """The live trial log of an experiment (see :class:`~rmac_mj.results.records.TrialLog`)."""
        return self.root / "progress" / self._stored(algorithm) / f"{_experiment_name(index)}.csv"

    # -- config --------------------------------------------------------------------------------------
    def read_config(self) -> dict[str, Any] | None:
        """The directory's ``config.json``, or None when there is none;
        :class:`~rmac_mj.results.documents.DamagedDirectory` when it cannot be read as a run's
        config (a JSON object with a ``protocol`` object)."""
        return documents.read_config(self.config_path)

    def read_protocol(self) -> dict[str, Any] | None:
        """The protocol (``Protocol.as_dict``) of the run in this directory, or None when there is none."""
        config = self.read_config()
        return None if config is None else config["protocol"]

    def write_config(self, document: dict[str, Any]) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        files.write_json(self.config_path, {"format": FORMAT, **document})

    # -- learner keys ----------------------------------------------------------------------------------
    def _renamed_keys(self) -> dict[str, str]:
        """Today's learner key -> the key this directory's files use, for the learners whose key
        changed (in a directory written before format 3; read once)."""
        if self._stored_keys is None:
            config = documents.read_config(self.config_path)
            before_3 = config is not None and config.get("format", 2) < 3
            renamed = LEARNER_KEYS_BEFORE_FORMAT_3.items() if before_3 else ()
            self._stored_keys = {today: stored for stored, today in renamed}
        return self._stored_keys

    def _stored(self, algorithm: str) -> str:
        """The key under which this directory stores today's learner ``algorithm``."""
        return self._renamed_keys().get(algorithm, algorithm)

    def lock(self) -> integrity.DirectoryLock:
        """The directory's exclusive lock (held while a run writes here; see
        :class:`~rmac_mj.results.integrity.DirectoryLock`)."""
        if self._lock is None:
            self._lock = integrity.DirectoryLock(self.root)
        return self._lock

    def begin(self, document: dict[str, Any], resume: bool) -> None:
        """Start a run described by ``document`` (``protocol``, ``code`` and optionally
        ``prior_sha256``, ``environment_origin`` and ``agents``) here, writing ``config.json``; or,
        with ``resume``, check that the directory holds this very run (same protocol, prior file,
        environment (its file's digest, its package's version) and code version) and clear what
        a killed run left half written. A resume may add experiments and nothing else (config.json then
        records the count it grew from in ``experiments_grown_from``). Raises :class:`ResumeRefused`
        naming the settings that differ, and refuses a directory holding results that no config
        describes. Call it under :meth:`lock`."""
        existing = self.read_config()
        if existing is None:
            self._begin_fresh(document)
            return
        differences, more = self._differences(existing, document, resume)
        if not resume:
            self._refuse_another_run(differences, document)
        if differences:
            raise ResumeRefused(
                f"{self.root} was written with a different config "
                f"({'; '.join(differences)}); refusing to mix results (give the same "
                "settings, or another --out)"
            )
        old, new = existing.get("code", {}), document["code"]
        if (old.get("package"), old.get("commit")) != (new.get("package"), new.get("commit")):
            raise ResumeRefused(
                f"{self.root} was written by another code version "
                f"({old.get('commit')}, now {new.get('commit')}); refusing to mix "
                "results"
            )
        if more > 0:
            self._grow(existing, document["protocol"]["experiments"])
        self.remove_temporaries()

    def _begin_fresh(self, document: dict[str, Any]) -> None:
        """Write the config of a run starting here, refusing results no config describes."""
        orphans = [name for name in ("curves", "snapshots") if (self.root / name).exists()]
        if orphans:
            raise ResumeRefused(
                f"{self.root} holds {' and '.join(orphans)} but no config.json: "
                "which run they belong to cannot be told; refusing to mix "
                "results (move them away, or choose another --out)"
            )
        self.write_config({**document, "provenance": files.provenance()})

    def _differences(
        self, existing: dict[str, Any], document: dict[str, Any], resume: bool
    ) -> tuple[list[str], int]:
        """What differs between the run in the directory (``existing``) and ``document``, said
        for a refusal (none where a resume only adds experiments), and how many experiments the
        new protocol adds (negative: drops)."""
        stored = existing.get("protocol", {})
        differences = documents.differences(stored, document["protocol"])
        if existing.get("prior_sha256") != document.get("prior_sha256"):
            differences.append("the prior knowledge file's contents (sha256)")
        changed = origin_problem(
            existing.get("environment_origin"), document.get("environment_origin")
        )
        if changed is not None:  # a run is one environment: its file, or its package's version
            differences.append(f"the environment: {changed}")
        more = added_experiments(stored, document["protocol"]) or 0
        if resume and more > 0 and len(differences) == 1:  # only the count grows: same seeds, more
            differences = []
        elif resume and more < 0 and len(differences) == 1:
            differences[0] += (
                " (a resume adds experiments, whose seeds do not depend on the count; "
                "it never drops any)"
            )
        return differences, more

    def _refuse_another_run(self, differences: list[str], document: dict[str, Any]) -> None:
        """The refusal of a fresh start where a run is: another, this one finished, or unfinished."""
        if differences:
            raise ResumeRefused(
                f"{self.root} already holds another run ({'; '.join(differences)}); "
                "choose another --out"
            )
        if self._complete(document["protocol"]):
            raise ResumeRefused(
                f"{self.root} already holds this run, finished (summary.json); "
                "choose another --out to repeat it"
            )
        raise ResumeRefused(
            f"{self.root} already holds this run, unfinished; pass --resume to "
            "finish it, or choose another --out"
        )

    def _grow(self, existing: dict[str, Any], experiments: int) -> None:
        """Record in config.json that a resume grew the run to ``experiments``."""
        stored = existing["protocol"]
        self.write_config(
            {
                **existing,
                "protocol": {**stored, "experiments": experiments},
                "experiments_grown_from": [
                    *existing.get("experiments_grown_from", []),
                    stored["experiments"],
                ],
            }
        )

    def remove_temporaries(self) -> None:
        """Delete the files a killed run was writing (never renamed into place)."""
        for stale in self.root.rglob(".*.tmp"):
            stale.unlink()

    # -- experiments ---------------------------------------------------------------------------------
    def finished(self, algorithm: str) -> set[int]:
        """The indices of ``algorithm``'s experiments whose results are saved (one directory listing:
        the cost grows with what has finished, not with what is planned)."""
        folder = self.root / "curves" / self._stored(algorithm)
        try:
            names = os.listdir(folder)
        except (FileNotFoundError, NotADirectoryError):
            return set()
        return {
            int(match.group(1)) for name in names if (match := _EXPERIMENT_FILE.fullmatch(name))
        }

    def _complete(self, protocol: dict[str, Any]) -> bool:
        """Every experiment of the protocol (as data) saved, and the summary written."""
        return self.summary_path.is_file() and all(
            sum(1 for i in self.finished(a) if i < protocol["experiments"])
            == protocol["experiments"]
            for a in protocol["algorithms"]
        )

    def holds_finished(self, protocol) -> bool:
        """Whether this directory holds ``protocol``'s run, finished: the same protocol, every
        experiment saved and the summary written."""
        stored = self.read_protocol()
        if stored is None:
            return False
        # Compared as data: making a Protocol of the stored one would build (and run) the
        # environment it names. A directory written before a field existed holds it at its default.
        now = protocol.as_dict()
        defaults = files.as_jsonable(
            {
                field.name: field.default
                if field.default is not dataclasses.MISSING
                else field.default_factory()
                for field in dataclasses.fields(protocol)
            }
        )
        same = set(stored) <= set(now) and {k: stored.get(k, defaults[k]) for k in now} == now
        return same and self._complete(stored)

    def experiment_problem(
        self,
        protocol,
        algorithm: str,
        index: int,
        snapshot_check: Callable[[dict[str, np.ndarray]], str | None] | None = None,
    ) -> str | None:
        """None when experiment ``index`` of ``algorithm`` is saved whole and as ``protocol`` says
        (its curve: the trials and greedy trials; every snapshot the protocol lists, and passes
        ``snapshot_check`` on its arrays: the run's learner can restore it); else what is wrong,
        naming the file."""
        every = protocol.evaluate_every
        greedy = [t for t in range(every, protocol.trials + 1, every)] if every else []
        path = self.curve_path(algorithm, index)
        problem = integrity.curve_problem(path, protocol.trials, greedy, protocol.steps)
        if problem is not None:
            return f"{path.relative_to(self.root)}: {problem}"
        snapshot_trials = protocol.snapshot_trials
        if protocol.steps is not None:  # the trials it ran, the last always saved
            ran = integrity.curve_trials(path)
            snapshot_trials = sorted({t for t in snapshot_trials if t <= ran} | {ran})
        for trial in snapshot_trials:
            path = self.snapshot_path(algorithm, index, trial)
            problem = integrity.snapshot_problem(path, algorithm, trial)
            if problem is None and snapshot_check is not None:
                problem = snapshot_check(self.read_snapshot_arrays(algorithm, index, trial))
            if problem is not None:
                return f"{path.relative_to(self.root)}: {problem}"
        return None

    def discard(self, algorithm: str, index: int) -> None:
        """Remove an experiment's curve and snapshots (before it is run again)."""
        self.curve_path(algorithm, index).unlink(missing_ok=True)
        self.checkpoint_path(algorithm, index).unlink(missing_ok=True)
        folder = self.snapshot_dir(algorithm, index)
        for path in folder.glob("*.npz") if folder.is_dir() else ():
            path.unlink()

    def save(self, result: ExperimentResult) -> None:
        """Write an experiment's snapshots, then its curve: the curve file marks the experiment done."""
        for trial, arrays in result.snapshots.items():
            files.write_npz(self.snapshot_path(result.algorithm, result.index, trial), **arrays)
        files.write_npz(
            self.curve_path(result.algorithm, result.index),
            returns=result.returns,
            greedy_trials=result.greedy_trials,
            greedy_returns=result.greedy_returns,
            wall_time_s=np.float64(result.wall_time_s),
            cpu_time_s=np.float64(result.cpu_time_s),
            task_seed=np.int64(result.task_seed),
            demonstration_returns=result.demonstration_returns,
            **({} if result.env_steps is None else {"env_steps": result.env_steps}),
        )
        self.checkpoint_path(result.algorithm, result.index).unlink(missing_ok=True)

    def load_curves(self, algorithm: str, experiments: int | None = None) -> Curves:
        """The curves of ``algorithm``'s experiments 0 .. ``experiments`` - 1 (all must be saved);
        None: every saved experiment, in order of index."""
        returns, greedy, wall, cpu, demonstrations, steps = [], [], [], [], [], []
        greedy_trials = np.zeros(0, dtype=int)
        indices = (
            range(experiments) if experiments is not None else sorted(self.finished(algorithm))
        )
        for index in indices:
            with np.load(self.curve_path(algorithm, index), allow_pickle=False) as data:
                returns.append(data["returns"])
                # written before environment steps were recorded: unknown (see Curves)
                steps.append(
                    data["env_steps"]
                    if "env_steps" in data.files
                    else np.full(data["returns"].shape, np.nan)
                )
                greedy.append(data["greedy_returns"])
                if data["greedy_trials"].size >= greedy_trials.size:
                    greedy_trials = data["greedy_trials"]
                wall.append(float(data["wall_time_s"]))
                cpu.append(float(data["cpu_time_s"]) if "cpu_time_s" in data.files else np.nan)
                demonstrations.append(data["demonstration_returns"])
        return Curves(
            returns=_padded(returns),
            greedy_returns=_padded(greedy),
            greedy_trials=greedy_trials,
            wall_times=np.array(wall),
            cpu_times=np.array(cpu),
            demonstration_returns=np.array(demonstrations),
            env_steps=_padded(steps),
        )

    # -- snapshots -----------------------------------------------------------------------------------
    def snapshot_algorithms(self) -> list[str]:
        """The learners with snapshots in this directory, sorted."""
        folder = self.root / "snapshots"
        names = [p.name for p in folder.iterdir() if p.is_dir()] if folder.is_dir() else []
        today = {stored: key for key, stored in self._renamed_keys().items()}
        return sorted(today.get(name, name) for name in names)

    def snapshot_trials(self, algorithm: str, index: int = 0) -> dict[int, pathlib.Path]:
        """Trial number -> snapshot path, for one experiment; MissingInputError when it has none."""
        folder = self.snapshot_dir(algorithm, index)
        found = {
            int(match.group(1)): path
            for path in folder.glob("trial_*.npz")
            if (match := _TRIAL_FILE.fullmatch(path.name))
        }
        if not found:
            raise MissingInputError(
                f"no snapshots in {folder} (algorithms with snapshots in "
                f"{self.root}: {self.snapshot_algorithms() or 'none'})"
            )
        return dict(sorted(found.items()))

    # -- summaries -----------------------------------------------------------------------------------
    def write_returns(self, rows: Iterator[tuple]) -> None:
        """``returns.csv``: one row (algorithm, experiment, trial, return, env_steps) per learning
        trial; env_steps, the environment steps taken by the end of the trial, is empty for curves
        written before they were counted."""
        files.write_csv(
            self.returns_path, ["algorithm", "experiment", "trial", "return", "env_steps"], rows
        )

    def write_summary(self, summary: dict[str, Any]) -> None:
        """``summary.json``; non-finite numbers (a learner that diverged) are written as null."""
        files.write_json(self.summary_path, files.finite_or_none(summary))

    def read_summary(self) -> dict[str, Any]:
        """The run's ``summary.json``; MissingInputError when the run has none (not finished)."""
        summary = documents.read_summary(self.summary_path)
        return with_learner_keys_of_today(summary) if self._renamed_keys() else summary

    def read_wall_times(self) -> list[dict[str, Any]]:
        """The parts recorded in ``wall_times.json`` (empty when there is none);
        :class:`UserInputError` naming the file when it is there but damaged."""
        return documents.read_wall_times(self.wall_times_path)

    def write_wall_times(self, parts: list[dict[str, Any]]) -> None:
        files.write_json(self.wall_times_path, {"parts": parts})


def _padded(rows: list[np.ndarray]) -> np.ndarray:
    """Rows of possibly different lengths as one float array of shape (rows, longest), NaN after
    each row's end (experiments of a budget in environment steps run different numbers of trials);
    rows of one length come back exactly as ``np.array(rows)``."""
    lengths = {len(row) for row in rows}
    if len(lengths) <= 1:
        return np.array(rows)
    padded = np.full((len(rows), max(lengths)), np.nan)
    for i, row in enumerate(rows):
        padded[i, : len(row)] = row
    return padded
