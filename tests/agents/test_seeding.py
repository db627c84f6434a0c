"""Prior knowledge (section 7): seeding learners, the demonstrator, the file format, the runner."""

import json

import numpy as np
import pytest

from rmac_mj import tasks
from rmac_mj.agents import LLRConfig, RMACConfig, discounted_returns, make_agent
from rmac_mj.errors import MissingInputError, UserInputError
from rmac_mj.experiments import (
    Protocol,
    RunOptions,
    demonstration_for,
    experiment_seeds,
    run_protocol,
)
from rmac_mj.experiments import prior_transitions as prior
from rmac_mj.results import ResumeRefused
from rmac_mj.rollout import action_space_of, run_trial, state_space_of
from rmac_mj.tasks.energy_swingup import lqr_gains


@pytest.fixture(scope="module")
def env():
    return tasks.load("dc_pendulum", "swingup")


def spaces(env):
    return state_space_of(env), action_space_of(env)


def synthetic(T=30, trials=2, seed=0):
    """T transitions split into ``trials`` trials, with unwrapped angles beyond pi."""
    rng = np.random.default_rng(seed)
    states = np.c_[rng.uniform(-5, 5, T), rng.uniform(-20, 20, T)]
    return dict(
        states=states,
        actions=rng.uniform(-3, 3, (T, 1)),
        rewards=-rng.uniform(0, 50, T),
        next_states=states + rng.normal(0, 0.1, (T, 2)),
        trial=np.sort(rng.integers(0, trials, T)),
    )


def wrapped(x):
    return np.c_[(x[:, 0] + np.pi) % (2 * np.pi) - np.pi, x[:, 1:]]


# -- seeding the learners -------------------------------------------------------------------------


def test_discounted_returns_restart_at_each_trial_end():
    rewards = np.array([-1.0, -2.0, -4.0, -8.0, -16.0])
    trial = np.array([0, 0, 0, 3, 3])
    g = 0.5
    expected = [-1 + g * (-2 + g * -4), -2 + g * -4, -4.0, -8 + g * -16, -16.0]
    np.testing.assert_allclose(discounted_returns(rewards, trial, g), expected)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_seeded_memories_hold_exactly_the_given_samples(env, backend):
    data = synthetic(T=30)
    agent = make_agent("rmac", *spaces(env), config=RMACConfig(backend=backend), seed=0)
    agent.seed_from(**data)
    x, x_next = wrapped(data["states"]), wrapped(data["next_states"])
    for memory, X, Y in (
        (agent.process, np.c_[x, data["actions"]], x_next),
        (agent.reference, x, x_next),
        (agent.critic.memory, x, discounted_returns(data["rewards"], data["trial"], 0.97)[:, None]),
    ):
        assert memory.n_samples_ == 30
        np.testing.assert_allclose(memory.X_[:30], X, atol=1e-12)
        np.testing.assert_allclose(memory.Y_[:30], Y, atol=1e-12)
    # The policy now follows the seeded models: a query at a seeded state finds that sample first.
    assert agent.reference.neighbours(x[7])[0] == 7


def test_mlac_memories_hold_exactly_the_given_samples(env):
    data = synthetic(T=30)
    agent = make_agent("mlac", *spaces(env), seed=0)
    agent.seed_from(**data)
    x, x_next = wrapped(data["states"]), wrapped(data["next_states"])
    gamma = agent.config.gamma
    for memory, X, Y in (
        (agent.actor, x, data["actions"]),
        (agent.process, np.c_[x, data["actions"]], x_next),
        (
            agent.critic.memory,
            x,
            discounted_returns(data["rewards"], data["trial"], gamma)[:, None],
        ),
    ):
        assert memory.n_samples_ == 30
        np.testing.assert_allclose(memory.X_[:30], X, atol=1e-12)
        np.testing.assert_allclose(memory.Y_[:30], Y, atol=1e-12)
    assert set(agent.prior_parts) == {"actor", "critic", "process"}


def test_more_samples_than_capacity_pass_through_the_replacement_rule(env):
    data = synthetic(T=150)
    cfg = RMACConfig(
        process=LLRConfig(replacement="oldest"),
        critic=LLRConfig(capacity=40, neighbours=10),
    )
    agent = make_agent("rmac", *spaces(env), config=cfg, seed=0)
    agent.seed_from(**data)
    # 'oldest': the process memory (capacity 100) keeps the last 100 transitions.
    assert agent.process.n_samples_ == 100
    kept = np.sort(agent.process.stamp_)
    np.testing.assert_array_equal(kept, np.arange(50, 150))
    X = np.c_[wrapped(data["states"]), data["actions"]]
    order = np.argsort(agent.process.stamp_)
    np.testing.assert_allclose(agent.process.X_[order], X[50:], atol=1e-12)
    # 'nearest' (the critic): full, and every stored sample is one of the recorded ones.
    assert agent.critic.memory.n_samples_ == 40
    given = wrapped(data["states"])
    for row in agent.critic.memory.X_[:40]:
        assert np.min(np.abs(given - row).sum(axis=1)) < 1e-12


