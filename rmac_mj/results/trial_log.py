"""The live log of one running experiment (:class:`TrialLog`): a CSV flushed after every trial."""

from __future__ import annotations

import pathlib


class TrialLog:
    """The live log of one experiment: a CSV (``trial,return,greedy_return,env_steps``; the last: the
    environment steps taken so far) flushed after every trial,
    so ``tail -f`` or pandas can follow a run. Not atomic and rewritten when a resumed run repeats the
    experiment: it is a view of a run in progress, not a result."""

    HEADER = "trial,return,greedy_return,env_steps\n"

    def __init__(self, path: pathlib.Path | None):
        self.path, self.handle = path, None

    def __enter__(self) -> TrialLog:
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.handle = open(self.path, "w", encoding="utf-8")
            self.handle.write(self.HEADER)
            self.handle.flush()
        return self

    def write(
        self, trial: int, value: float, greedy: float | None, env_steps: int | None = None
    ) -> None:
        if self.handle is not None:
            text = "" if greedy is None else repr(float(greedy))
            steps = "" if env_steps is None else str(int(env_steps))
            self.handle.write(f"{trial},{float(value)!r},{text},{steps}\n")
            self.handle.flush()

    def __exit__(self, *exc) -> None:
        if self.handle is not None:
            self.handle.close()
