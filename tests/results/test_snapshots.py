"""Snapshots: a learner a run saved comes back in one call, and snapshots earlier versions wrote
still load, through the one upgrader of their format."""

import json
import pathlib

import numpy as np
import pytest

from rmac_mj import tasks
from rmac_mj.agents import make_agent
from rmac_mj.errors import UserInputError
from rmac_mj.results import load_snapshot, save_snapshot, snapshot_environment
from rmac_mj.results.snapshots import FORMAT, upgrade, upgrade_config
from rmac_mj.rollout import action_space_of, run_trial, state_space_of

#: Snapshots of format 1, written by rmac-mj at commit f091e63 (before the learning rates took the
#: paper's names): ``rmac-mj reproduce --algorithms s-ac,mlac --experiments 1 --trials 1
#: --no-optimal --set 's-ac.tile_coding={"num_tilings": 2, "tiles": 3}' --set mlac.actor_capacity=20
#: --set mlac.critic_capacity=20 --set mlac.process_capacity=20 --set mlac.actor_neighbours=3
#: --set mlac.critic_neighbours=3 --set mlac.process_neighbours=4``, after trial 1.
FORMAT_1 = pathlib.Path(__file__).resolve().parents[1] / "data" / "snapshot_format_1"

#: Snapshots of format 2 (in FORMAT_2, below), each LLR memory's settings flat in the config,
#: written by rmac-mj at commit 7850e37 (``snapshot_format_2/config.json`` is that run's): ``rmac-mj reproduce
#: --algorithms rmac,mlac --experiments 1 --trials 1 --no-optimal --set rmac.critic_capacity=20
#: --set rmac.critic_neighbours=4 --set rmac.process_capacity=12 --set rmac.process_neighbours=4
#: --set rmac.reference_capacity=20 --set rmac.reference_neighbours=4
#: --set rmac.process_replacement=oldest --set rmac.critic_clip=false --set mlac.actor_capacity=20
#: --set mlac.critic_capacity=20 --set mlac.process_capacity=12 --set mlac.actor_neighbours=3
#: --set mlac.critic_neighbours=3 --set mlac.process_neighbours=4
#: --set mlac.actor_replacement=oldest``, after trial 1 (``rmac.npz``, ``mlac.npz``).
#: What that version's learners answered, loaded from these files: state -> (greedy action, value).
ANSWERS_2 = {
    "rmac": {
        (np.pi, 0.0): (2.117170675536946, -154.5221744002279),
        (0.5, -2.0): (-3.0, 522.310904536207),
        (-1.0, 3.0): (3.0, 443.5315573779945),
    },
    "mlac": {
        (np.pi, 0.0): (-2.31630706799236, -334.1371796115468),
        (0.5, -2.0): (-1.1196164966055613, -337.59662850527275),
        (-1.0, 3.0): (-3.0, -236.77536189763595),
    },
}
#: Each format-2 learner's memories as the run set them: (capacity, K, replacement, clip).
MEMORIES_2 = {
    "rmac": {
        "critic": (20, 4, "nearest", False),
        "process": (12, 4, "oldest", False),
        "reference": (20, 4, "nearest", True),
    },
    "mlac": {
        "actor": (20, 3, "oldest", False),
        "critic": (20, 3, "nearest", True),
        "process": (12, 4, "nearest", False),
    },
}

#: What that version's learners answered, loaded from these files: state -> (greedy action, value).
WRITTEN = {
    "s-ac": {
        (np.pi, 0.0): (-0.9459123947521382, -211.33976297324386),
        (0.5, -2.0): (0.0, 0.0),
    },
    "mlac": {
        (np.pi, 0.0): (2.962977676379427, -540.5557977539037),
        (0.5, -2.0): (2.9999999999987494, -549.3823282653077),
        (-1.0, 3.0): (-3.0, -398.2300199306504),
    },
}


