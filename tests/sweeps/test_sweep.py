"""Sweeps: the file format and its validation, a tiny sweep end to end (killed and resumed), and
``reproduce --config`` against the same ``--set`` overrides; a sweep's size counted, never
enumerated, and refused above its limit, and a learner too large for the memory refused before it
is built."""

import csv
import json
import pathlib
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from stoppable_run import hooked_cli  # tests/ is on sys.path

from rmac_mj import cli, constraints
from rmac_mj.errors import UserInputError
from rmac_mj.experiments import RunOptions
from rmac_mj.sweeps import (
    SweepFileError,
    format_table,
    load_configuration,
    load_sweep,
    run_sweep,
)

TINY = """
[protocol]
algorithms = ["s-ac"]
experiments = 2
trials = 3
evaluate_every = 3
snapshot_trials = [1]
[grid]
"s-ac.alpha_a" = [0.005, 0.02]
"""


def write(tmp_path, text, name="sweep.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def curves(out):
    return {
        p.relative_to(out).as_posix(): np.load(p, allow_pickle=False)["returns"]
        for p in sorted(pathlib.Path(out).glob("*/curves/*/exp_*.npz"))
    }


# ----------------------------------------------------------------------------------------------------
# The file format.


def test_grid_and_variants_cross_into_named_configurations(tmp_path):
    path = write(
        tmp_path,
        """
[protocol]
algorithms = ["rmac", "s-ac"]
experiments = 3
"s-ac.rate_split" = "actor"
[grid]
rmac.exploration.sigma = [0.5, 2]              # a bare dotted key means the same as a quoted one
"s-ac.exploration.sigma" = [1.0]
"rmac.critic.weights" = [[1, 0.1], [1, 0.3]]
[[variant]]
name = "paper"
[[variant]]
name = "oldest"
rmac.critic.replacement = "oldest"
""",
    )
    plan = load_sweep(path)
    assert plan.parameters == [
        "variant",
        "rmac.exploration.sigma",
        "s-ac.exploration.sigma",
        "rmac.critic.weights",
    ]
    names = [c.name for c in plan.configurations]
    assert len(names) == 2 * 2 * 1 * 2 == len(set(names))
    # The same last field in two learners keeps its learner in the name; others are shortened.
    assert (
        names[0] == "paper__rmac.exploration.sigma=0.5__s-ac.exploration.sigma=1.0__weights=1,0.1"
    )
    assert (
        names[-1] == "oldest__rmac.exploration.sigma=2__s-ac.exploration.sigma=1.0__weights=1,0.3"
    )
    last = plan.configurations[-1].protocol
    assert last.experiments == 3 and last.algorithms == ("rmac", "s-ac")
    assert last.agent_configs == {
        "rmac": {
            "exploration": {"sigma": 2},
            "critic": {"weights": [1, 0.3], "replacement": "oldest"},
        },
        "s-ac": {"rate_split": "actor", "exploration": {"sigma": 1.0}},
    }
    assert "replacement" not in plan.configurations[0].protocol.agent_configs["rmac"]["critic"]


@pytest.mark.parametrize(
    "text, named",
    [
        ("[grdi]\n", "[grdi]: unknown section (did you mean [grid]?)"),
        (
            "[protocol]\nexperimentz = 3\n",
            "[protocol] experimentz: unknown key (did you mean experiments?)",
        ),
        (
            '[grid]\n"rmac.alpha_rr" = [0.01]\n',
            "\"rmac.alpha_rr\": RMACConfig has no parameter 'alpha_rr' (did you mean 'rmac.alpha_r'?)",
        ),
        (
            '[grid]\n"rmac.critic_capacity" = [3000]\n',
            "\"rmac.critic_capacity\": RMACConfig has no parameter 'critic_capacity' "
            "(did you mean 'rmac.critic.capacity'?)",
        ),
        ('[grid]\n"rmac.exploration.sigmaa" = [1]\n', "Exploration has no parameter 'sigmaa'"),
        ('[grid]\n"dqn.alpha" = [1]\n', "\"dqn.alpha\": unknown algorithm 'dqn'"),
        (
            '[protocol]\nalgorithms = ["s-ac"]\n[grid]\n"rmac.alpha_r" = [0.01]\n',
            '"rmac.alpha_r": sets rmac, which the protocol does not run',
        ),
        (
            '[grid]\n"rmac.alpha_r" = ["fast"]\n',
            '"rmac.alpha_r" value "fast": expected a number in [0, 1]',
        ),
        (
            '[grid]\n"rmac.critic.capacity" = [2000.5]\n',
            '"rmac.critic.capacity" value 2000.5: expected an integer >= 1',
        ),
        (
            '[protocol]\nexperiments = "ten"\n',
            "[protocol] experiments: expected an integer in [1, 10000]",
        ),
        ('[grid]\n"rmac.alpha_r" = 0.01\n', '"rmac.alpha_r": expected a list of values to sweep'),
        (
            '[grid]\n"rmac.critic.weights" = [1, 0.1]\n',
            '"rmac.critic.weights" value 1: expected a list of finite numbers >= 0',
        ),
        (
            '[grid]\n"rmac.gamma" = [0.9, 1.5]\n',
            '"rmac.gamma" value 1.5: expected a number in [0, 1)',
        ),
        ('[grid]\n"rmac.critic.weights" = [[1, 0.1, 3]]\n', "config.critic.weights has 3 entries"),
        (
            '[protocol]\n"rmac.critic.replacement" = "newest"\n',
            "\"rmac.critic.replacement\": expected one of 'oldest', 'nearest', 'redundancy', or None, "
            'got "newest"',
        ),
        ('[grid]\n"rmac.alpha_r" = [0.01, 0.01]\n', '"rmac.alpha_r": repeats a value'),
        ('[[variant]]\n"rmac.alpha_r" = 0.01\n', "[[variant]] #1 name: each variant needs a name"),
        (
            '[grid]\n"rmac.alpha_r" = [0.01]\n[[variant]]\nname = "a"\n"rmac.alpha_r" = 0.02\n',
            '[[variant]] "a" "rmac.alpha_r": is also swept in [grid]',
        ),
        ("[grid\n", "not valid TOML"),
        (
            '[[variant]]\nname = "u"\n"rmac.exploration.where" = "uncertain"\n',
            '[[variant]] "u" "rmac.exploration.where": RMACConfig.exploration.uncertainty_threshold must be a finite number >= 0 with where=\'uncertain\'',
        ),
    ],
)
def test_a_malformed_file_names_the_key(tmp_path, text, named):
    with pytest.raises(UserInputError) as error:
        load_sweep(write(tmp_path, text))
    message = str(error.value)
    assert named in message and message.startswith(str(tmp_path / "sweep.toml"))
    assert "\n" not in message


STUDIES = sorted((pathlib.Path(__file__).parents[2] / "docs" / "studies").glob("*.toml"))


@pytest.mark.parametrize("path", STUDIES, ids=[path.stem for path in STUDIES])
def test_every_study_in_docs_loads(path):
    # The studies' files are commands the docs quote: a renamed config field must not leave one
    # that is refused when a reader runs it.
    assert load_sweep(path).configurations


def test_a_variant_sets_fields_that_depend_on_each_other(tmp_path):
    # Each key is checked with the variant's other values: where='uncertain' needs its threshold.
    plan = load_sweep(
        write(
            tmp_path,
            """
[[variant]]
name = "uncertain"
"rmac.exploration.where" = "uncertain"
"rmac.exploration.uncertainty_threshold" = 0.8
""",
        )
    )
    assert plan.configurations[0].protocol.agent_configs["rmac"] == {
        "exploration": {"where": "uncertain", "uncertainty_threshold": 0.8}
    }


@pytest.mark.slow
def test_a_malformed_file_exits_2_with_one_line_before_running_anything(tmp_path):
    path = write(tmp_path, '[protocol]\nalgorithms = ["s-ac"]\n[grid]\n"s-ac.alpha_a" = 0.01\n')
    result = subprocess.run(
        [sys.executable, "-m", "rmac_mj.cli", "sweep", str(path), "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        f'rmac-mj: error: {path}: [grid] "s-ac.alpha_a": expected a list of values to sweep, '
        "e.g. [0.01, ...]; got 0.01"
    ]
    assert not (tmp_path / "out").exists()


def test_a_config_file_takes_single_values_only(tmp_path):
    single = load_configuration(
        write(
            tmp_path,
            """
[protocol]
algorithms = ["rmac"]
trials = 5
"rmac.alpha_c" = 0.2
[grid]
"rmac.critic.weights" = [1, 0.3]     # one value of a list-valued field
"rmac.alpha_r" = [0.01]              # a one-value grid is one configuration
""",
        )
    )
    assert single.options == {"algorithms": ("rmac",), "trials": 5}
    assert single.agent_configs == {
        "rmac": {"alpha_c": 0.2, "critic": {"weights": [1, 0.3]}, "alpha_r": 0.01}
    }
    with pytest.raises(
        UserInputError,
        match=r'"rmac.alpha_r": lists 2 values; --config runs one '
        r"configuration",
    ):
        load_configuration(write(tmp_path, '[grid]\n"rmac.alpha_r" = [0.01, 0.02]\n'))
    with pytest.raises(UserInputError, match="2 variants"):
        load_configuration(write(tmp_path, '[[variant]]\nname = "a"\n[[variant]]\nname = "b"\n'))


# ----------------------------------------------------------------------------------------------------
# Running.


@pytest.mark.slow
def test_tiny_sweep_killed_resumed_and_summarised(tmp_path, capsys):
    path = write(tmp_path, TINY)
    killed, marker = tmp_path / "killed", tmp_path / "saved-one"
    args = [
        "sweep",
        str(path),
        "--jobs",
        "1",
        "--no-optimal",
        "--no-progress",
        "--out",
        str(killed),
    ]
    process = subprocess.Popen(
        [*hooked_cli(marker), *args], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    deadline = time.time() + 240
    while not marker.exists():
        assert process.poll() is None, "the sweep ended before saving its first experiment"
        assert time.time() < deadline
        time.sleep(0.02)
    process.send_signal(signal.SIGKILL)
    process.wait()
    assert len(curves(killed)) == 1 and not (killed / "sweep.csv").exists()
    assert cli.main([*args, "--resume"]) == 0  # in this process: the same command, no start-up
    assert "alpha_a=0.02" in capsys.readouterr().out

    # The same sweep uninterrupted, all experiments through one pool of two workers.
    whole = tmp_path / "whole"
    from rmac_mj.experiments import runner
    from rmac_mj.solvers import optimum

    service = runner.NearOptimalService
    with pytest.MonkeyPatch.context() as patch:  # the task's reference and floor, as if computed
        patch.setattr(optimum, "run_optimum", lambda protocol, log=None: -748.0)
        patch.setattr(
            optimum, "run_exploration_floor", lambda protocol, algorithm, log=None: -870.0
        )
        # in this process, where the patches are (a process of their own would compute them)
        patch.setattr(
            runner,
            "NearOptimalService",
            lambda protocols, log, background: service(protocols, log, background=False),
        )
        rows = run_sweep(
            load_sweep(path), whole, RunOptions(jobs=2, progress=False, references=True)
        )
    resumed_curves, whole_curves = curves(killed), curves(whole)
    assert sorted(resumed_curves) == sorted(whole_curves) and len(whole_curves) == 2 * 2
    for key in whole_curves:
        np.testing.assert_array_equal(resumed_curves[key], whole_curves[key])
    assert not np.array_equal(
        whole_curves["alpha_a=0.005/curves/s-ac/exp_000.npz"],
        whole_curves["alpha_a=0.02/curves/s-ac/exp_000.npz"],
    )

    for out in (killed, whole):
        with open(out / "sweep.csv", newline="") as handle:
            table = list(csv.DictReader(handle))
        assert [(r["configuration"], r["s-ac.alpha_a"], r["algorithm"]) for r in table] == [
            ("alpha_a=0.005", "0.005", "s-ac"),
            ("alpha_a=0.02", "0.02", "s-ac"),
        ]
        index = json.loads((out / "sweep.json").read_text())
        assert [c["directory"] for c in index["configurations"]] == [
            "alpha_a=0.005",
            "alpha_a=0.02",
        ]
    summary = json.loads((whole / "alpha_a=0.02" / "summary.json").read_text())
    assert summary["exploration_floor"] == -870.0 and summary["optimal_return"] == -748.0
    row = rows[1]
    assert row["final_return_mean"] == pytest.approx(summary["s-ac"]["final_return_mean"])
    assert row["gap_to_optimal"] == pytest.approx(-748.0 - row["final_return_mean"])
    assert row["greedy_trial"] == 3 and row["greedy_return_mean"] == pytest.approx(
        summary["s-ac"]["greedy_return_per_eval"][-1]
    )
    assert row["mean_return_first_5min"] is None  # a run shorter than the window: empty
    for metric in ("final_return", "greedy_return", "minutes_to_90pct", "gap_to_optimal"):
        assert (whole / f"sweep_{metric}.png").is_file(), metric
    assert not (whole / "sweep_first_5min.png").exists()  # no window in a 9 s run: nothing drawn
    with pytest.raises(UserInputError, match="already holds a sweep"):
        run_sweep(load_sweep(path), whole, RunOptions(jobs=1, progress=False))
    other = write(tmp_path, TINY.replace("0.02]", "0.03]"), "other.toml")
    with pytest.raises(UserInputError, match="a different file"):
        run_sweep(load_sweep(other), whole, RunOptions(jobs=1, resume=True, progress=False))


@pytest.mark.slow
def test_a_resumed_sweep_adds_experiments_to_every_configuration(tmp_path):
    out = tmp_path / "out"
    run_sweep(
        load_sweep(write(tmp_path, TINY)), out, RunOptions(jobs=1, progress=False, figures=False)
    )
    larger = write(tmp_path, TINY.replace("experiments = 2", "experiments = 3"), "larger.toml")
    with pytest.raises(UserInputError, match="already holds a sweep"):
        run_sweep(load_sweep(larger), out, RunOptions(jobs=1, progress=False, figures=False))
    rows = run_sweep(
        load_sweep(larger), out, RunOptions(jobs=1, resume=True, progress=False, figures=False)
    )
    assert [r["experiments"] for r in rows] == [3, 3] and len(curves(out)) == 2 * 3
    index = json.loads((out / "sweep.json").read_text())
    assert index["sweep"]["protocol"]["experiments"] == 3 and index["experiments_grown_from"] == [2]
    assert (out / "sweep.toml").read_text() == larger.read_text()
    fresh = tmp_path / "fresh"
    run_sweep(load_sweep(larger), fresh, RunOptions(jobs=1, progress=False, figures=False))
    grown_curves, fresh_curves = curves(out), curves(fresh)
    for key in fresh_curves:
        np.testing.assert_array_equal(grown_curves[key], fresh_curves[key])
    smaller = write(tmp_path, TINY, "smaller.toml")  # a resume never drops experiments
    with pytest.raises(UserInputError, match="a resume may only add experiments"):
        run_sweep(load_sweep(smaller), out, RunOptions(jobs=1, resume=True, progress=False))
    both = write(
        tmp_path,
        TINY.replace("experiments = 2", "experiments = 4").replace("trials = 3", "trials = 4"),
        "both.toml",
    )
    with pytest.raises(UserInputError, match="a different file"):
        run_sweep(load_sweep(both), out, RunOptions(jobs=1, resume=True, progress=False))


@pytest.mark.slow
def test_a_small_sweep_says_its_final_window_and_that_few_experiments_mean_little(
    tmp_path, monkeypatch
):
    """Issue 20: sweep tables and figures said "the last 50 trials" of a 5-trial run and drew 95%
    intervals of 2 experiments without a word; they carry reproduce's small-n note."""
    from rmac_mj.sweeps import figure as plots

    plan = load_sweep(write(tmp_path, TINY))

    def rows(experiments):
        return [
            {
                "configuration": c.name,
                **c.values,
                "algorithm": "s-ac",
                "experiments": experiments,
                "final_return_mean": -900.0,
                "final_return_ci95_low": -2600.0,
                "final_return_ci95_high": 800.0,
                "minutes_to_90pct": 0.1,
                "mean_return_first_5min": -900.0,
                "first_5min_ci95_low": -2600.0,
                "first_5min_ci95_high": 800.0,
                "stuck_experiments": None,
                "wall_time_s": 1.0,
                "final_window": 3,
                "stuck_below": None,
            }
            for c in plan.configurations
        ]

    few, enough = format_table(plan, rows(2)), format_table(plan, rows(5))
    assert "final return: mean of the last 3 trials per experiment" in few
    assert "final return: mean of the last 3 trials per experiment" in enough
    assert "note: 2 experiments per learner: too few to rank the learners" in few
    assert "note:" not in enough

    close, drawn = plots.plt.close, []
    monkeypatch.setattr(plots.plt, "close", drawn.append)  # keep the figures to read their texts
    try:
        notes = {}
        for experiments in (2, 5):
            drawn.clear()
            plots.plot_sweep(plan, rows(experiments), tmp_path)
            texts = {fig.axes[0].get_ylabel(): [t.get_text() for t in fig.texts] for fig in drawn}
            assert "final return (mean of the last 3 trials)" in texts
            notes[experiments] = texts
            for fig in drawn:
                close(fig)
    finally:
        monkeypatch.undo()
    interval = "2 experiments per configuration: 95% intervals from fewer than 5 mean little"
    assert interval in notes[2]["final return (mean of the last 3 trials)"]
    assert interval in notes[2]["mean return of the first 5 simulated minutes"]
    wall_time = notes[2]["wall time of its experiments, summed [s]"]  # no interval drawn, no note
    assert not any("per configuration" in text for text in wall_time)
    assert not any("per configuration" in text for texts in notes[5].values() for text in texts)


@pytest.mark.parametrize(
    "text, named",
    [
        ('{"sweep": {"protocol"', "is damaged (Expecting ':' delimiter"),
        ("[1, 2]", "is damaged (not a sweep's index"),
    ],
)
def test_a_damaged_sweep_index_is_one_line_not_a_traceback(tmp_path, capsys, text, named):
    out = tmp_path / "sweep"
    out.mkdir()
    (out / "sweep.json").write_text(text)
    assert (
        cli.main(
            [
                "sweep",
                str(write(tmp_path, TINY)),
                "--resume",
                "--jobs",
                "1",
                "--no-optimal",
                "--no-progress",
                "--out",
                str(out),
            ]
        )
        == 2
    )
    errors = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert len(errors) == 1 and named in errors[0] and "sweep.json" in errors[0]
    assert not any(p.is_dir() for p in out.iterdir())  # nothing ran


@pytest.mark.slow
def test_reproduce_config_equals_the_same_set_overrides(tmp_path, capsys):
    path = write(
        tmp_path,
        """
[protocol]
algorithms = ["s-ac"]
experiments = 1
trials = 5                           # the command line's --trials 3 wins
seed = 7
[grid]
"s-ac.alpha_a" = 0.02
"s-ac.exploration.sigma" = 0.5
""",
        "one.toml",
    )
    common = ["--jobs", "1", "--no-optimal", "--no-progress"]
    assert (
        cli.main(
            [
                "reproduce",
                "--config",
                str(path),
                "--trials",
                "3",
                "--set",
                "s-ac.exploration.period=2",
                "--out",
                str(tmp_path / "config"),
                *common,
            ]
        )
        == 0
    )
    assert (
        cli.main(
            [
                "reproduce",
                "--algorithms",
                "s-ac",
                "--experiments",
                "1",
                "--trials",
                "3",
                "--seed",
                "7",
                "--set",
                "s-ac.alpha_a=0.02",
                "--set",
                "s-ac.exploration.sigma=0.5",
                "--set",
                "s-ac.exploration.period=2",
                "--out",
                str(tmp_path / "set"),
                *common,
            ]
        )
        == 0
    )
    from_config = json.loads((tmp_path / "config" / "config.json").read_text())["protocol"]
    from_set = json.loads((tmp_path / "set" / "config.json").read_text())["protocol"]
    assert from_config == from_set
    assert from_config["trials"] == 3 and from_config["agent_configs"] == {
        "s-ac": {"alpha_a": 0.02, "exploration": {"sigma": 0.5, "period": 2}}
    }
    np.testing.assert_array_equal(
        *(np.load(tmp_path / d / "curves/s-ac/exp_000.npz")["returns"] for d in ("config", "set"))
    )

    grid = write(
        tmp_path, '[protocol]\nalgorithms = ["s-ac"]\n[grid]\n"s-ac.alpha_a" = [0.01, 0.02]\n'
    )
    assert cli.main(["reproduce", "--config", str(grid), "--out", str(tmp_path / "x")]) == 2
    assert "lists 2 values; --config runs one configuration" in capsys.readouterr().err


def test_a_sweep_takes_its_size_from_the_command_line_over_the_files(tmp_path, capsys):
    """Issue 39: ``sweep --experiments 1 --trials 2`` runs a study's file at a smaller size (no
    copy to edit); the table claims no interval it does not print, and a resume at another size is
    refused."""
    path = write(tmp_path, TINY.replace("evaluate_every = 3", "evaluate_every = 2"))
    out = tmp_path / "out"
    args = ["sweep", str(path), "--experiments", "1", "--trials", "2", "--no-optimal"]
    assert cli.main([*args, "--no-progress", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "with --experiments 1 --trials 2: 2 configurations x 1 experiments" in captured.err
    assert {name: len(r) for name, r in curves(out).items()} == {
        "alpha_a=0.005/curves/s-ac/exp_000.npz": 2,
        "alpha_a=0.02/curves/s-ac/exp_000.npz": 2,
    }
    index = json.loads((out / "sweep.json").read_text())
    assert index["command_line_sizes"] == {"experiments": 1, "trials": 2}
    header = next(line for line in captured.out.splitlines() if line.startswith("configuration"))
    assert "final return " in header and "95% CI" not in header  # 1 experiment: no interval
    assert "greedy at end" in header
    assert "greedy at end: the greedy evaluation after trial 2" in captured.out
    # the same folder at the file's own size is another sweep
    assert cli.main(["sweep", str(path), "--no-progress", "--resume", "--out", str(out)]) == 2
    assert "different file or size" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["sweep", "--help"])
    assert "run every configuration of a sweep file" in capsys.readouterr().out


# -- sizes -------------------------------------------------------------------------------------------

MEMORIES = ("process", "reference", "critic")


def test_a_grid_of_a_trillion_configurations_is_refused_at_once(tmp_path):
    rates = [0.001 * (k + 1) for k in range(10)]
    counts = list(range(1, 11))
    grid = {
        **{f"rmac.{key}": rates for key in ("alpha_r", "alpha_c", "gamma", "lam")},
        "rmac.exploration.sigma": rates,
        "rmac.exploration.period": counts,
        **{f"rmac.{memory}.capacity": [100 * n for n in counts] for memory in MEMORIES},
        **{f"rmac.{memory}.neighbours": counts for memory in MEMORIES},
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