def test_redundancy_replacement_scores_the_seeded_samples_and_keeps_recorded_ones(env):
    # Under 'redundancy' the first `capacity` samples are scored as they are stored (fit) and the
    # rest update the scores as they pass through the rule; both back ends keep the same samples.
    data = synthetic(T=150)
    memories = []
    for backend in ("numba", "numpy"):
        cfg = RMACConfig(
            process=LLRConfig(replacement="redundancy"),
            critic=LLRConfig(replacement="redundancy", capacity=40, neighbours=10),
            backend=backend,
        )
        agent = make_agent("rmac", *spaces(env), config=cfg, seed=0)
        agent.seed_from(**data)
        memories.append((agent.process, agent.critic.memory))
        assert agent.process.n_samples_ == 100 and agent.critic.memory.n_samples_ == 40
        X = np.c_[wrapped(data["states"]), data["actions"]]
        for row in agent.process.X_:
            assert np.min(np.abs(X - row).sum(axis=1)) < 1e-12
        assert np.all(agent.process.redundancy_ <= 0) and np.all(
            agent.critic.memory.redundancy_ < 0
        )
        # Samples were replaced, and not only the last ones kept (as 'oldest' would).
        assert agent.process.stamp_.min() < 50
    for fast, slow in zip(*memories):
        np.testing.assert_array_equal(fast.stamp_, slow.stamp_)
        np.testing.assert_allclose(fast.redundancy_, slow.redundancy_, rtol=1e-9, atol=1e-12)


def test_parts_select_what_is_seeded(env):
    agent = make_agent("rmac", *spaces(env), seed=0)
    agent.seed_from(**synthetic(), parts=["process"])
    assert (
        agent.process.n_samples_,
        agent.reference.n_samples_,
        agent.critic.memory.n_samples_,
    ) == (30, 0, 0)
    with pytest.raises(ValueError, match="parts must name some of"):
        agent.seed_from(**synthetic(), parts=["actor"])


def test_learners_without_prior_knowledge_refuse_it_by_name(env):
    agent = make_agent("s-ac", *spaces(env), seed=0)
    with pytest.raises(NotImplementedError, match="s-ac does not take prior knowledge"):
        agent.seed_from(**synthetic())


@pytest.mark.parametrize(
    "field, value, message",
    [
        ("states", np.zeros((30, 3)), r"states must have shape \(T, 2\)"),
        ("actions", np.zeros((29, 1)), r"actions must have shape \(30, 1\)"),
        ("rewards", np.full(30, np.nan), "rewards must be finite; 30 of 30 rows"),
        ("trial", np.arange(30)[::-1], "trial must be non-decreasing"),
        ("trial", np.zeros(30), "trial must hold integers"),
    ],
)
def test_seed_from_checks_its_arrays(env, field, value, message):
    agent = make_agent("rmac", *spaces(env), seed=0)
    with pytest.raises(ValueError, match=message):
        agent.seed_from(**{**synthetic(), field: value})


def test_seeding_inside_a_trial_is_refused(env):
    agent = make_agent("rmac", *spaces(env), seed=0)
    agent.start(np.array([np.pi, 0.0]))
    with pytest.raises(RuntimeError, match="inside a trial"):
        agent.seed_from(**synthetic())


# -- the demonstrator ------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["demo", "poor-demo"])
def test_demonstrator_swings_the_model_up_from_hanging(env, name):
    controller = tasks.knowledge("dc_pendulum", "swingup").demonstrator(name).controller(env)
    demo = prior.record(env, controller, trials=1)
    np.testing.assert_allclose(np.abs(demo.states[0]), [np.pi, 0.0], atol=1e-12)  # x_0 = [pi, 0]
    last_second = demo.next_states[-34:, 0]  # the last 1.02 s
    assert np.all(np.abs(last_second) < 0.2), last_second
    # Not optimal: worse than the near-optimal -748 (docs/optimal.md), the poor one much worse.
    ret = demo.trial_returns()[0]
    assert ret < -800 and (ret > -1100 if name == "demo" else ret < -1500), ret


def test_lqr_gains_stabilise_the_linearised_model(env):
    gains = lqr_gains(env)
    assert np.all(gains > 0)
    controller = tasks.knowledge("dc_pendulum", "swingup").demonstrator("demo").controller(env)
    # Near upright the controller is the LQR: u = -K x.
    np.testing.assert_allclose(
        controller(np.array([0.1, -0.5])), [-(0.1 * gains[0] - 0.5 * gains[1])]
    )


