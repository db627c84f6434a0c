"""Smoke test of `rmac-mj bench`: it runs and its JSON has the documented keys (no timing asserts)."""

import json
import subprocess
import sys


def test_bench_runs_and_writes_the_documented_keys(tmp_path):
    path = tmp_path / "bench.json"
    result = subprocess.run([sys.executable, "-m", "rmac_mj.cli", "bench", "--quick", "--json",
                             str(path)], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    assert "env.step" in result.stdout and "x env.step" in result.stdout
    report = json.loads(path.read_text())
    for key in ("physics_step_us", "env_step_us", "llr_query_insert_us", "sac_step_us",
                "rmac_step_us", "protocol_projected_min"):
        assert isinstance(report[key], float) and report[key] > 0, key
    assert set(report["experiment_wall_s"]) == {"s-ac", "rmac"}
    assert report["machine"]["cores"] >= 1 and report["machine"]["cpu"]