@pytest.mark.parametrize("algorithm", sorted(WRITTEN))
def test_a_format_1_snapshot_acts_as_the_version_that_wrote_it(algorithm):
    path = FORMAT_1 / f"{algorithm}.npz"
    with np.load(path, allow_pickle=False) as data:
        written = json.loads(str(data["meta"]))
    assert "format" not in written and {"alpha_actor", "alpha_critic"} <= set(written["config"])
    agent, meta = load_snapshot(path)
    assert meta["format"] == FORMAT and meta["trial"] == 1
    assert (agent.config.alpha_a, agent.config.alpha_c) == (
        written["config"]["alpha_actor"],
        written["config"]["alpha_critic"],
    )
    np.testing.assert_array_equal(agent.state_space.input_weights, [1.0, 0.1])
    if algorithm == "mlac":  # its memories' flat settings nested, through both steps
        sizes = [
            (getattr(agent.config, m).capacity, getattr(agent.config, m).neighbours)
            for m in ("actor", "critic", "process")
        ]
        assert sizes == [(20, 3), (20, 3), (20, 4)]
    for x, (action, value) in WRITTEN[algorithm].items():
        assert agent.greedy_action(np.array(x))[0] == action
        assert agent.value(np.array(x)) == value
    env = snapshot_environment(agent, meta)
    assert np.isfinite(run_trial(env, agent, learn=False))


#: Snapshots of format 2, written by rmac-mj at commit 7850e37 (when MPC's key was ``mpc`` and S-AC
#: with Dyna planning was ``recommended``): ``rmac-mj reproduce --algorithms mpc,recommended
#: --experiments 1 --trials 1 --no-optimal`` with 2 tilings of 3 tiles and planning models of 120
#: samples (``--set 'mpc.planning={"steps": 30, "start": "memory", "horizon": null,
#: "model_capacity": 120}'``, ``--set 'recommended.planning={"steps": 30, "model_capacity": 120}'``),
#: after trial 1.
FORMAT_2 = pathlib.Path(__file__).resolve().parents[1] / "data" / "snapshot_format_2"

#: Written key -> (today's key, its class, what that version answered in one greedy trial from these
#: states in turn: greedy action, value).
WRITTEN_2 = {
    "mpc": (
        "recommended",
        "MPC",
        [
            ((np.pi, 0.0), (-2.383141429060764, -1088.8670772124246)),
            ((0.5, -2.0), (-1.6288203392769405, -724.9050969935727)),
            ((-1.0, 3.0), (-1.5913229236187134, -653.2315629631773)),
        ],
    ),
    "recommended": (
        "s-ac-dyna",
        "DynaAC",
        [
            ((np.pi, 0.0), (-0.24191664741489624, -1563.5835837483155)),
            ((0.5, -2.0), (0.0, 0.0)),
        ],
    ),
}


@pytest.mark.parametrize("written_key", sorted(WRITTEN_2))
def test_a_format_2_snapshot_comes_back_under_todays_learner_key(written_key):
    key, class_name, answers = WRITTEN_2[written_key]
    path = FORMAT_2 / f"{written_key}.npz"
    with np.load(path, allow_pickle=False) as data:
        written = json.loads(str(data["meta"]))
    assert (written["format"], written["algorithm"]) == (2, written_key)
    agent, meta = load_snapshot(path)
    assert (meta["format"], meta["algorithm"], agent.name) == (FORMAT, key, key)
    assert type(agent).__name__ == class_name
    agent.begin_greedy_trial()
    for x, (action, value) in answers:
        assert agent.greedy_action(np.array(x))[0] == action
        assert agent.value(np.array(x)) == value


@pytest.mark.parametrize("algorithm", sorted(MEMORIES_2))
def test_a_format_2_snapshot_of_flat_memory_settings_acts_as_the_version_that_wrote_it(algorithm):
    path = FORMAT_2 / f"{algorithm}.npz"
    with np.load(path, allow_pickle=False) as data:
        written = json.loads(str(data["meta"]))
    memories = MEMORIES_2[algorithm]
    assert written["format"] == 2 and all(f"{m}_capacity" in written["config"] for m in memories)
    agent, meta = load_snapshot(path)
    assert meta["format"] == FORMAT and not any("_capacity" in key for key in meta["config"])
    for name, (capacity, neighbours, replacement, clip) in memories.items():
        memory = getattr(agent.config, name)
        assert (memory.capacity, memory.neighbours, memory.replacement, memory.clip) == (
            capacity,
            neighbours,
            replacement,
            clip,
        )
        assert meta["config"][name]["weights"] == written["config"][f"{name}_weights"]
    for x, (action, value) in ANSWERS_2[algorithm].items():
        agent.begin_greedy_trial()
        assert agent.greedy_action(np.array(x))[0] == action
        assert agent.value(np.array(x)) == value


