"""What the command-line tests share: one finished run, made once by ``rmac-mj reproduce``."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import pathlib

import pytest

from rmac_mj.cli import main


@dataclasses.dataclass(frozen=True)
class FinishedRun:
    """A run ``rmac-mj COMMAND --out OUT`` finished, and what it printed on stdout. Tests that
    change it work on a copy."""

    command: list[str]
    out: pathlib.Path
    stdout: str


@pytest.fixture(scope="session")
def finished_run(tmp_path_factory) -> FinishedRun:
    command = ["reproduce", "--algorithms", "s-ac", "--experiments", "2", "--trials", "3"]
    command += ["--jobs", "1", "--no-optimal", "--no-progress"]
    out = tmp_path_factory.mktemp("finished") / "run"
    printed, said = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(printed), contextlib.redirect_stderr(said):
        code = main([*command, "--out", str(out)])
    assert code == 0, said.getvalue()
    return FinishedRun(command, out, printed.getvalue())