def test_unknown_demonstrator_is_named():
    with pytest.raises(
        ValueError,
        match="no demonstrator 'expert' for dc_pendulum/swingup; available: demo, poor-demo",
    ):
        tasks.knowledge("dc_pendulum", "swingup").demonstrator("expert", "dc_pendulum/swingup")


# -- recording and the file format ------------------------------------------------------------------


def test_record_save_load_round_trip(env, tmp_path):
    controller = tasks.knowledge("dc_pendulum", "swingup").demonstrator("demo").controller(env)
    demo = prior.record(env, controller, trials=2, seed=3, action_noise=0.5)
    assert demo.n_transitions == 200 and demo.n_trials == 2
    np.testing.assert_array_equal(demo.trial, np.repeat([0, 1], 100))
    for t in range(2):  # consecutive within a trial
        rows = demo.trial == t
        np.testing.assert_array_equal(demo.next_states[rows][:-1], demo.states[rows][1:])
    assert np.all(np.abs(demo.actions) <= 3.0)  # the applied, saturated action
    assert demo.trial_returns()[0] != demo.trial_returns()[1]  # the noise differs per trial
    again = prior.record(env, controller, trials=2, seed=3, action_noise=0.5)
    np.testing.assert_array_equal(again.actions, demo.actions)  # the seed decides the noise
    # The recorded rewards are the task's: replaying the actions gives the same return.
    env.reset()
    total = 0.0
    for u in demo.actions[:100]:
        total += env.step(u).reward
    assert total == pytest.approx(demo.trial_returns()[0], abs=1e-9)

    path = prior.save_demonstration(tmp_path / "demo.npz", demo)
    with np.load(path, allow_pickle=False) as data:
        assert sorted(data.files) == sorted(prior.FIELDS)
    loaded = prior.load_demonstration(path, *spaces(env))
    for field in prior.FIELDS:
        np.testing.assert_array_equal(getattr(loaded, field), getattr(demo, field))


def _write(path, **arrays):
    np.savez(path, **arrays)
    return path


@pytest.mark.parametrize(
    "change, message",
    [
        (dict(drop="rewards"), r"missing \['rewards'\]"),
        (dict(extra=np.zeros(3)), r"unexpected \['extra'\]"),
        (dict(states=np.zeros((30, 2, 1))), r"states must have shape \(T, d\)"),
        (dict(next_states=np.zeros((30, 3))), r"next_states must have shape \(T, 2\)"),
        (dict(actions=np.zeros(30)), r"actions must have shape"),
        (dict(states=np.full((30, 2), np.inf)), "states must be finite; 30 of 30 rows"),
        (dict(trial=np.r_[np.zeros(20), np.ones(10)]), "trial must hold integers"),
        (dict(trial=np.r_[np.ones(20), np.zeros(10)].astype(int)), "row 20 goes back from 1 to 0"),
        (
            dict(states=np.zeros((30, 3)), next_states=np.zeros((30, 3))),
            "states have n=3 entries per row, the task's state has 2",
        ),
        (
            dict(actions=np.zeros((30, 2))),
            "actions have m=2 entries per row, the task's action has 1",
        ),
        (dict(actions=np.full((30, 1), 12.0)), "30 of 30 rows lie outside the task's action range"),
    ],
)
def test_malformed_prior_file_is_refused_naming_what_is_wrong(env, tmp_path, change, message):
    arrays = {k: v for k, v in synthetic().items()}
    drop = change.pop("drop", None)
    arrays.update(change)
    if drop:
        del arrays[drop]
    path = _write(tmp_path / "bad.npz", **arrays)
    with pytest.raises(UserInputError, match=message) as error:
        prior.load_demonstration(path, *spaces(env))
    assert str(path) in str(error.value)


def test_unreadable_or_missing_prior_file_is_refused(env, tmp_path):
    with pytest.raises(MissingInputError, match="no such demonstration file"):
        prior.load_demonstration(tmp_path / "none.npz")
    (tmp_path / "text.npz").write_text("states,actions\n1,2\n")
    with pytest.raises(UserInputError, match="not an .npz file"):
        prior.load_demonstration(tmp_path / "text.npz")
    arrays = synthetic()
    arrays["rewards"] = np.array([object()] * 30)  # needs pickle, which is refused
    path = _write(tmp_path / "pickled.npz", **arrays)
    with pytest.raises(UserInputError, match="pickled.npz: .*allow_pickle"):
        prior.load_demonstration(path)


# -- the runner and the command line ------------------------------------------------------------------