def test_todays_snapshot_and_config_pass_the_upgrader_as_they_are(tmp_path):
    env = tasks.load("dc_pendulum", "swingup")
    agent = make_agent("rmac", *_spaces(env), config={"process": {"capacity": 30}}, seed=0)
    path = save_snapshot(tmp_path / "s.npz", agent, *_spaces(env), domain="dc_pendulum")
    with np.load(path, allow_pickle=False) as data:
        meta = json.loads(str(data["meta"]))
    assert meta["config"]["process"]["capacity"] == 30 and upgrade(meta) == meta
    assert upgrade_config("rmac", meta["config"]) is meta["config"]
    # format 3 as first written (before the memories nested; nothing released in between)
    flat = {k: v for k, v in meta["config"].items() if k != "process"}
    flat.update({f"process_{k}": v for k, v in meta["config"]["process"].items()})
    assert upgrade(dict(meta, config=flat)) == meta
    # flat and nested names of one memory, as a config of some fields may hold them, end nested
    assert upgrade_config(
        "mlac", {"actor_capacity": 5, "actor": {"clip": True}, "alpha_a": 0.1}
    ) == {
        "actor": {"capacity": 5, "clip": True},
        "alpha_a": 0.1,
    }


@pytest.mark.slow
def test_a_format_2_run_folder_resumes_with_its_settings_nested(tmp_path, capsys):
    """The run that wrote the format-2 snapshots: its config.json (flat memory names) read as today's
    by --resume, which finishes the run with the memories it was started with."""
    from rmac_mj.cli import main
    from rmac_mj.results import ResultStore
    from rmac_mj.results.files import code_version

    document = json.loads((FORMAT_2 / "config.json").read_text())
    assert document["protocol"]["agent_configs"]["rmac"]["process_replacement"] == "oldest"
    out = tmp_path / "run"
    out.mkdir()
    # the same code version (another one's run is refused whatever its format), nothing run yet
    (out / "config.json").write_text(json.dumps(dict(document, code=code_version())))
    config = ResultStore(out).read_config()
    assert config["protocol"]["agent_configs"]["rmac"]["process"] == {
        "capacity": 12,
        "neighbours": 4,
        "replacement": "oldest",
    }
    assert config["agents"]["mlac"]["actor"]["replacement"] == "oldest"
    resume = ["reproduce", "--resume", "--out", str(out), "--no-progress", "--jobs", "1"]
    assert main(resume) == 0, capsys.readouterr().err
    agent, meta = load_snapshot(out / "snapshots" / "rmac" / "exp_000" / "trial_0001.npz")
    assert (agent.config.process.capacity, agent.config.process.replacement) == (12, "oldest")
    assert meta["config"] == ResultStore(out).read_config()["agents"]["rmac"]


def test_format_1_task_kwargs_take_todays_names():
    with np.load(FORMAT_1 / "s-ac.npz", allow_pickle=False) as data:
        written = json.loads(str(data["meta"]))
    written["task_kwargs"] = {"action_weight": 0.25}  # the pendulum's reward weighting P, then
    meta = upgrade(written)
    assert meta["task_kwargs"] == {"action_weights": 0.25}
    assert upgrade(meta) == meta  # the current format passes as it is
    agent = make_agent("s-ac", *_spaces(tasks.load("dc_pendulum", "swingup")), seed=0)
    assert snapshot_environment(agent, meta).task.action_weights == 0.25


def test_a_snapshot_of_a_newer_format_is_refused_naming_it(tmp_path):
    env = tasks.load("dc_pendulum", "swingup")
    agent = make_agent("s-ac", *_spaces(env), seed=0)
    path = save_snapshot(tmp_path / "s.npz", agent, *_spaces(env), domain="dc_pendulum")
    with np.load(path, allow_pickle=False) as data:
        arrays = dict(data)
    meta = json.loads(str(arrays["meta"]))
    assert meta["format"] == FORMAT
    arrays["meta"] = np.array(json.dumps(dict(meta, format=FORMAT + 1)))
    np.savez(tmp_path / "newer.npz", **arrays)
    with pytest.raises(
        UserInputError, match=f"snapshot format {FORMAT + 1}; .* formats 1 to {FORMAT}"
    ):
        load_snapshot(tmp_path / "newer.npz")


def _spaces(env):
    return state_space_of(env), action_space_of(env)
