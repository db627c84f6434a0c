"""A sweep's size is counted, never enumerated, and refused above its limit; a learner of a sweep
too large for the memory is refused before it is built."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time

import pytest

from rmac_mj import constraints
from rmac_mj.sweeps import SweepFileError, load_sweep

MEMORIES = ("process", "reference", "critic")


def test_a_grid_of_a_trillion_configurations_is_refused_at_once(tmp_path):
    rates = [0.001 * (k + 1) for k in range(10)]
    counts = list(range(1, 11))
    grid = {
        **{f"rmac.{key}": rates for key in ("alpha_r", "alpha_c", "gamma", "lam")},
        "rmac.exploration.sigma": rates,
        "rmac.exploration.period": counts,
        **{f"rmac.{memory}_capacity": [100 * n for n in counts] for memory in MEMORIES},
        **{f"rmac.{memory}_neighbours": counts for memory in MEMORIES},
    }
    grid = "\n".join(f'"{key}" = {values}' for key, values in grid.items())
    path = tmp_path / "huge.toml"
    path.write_text(f'[protocol]\nalgorithms = ["rmac"]\n[grid]\n{grid}\n')
    heard = []
    started = time.perf_counter()
    with pytest.raises(SweepFileError) as refused:
        load_sweep(path, announce=heard.append)
    assert time.perf_counter() - started < 2.0
    message = str(refused.value)
    assert f"must be at most {constraints.SWEEP_CONFIGURATIONS.value}" in message
    assert "got 1000000000000 (10 x 10 x 10" in message and "\n" not in message
    assert heard == []  # nothing announced, nothing enumerated


@pytest.mark.slow
def test_a_sweep_of_a_tiling_too_large_is_refused_before_its_learner_is_built(tmp_path):
    path = tmp_path / "tiles.toml"
    path.write_text(
        '[protocol]\nalgorithms = ["s-ac"]\nexperiments = 1\ntrials = 1\n'
        '[grid]\n"s-ac.tile_coding.num_tilings" = [16, 1000000000]\n'
    )
    script = textwrap.dedent(
        f"""
        import resource, sys
        resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, 4 * 2**30))
        from rmac_mj.cli import main
        sys.exit(main(["sweep", {str(path)!r}, "--out", {str(tmp_path / "out")!r}]))
        """
    )
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 2, result.stderr
    last = result.stderr.strip().splitlines()[-1]
    assert 'num_tilings" = 1000000000' in last and "needs about" in last, result.stderr
    assert "MemoryError" not in result.stderr and "Traceback" not in result.stderr