def test_seeded_rmac_reaches_upright_in_its_first_trial(env):
    protocol = Protocol(algorithms=("rmac",), experiments=1, trials=1, prior="demo")
    demo = demonstration_for(protocol, 0)
    np.testing.assert_array_equal(demo.actions, demonstration_for(protocol, 0).actions)
    assert not np.array_equal(demo.actions, demonstration_for(protocol, 1).actions)
    seeded, empty = (make_agent("rmac", *spaces(env), seed=0) for _ in range(2))
    seeded.seed_from(**demo.arrays())
    angles = []
    ret = run_trial(env, seeded, on_step=lambda e, u, r: angles.append(e.physics.angle()))
    assert np.min(np.abs(angles)) < 0.1  # it gets up at once (it may still fall while exploring)
    assert ret > run_trial(env, empty) + 1500  # an empty RMAC's first trial stays far below


def test_protocol_refuses_learners_and_parts_that_take_no_prior():
    with pytest.raises(
        ValueError,
        match=r"^s-ac does not take prior knowledge: run only learners "
        r"that do \(rmac",
    ):
        Protocol(algorithms=("rmac", "s-ac"), prior="demo")
    with pytest.raises(ValueError, match="rmac takes no actor prior"):
        Protocol(algorithms=("rmac",), prior="demo", prior_parts=("actor",))
    with pytest.raises(ValueError, match="prior_parts needs prior"):
        Protocol(algorithms=("rmac",), prior_parts=("process",))
    with pytest.raises(
        ValueError, match=r"Protocol.prior_trials must be an integer in \[1, 10000\] .*, got 0"
    ):
        Protocol(algorithms=("rmac",), prior="demo", prior_trials=0)
    assert Protocol(prior=None).is_paper_protocol


@pytest.mark.slow
def test_reproduce_with_prior_end_to_end(env, tmp_path, capsys):
    from rmac_mj.cli import main

    common = [
        "reproduce",
        "--algorithms",
        "rmac",
        "--experiments",
        "1",
        "--trials",
        "2",
        "--jobs",
        "1",
        "--no-optimal",
        "--no-progress",
    ]
    out = tmp_path / "demo"
    assert main([*common, "--prior", "demo", "--prior-trials", "2", "--out", str(out)]) == 0
    config = json.loads((out / "config.json").read_text())["protocol"]
    assert (config["prior"], config["prior_trials"]) == ("demo", 2)
    with np.load(out / "curves/rmac/exp_000.npz") as curve:
        demonstration_returns, returns = curve["demonstration_returns"], curve["returns"]
    assert demonstration_returns.shape == (2,) and returns.shape == (2,)
    protocol = Protocol(algorithms=("rmac",), experiments=1, trials=2, prior="demo", prior_trials=2)
    np.testing.assert_allclose(
        demonstration_returns, demonstration_for(protocol, 0).trial_returns()
    )
    # The run is the seeded agent's: its first trial is the one a seeded agent makes.
    agent = make_agent("rmac", *spaces(env), seed=np.random.default_rng(experiment_seeds(0, 0)[0]))
    agent.seed_from(**demonstration_for(protocol, 0).arrays())
    assert run_trial(env, agent) == pytest.approx(returns[0], abs=1e-9)

    # A user's own recording.
    path = prior.save_demonstration(tmp_path / "logs.npz", demonstration_for(protocol, 0))
    out = tmp_path / "file"
    from_file = Protocol(
        algorithms=("rmac",),
        experiments=1,
        trials=1,
        prior=str(path),
        prior_parts=("process", "critic"),
    )
    run_protocol(from_file, out, RunOptions(jobs=1, progress=False, figures=False))
    document = json.loads((out / "config.json").read_text())
    assert document["protocol"]["prior_parts"] == ["process", "critic"]
    assert len(document["prior_sha256"]) == 64
    run_protocol(from_file, out, RunOptions(jobs=1, resume=True, progress=False, figures=False))
    prior.save_demonstration(path, demonstration_for(protocol, 1))  # the file changes
    with pytest.raises(ResumeRefused, match="different config"):
        run_protocol(from_file, out, RunOptions(jobs=1, resume=True, progress=False, figures=False))
    capsys.readouterr()

    for args, message in (
        (["--prior", "demo", "--algorithms", "rmac,s-ac"], "s-ac does not take prior knowledge"),
        (["--prior", str(tmp_path / "missing.npz")], "no such demonstration file"),
        (["--prior", str(path), "--prior-trials", "3"], "a recorded file is used whole"),
        (["--prior", "expert"], "no demonstrator 'expert'"),
        (["--prior", "demo", "--prior-parts", "actor"], "rmac takes no actor prior"),
        (["--prior-trials", "3"], "need --prior"),
    ):
        assert main([*common, "--out", str(tmp_path / "refused"), *args]) == 2
        stderr = capsys.readouterr().err
        assert message in stderr and len(stderr.strip().splitlines()) == 1, stderr
