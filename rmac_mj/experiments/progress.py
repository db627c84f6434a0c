"""The progress display of a run or a sweep: trials or environment steps done (the run's budget's
unit), rate, time left, recent returns.

Workers stream every trial to their experiment's live log (``ResultStore.progress_path``);
:class:`TrialFeed` follows those logs and feeds :class:`Progress`.
"""

from __future__ import annotations

import collections
import math
import pathlib
import sys
import time
from collections.abc import Sequence
from typing import TextIO

import numpy as np

#: An experiment in a display: (run, algorithm, index), ``run`` being the position of its protocol.
Key = tuple[int, str, int]


def duration(seconds: float) -> str:
    """``"42 s"``, ``"3 min 05 s"`` or ``"2 h 07 min"``."""
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds} s"
    minutes, seconds = divmod(seconds, 60)
    if minutes < 60:
        return f"{minutes} min {seconds:02d} s"
    return f"{minutes // 60} h {minutes % 60:02d} min"


def _is_terminal(stream: TextIO) -> bool:
    isatty = getattr(stream, "isatty", None)
    try:
        return bool(isatty and isatty())
    except ValueError:  # a closed stream
        return False


class Progress:
    """The run's progress in the units it is budgeted in, overall and per learner, with the mean
    return of each learner's last trials.

    A run budgeted in environment steps (every protocol has ``steps``) counts the steps its
    experiments took of the steps asked, and its trials as they come; otherwise it counts trials of
    the trials asked. One display for one run or for several (a sweep): the learners' bars count
    over all runs. On a terminal: tqdm bars (rate, time left). Otherwise (nohup, a Slurm log, a
    pipe): a plain line every ``interval`` seconds and at the end, without carriage returns or
    escape codes. Progress is made as the experiments report their trials (:meth:`trial`), and by
    the rest of an experiment's budget when it finishes (:meth:`experiment`).

    Args:
      protocols: the runs' protocols (anything with ``algorithms``, ``experiments``, ``trials`` and
        ``steps``).
      finished: per run, how many experiments of each learner were already done before this start.
    """

    #: Trials over which the live mean return is taken, per learner.
    RECENT = 10

    def __init__(
        self,
        protocols: Sequence,
        finished: Sequence[dict[str, int]],
        enabled: bool,
        stream: TextIO | None = None,
        interval: float = 10.0,
    ):
        self.algorithms = list(dict.fromkeys(a for p in protocols for a in p.algorithms))
        #: "step" (environment steps) when every run is budgeted in them, else "trial".
        self.unit = (
            "step"
            if protocols and all(getattr(p, "steps", None) is not None for p in protocols)
            else "trial"
        )
        #: What one experiment of each run is to do, in the display's unit.
        self.budget = {
            k: p.steps if self.unit == "step" else p.trials for k, p in enumerate(protocols)
        }
        self.runs = len(protocols)
        self.runs_left = {
            k: sum(p.experiments - finished[k].get(a, 0) for a in p.algorithms)
            for k, p in enumerate(protocols)
        }
        self.runs_done = sum(1 for left in self.runs_left.values() if left == 0)
        self._count(protocols, finished)
        # per experiment in flight: (trials reported, progress credited)
        self.credited: dict[Key, tuple[int, int]] = {}
        self.recent = {a: collections.deque(maxlen=self.RECENT) for a in self.algorithms}
        self.stream = sys.stderr if stream is None else stream
        self.enabled = enabled
        # tqdm.auto draws widgets in a notebook, whose stderr is no terminal either
        self.plain = enabled and not (_is_terminal(self.stream) or "ipykernel" in sys.modules)
        self.interval = interval
        self.started = time.monotonic()
        self.last_trial = self.started  # when progress was last made: the rate's end
        self.first_progress = self.progressed["all"]
        self.last_line = -math.inf
        self.bars = {}
        if not enabled:
            return
        if self.plain:
            self._line()
            return
        self._open_bars()

    def _count(self, protocols: Sequence, finished: Sequence[dict[str, int]]) -> None:
        """The counts the display starts from, each per learner over the runs and in all: the
        experiments, those done, the progress to make and made, the trials run."""

        def over_runs(amount) -> dict[str, int]:
            totals = {
                a: sum(amount(k, p, a) for k, p in enumerate(protocols) if a in p.algorithms)
                for a in self.algorithms
            }
            return {"all": sum(totals.values()), **totals}

        self.experiments = over_runs(lambda k, p, a: p.experiments)
        self.done = over_runs(lambda k, p, a: finished[k].get(a, 0))
        self.total = over_runs(lambda k, p, a: p.experiments * self.budget[k])
        self.progressed = over_runs(lambda k, p, a: finished[k].get(a, 0) * self.budget[k])
        #: Trials run, counted as they come (with steps: those of this start only).
        self.trials_run = over_runs(
            lambda k, p, a: 0 if self.unit == "step" else finished[k].get(a, 0) * p.trials
        )

    def _open_bars(self) -> None:
        """A tqdm bar for all learners, then one per learner (on a terminal)."""
        from tqdm.auto import tqdm

        for position, key in enumerate(["all", *self.algorithms]):
            label = (
                ("all learners" if self.runs == 1 else f"{self.runs} runs") if key == "all" else key
            )
            self.bars[key] = tqdm(
                total=self.total[key],
                initial=self.progressed[key],
                file=self.stream,
                desc=f"{label:>12}",
                unit=self.unit,
                unit_scale=self.unit == "step",
                position=position,
                dynamic_ncols=True,
            )
            self.bars[key].set_postfix_str(self._postfix(key))

    def _recent_mean(self, algorithm: str) -> str:
        recent = self.recent[algorithm]
        return f"last {len(recent)} trials {np.mean(recent):.0f}" if recent else "no trial yet"

    def _postfix(self, key: str) -> str:
        text = f"{self.done[key]}/{self.experiments[key]} experiments"
        if self.unit == "step":
            text = f"{self.trials_run[key]} trials, {text}"
        if key != "all":
            return f"{text}, {self._recent_mean(key)}"
        return text if self.runs == 1 else f"{text}, {self.runs_done}/{self.runs} runs done"

    def trial(self, key: Key, trial: int, value: float, env_steps: int | None = None) -> None:
        """Experiment ``key`` finished learning trial ``trial`` with return ``value``, having taken
        ``env_steps`` environment steps so far (None: not known; a run budgeted in steps then
        advances when the experiment finishes)."""
        trials, previous = self.credited.get(key, (0, 0))
        if trial <= trials:
            return
        if self.unit == "step":
            reached = previous if env_steps is None else min(int(env_steps), self.budget[key[0]])
        else:
            reached = trial
        reached = max(reached, previous)
        self.credited[key] = (trial, reached)
        self.recent[key[1]].append(value)
        self._advance(key[1], reached - previous, trial - trials)

    def experiment(self, key: Key, returns: np.ndarray | None = None) -> None:
        """Experiment ``key`` finished (and is saved); ``returns``: its learning curve, whose trials
        not yet reported join the recent mean (and, in steps, the trials run)."""
        run, algorithm, _ = key
        trials, previous = self.credited.pop(key, (0, 0))
        unreported = 0
        if returns is not None:
            returns = np.asarray(returns, dtype=float)
            unreported = max(0, len(returns) - trials)
            self.recent[algorithm].extend(returns[trials:][-self.RECENT :])
        elif self.unit == "trial":
            unreported = self.budget[run] - trials
        self.done["all"] += 1
        self.done[algorithm] += 1
        self.runs_left[run] -= 1
        if self.runs_left[run] == 0:
            self.runs_done += 1
        self._advance(algorithm, self.budget[run] - previous, unreported)

    def _advance(self, algorithm: str, amount: int, trials: int) -> None:
        self.last_trial = time.monotonic()
        for key in ("all", algorithm):
            self.progressed[key] += amount
            self.trials_run[key] += trials
            if key in self.bars:
                self.bars[key].set_postfix_str(self._postfix(key), refresh=False)
                self.bars[key].update(amount)
        self.tick()

    def tick(self) -> None:
        """In plain mode, print a line if ``interval`` seconds passed since the last one."""
        if self.plain and time.monotonic() - self.last_line >= self.interval:
            self._line()

    def _amount(self, key: str) -> str:
        """``"120/600 trials"``, or ``"12000/80000 env steps, 312 trials"``."""
        if self.unit == "step":
            return (
                f"{self.progressed[key]}/{self.total[key]} env steps, {self.trials_run[key]} trials"
            )
        return f"{self.progressed[key]}/{self.total[key]} trials"

    def _line(self) -> None:
        elapsed = time.monotonic() - self.started
        total, done = self.total["all"], self.progressed["all"]
        # progress per second of the experiments' own time: a wait after the last one (the summary
        # waiting for the near-optimal reference, the figures) does not slow it down
        learning = (self.last_trial if done >= total else time.monotonic()) - self.started
        rate = (done - self.first_progress) / learning if learning > 0 else 0.0
        eta = f", about {duration((total - done) / rate)} left" if rate > 0 and done < total else ""
        runs = "" if self.runs == 1 else f", {self.runs_done}/{self.runs} runs"
        parts = [
            f"[{duration(elapsed)}] {self._amount('all')} ({self.done['all']}/"
            f"{self.experiments['all']} experiments{runs}), {rate:.0f} {self.unit}s/s{eta}"
        ]
        for algorithm in self.algorithms:
            parts.append(f"{algorithm} {self._amount(algorithm)}, {self._recent_mean(algorithm)}")
        print(" | ".join(parts), file=self.stream, flush=True)
        self.last_line = time.monotonic()

    def close(self) -> None:
        if self.plain:  # the final state
            self._line()
        for bar in self.bars.values():
            bar.close()


