"""The command line: bad arguments give one clear line and a non-zero exit, not a traceback."""

import subprocess
import sys

import pytest


def rmac_mj(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "rmac_mj.cli", *args], capture_output=True,
                          text=True, timeout=120, cwd=cwd)


@pytest.mark.parametrize("args, message", [
    (["reproduce", "--experiments", "-2"], "positive integer"),
    (["reproduce", "--trials", "zero"], "positive integer"),
    (["reproduce", "--algorithms", "rmac,dqn", "--out", "{tmp}/x"], "unknown algorithm 'dqn'"),
    (["reproduce", "--out", "{tmp}/file/sub"], "cannot write"),
    (["policy", "{tmp}/missing.npz"], "no snapshot"),
    (["compare", "{tmp}"], "no summary.json"),
    (["render", "--out", "{tmp}/x.mp4"], "exactly one of"),
    (["reproduce", "--domain", "cartpole", "--out", "{tmp}/x"], "unknown domain 'cartpole'"),
    (["reproduce", "--task", "spin", "--out", "{tmp}/x"], "unknown task 'spin'"),
    (["bench", "--domain", "cartpole"], "unknown domain_name 'cartpole'"),
    (["policy", "{tmp}/missing.npz", "--dims", "1"], "two state dimensions"),
    (["render", "--progression", "{tmp}", "--task", "swingup", "--out", "{tmp}/x.mp4"],
     "single SNAPSHOT"),
])
def test_bad_arguments_give_one_line(tmp_path, args, message):
    (tmp_path / "file").write_text("not a directory")
    result = rmac_mj(*[a.replace("{tmp}", str(tmp_path)) for a in args])
    assert result.returncode == 2
    assert message in result.stderr
    assert "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_reproduce_and_compare_and_policy(tmp_path):
    out = tmp_path / "run"
    result = rmac_mj("reproduce", "--algorithms", "s-ac", "--experiments", "2", "--trials", "3",
                     "--jobs", "1", "--out", str(out), "--no-optimal", "--no-progress")
    assert result.returncode == 0, result.stderr
    assert "s-ac" in result.stdout and "final return" in result.stdout
    result = rmac_mj("compare", str(out), str(out), "--out", str(tmp_path / "cmp"))
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "cmp.png").is_file()
    result = rmac_mj("policy", str(out / "snapshots/s-ac/exp_000/trial_0003.npz"), "--out",
                     str(tmp_path / "policy"))
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "policy.png").is_file()


def test_set_overrides_parse_into_nested_agent_configs():
    from rmac_mj.cli import UsageError, parse_overrides

    assert parse_overrides(["rmac.exploration.sigma=0.5", "s-ac.rate_split=actor",
                            "s-ac.tile_high=[null, 60]"]) == {
        "rmac": {"exploration": {"sigma": 0.5}},
        "s-ac": {"rate_split": "actor", "tile_high": [None, 60]}}
    for bad in ("rmac", "rmac=1", "sigma=0.5", "rmac..x=1"):
        with pytest.raises(UsageError, match="ALGO.FIELD=VALUE"):
            parse_overrides([bad])


def test_unknown_hyperparameter_is_one_line(tmp_path):
    result = rmac_mj("reproduce", "--algorithms", "s-ac", "--out", str(tmp_path / "x"),
                     "--set", "s-ac.bogus=1")
    assert result.returncode == 2 and "unknown hyperparameters ['bogus']" in result.stderr


def test_a_bug_keeps_its_traceback(tmp_path):
    """Only bad user input is shortened to one line; a ValueError from inside the code is a bug."""
    script = (
        "import sys\n"
        "from rmac_mj.experiments import runner\n"
        "def broken(*args, **kwargs):\n"
        "    raise ValueError('deep inside a learner')\n"
        "runner.run_protocol = broken\n"
        "from rmac_mj.cli import main\n"
        f"sys.exit(main(['reproduce', '--out', {str(tmp_path / 'x')!r}, '--no-progress']))\n")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 1
    assert "Traceback" in result.stderr and "deep inside a learner" in result.stderr


def test_bad_hyperparameter_value_is_one_line(tmp_path):
    result = rmac_mj("reproduce", "--algorithms", "rmac", "--out", str(tmp_path / "x"),
                     "--set", "rmac.gamma=1.5")
    assert result.returncode == 2 and "RMACConfig.gamma must be in [0, 1]" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
