"""A run the tests can stop at a known point: the command line in a subprocess that blocks after
its first saved experiment (for kill, resume and signal tests in several rooms)."""

import pathlib
import subprocess
import sys
import time


def hooked_cli(marker: pathlib.Path) -> list[str]:
    """``python -c`` running the CLI with one change: after the driver saves its first experiment it
    touches ``marker`` and blocks, so a signal sent once ``marker`` exists lands with exactly one
    experiment saved, however fast or loaded the machine is."""
    script = (
        "import pathlib, sys, time\n"
        "from rmac_mj.experiments import runner\n"
        "from rmac_mj.results.store import ResultStore\n"
        "save = ResultStore.save\n"
        "def save_then_wait(store, result):\n"
        "    save(store, result)\n"
        f"    pathlib.Path({str(marker)!r}).touch()\n"
        "    time.sleep(600)\n"
        "ResultStore.save = save_then_wait\n"
        "from rmac_mj.cli import main\n"
        "sys.exit(main(sys.argv[1:]))\n"
    )
    return [sys.executable, "-c", script]


def wait_for(path: pathlib.Path, process: subprocess.Popen, timeout: float = 240) -> None:
    deadline = time.time() + timeout
    while not path.exists():
        assert process.poll() is None, "the run ended before saving its first experiment"
        assert time.time() < deadline, f"no experiment saved within {timeout} s"
        time.sleep(0.02)
