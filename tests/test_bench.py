"""Smoke test of `rmac-mj bench`: it runs and its JSON has the documented keys (no timing asserts)."""

import json
import subprocess
import sys

from rmac_mj.experiments import bench


def test_bench_runs_and_writes_the_documented_keys(tmp_path):
    path = tmp_path / "bench.json"
    result = subprocess.run([sys.executable, "-m", "rmac_mj.cli", "bench", "--quick", "--json",
                             str(path)], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    assert "x raw step" in result.stdout and "x env.step" in result.stdout
    assert "real run, measured" in result.stdout
    report = json.loads(path.read_text())
    for key in ("physics_step_us", "env_step_us", "llr_query_insert_us", "sac_step_us",
                "rmac_step_us", "mlac_step_us", "protocol_projected_min"):
        assert isinstance(report[key], float) and report[key] > 0, key
    for key in ("env_overhead_us", "glue_step_us", "outside_physics_learner_us"):
        assert isinstance(report[key], float), key  # differences of timings: may be tiny or noisy
    # Every per-step figure also as a multiple of the raw control step.
    assert set(report["x_physics_step"]) == {key for key, _ in bench.ROWS}
    assert report["x_physics_step"]["physics_step_us"] == 1.0
    assert report["x_physics_step"]["env_step_us"] == report["env_step_us"] / report["physics_step_us"]
    assert set(report["experiment_s"]) == {"s-ac", "rmac"}
    assert report["steps_per_trial"] == 100
    run = report["run"]
    assert run["workers"] == 2 and run["steps"] == 2 * run["experiments_per_learner"] * run["trials"] * 100
    for key in ("wall_s", "physics_s", "x_physics", "in_experiments_s", "in_experiments_x_physics"):
        assert isinstance(run[key], float) and run[key] > 0, key
    assert run["x_physics"] == run["wall_s"] / run["physics_s"]
    assert run["cpu_s"] is None or run["cpu_x_physics"] == run["cpu_s"] / run["physics_s"]
    assert report["machine"]["cores"] >= 1 and report["machine"]["cpu"]
    markdown = bench.format_markdown(report)  # the README's table, from the same report
    assert report["machine"]["cpu"] in markdown
    assert len([line for line in markdown.splitlines() if line.startswith("| ")]) == len(bench.ROWS) + 5