class TrialFeed:
    """Follows the live trial logs of the experiments in flight and reports their trials to a
    :class:`Progress` display."""

    def __init__(self, progress: Progress):
        self.files: dict[Key, pathlib.Path] = {}
        self.offsets: dict[Key, int] = {}
        self.progress = progress

    def watch(self, key: Key, path: pathlib.Path) -> None:
        """Follow experiment ``key``'s live log at ``path`` (it may not exist yet)."""
        self.files[key] = path

    def poll(self) -> None:
        for key, path in self.files.items():
            try:
                with open(path, "rb") as handle:
                    handle.seek(self.offsets.get(key, 0))
                    chunk = handle.read()
            except FileNotFoundError:
                continue
            end = chunk.rfind(b"\n") + 1  # complete lines only; the rest is still being written
            if not end:
                continue
            self.offsets[key] = self.offsets.get(key, 0) + end
            for line in chunk[:end].decode("utf-8").splitlines():
                fields = line.split(",")  # trial,return,greedy_return[,env_steps]
                if fields[0] != "trial":
                    steps = int(fields[3]) if len(fields) > 3 and fields[3] else None
                    self.progress.trial(key, int(fields[0]), float(fields[1]), steps)
        self.progress.tick()

    def finished(self, key: Key) -> None:
        self.files.pop(key, None)
        self.offsets.pop(key, None)
