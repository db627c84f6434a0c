"""Exploration (base.Exploration): the paper's schedule, a decaying noise level, and exploring only
where the process model is uncertain; the agents' trial counter that the decay reads."""

import math

import numpy as np
import plain_pendulum
import pytest

from rmac_mj.agents import (
    MLAC,
    RMAC,
    ActionSpace,
    Exploration,
    MLACConfig,
    RMACConfig,
    StandardACConfig,
    StandardActorCritic,
    StateSpace,
    model_uncertainty,
)
from rmac_mj.approximators import LLRMemory

PENDULUM = StateSpace(
    low=[-np.pi, -8 * np.pi],
    high=[np.pi, 8 * np.pi],
    periodic=[True, False],
    input_weights=[1.0, 0.1],
)
VOLTS = ActionSpace(low=[-3.0], high=[3.0], cost=[1.0])


def _returns(agent, trials, steps=60):
    """Learning trials of the DC-motor pendulum in plain floats, from hanging down; their returns."""
    return plain_pendulum.returns(agent, trials, steps)


# -- the schedule ---------------------------------------------------------------------------------


def test_decay_schedules_at_given_trials():
    paper = Exploration(sigma=1.0)  # the paper's, resolved on +-3 V
    assert [paper.sigma_at(t) for t in (0, 1, 599)] == [1.0, 1.0, 1.0]
    exponential = Exploration(sigma=1.0, decay="exponential", decay_rate=0.9, sigma_min=0.2)
    assert exponential.sigma_at(0) == 1.0
    assert exponential.sigma_at(1) == pytest.approx(0.9)
    assert exponential.sigma_at(10) == pytest.approx(0.9**10)  # 0.349 > floor
    assert exponential.sigma_at(16) == 0.2  # 0.185 < floor
    assert exponential.sigma_at(1000) == 0.2
    linear = Exploration(sigma=2.0, decay="linear", decay_trials=100, sigma_min=0.5)
    assert [linear.sigma_at(t) for t in (0, 50, 100, 500)] == pytest.approx([2.0, 1.25, 0.5, 0.5])
    assert linear.sigma_at(25) == pytest.approx(1.625)


def test_noise_follows_the_schedule_draw_for_draw():
    """Scheduled steps draw N(0, sigma_t) from the generator, the others draw nothing."""
    e = Exploration(sigma=2.0, period=3, phase=1, decay="linear", decay_trials=4, sigma_min=0.0)
    rng, ref = np.random.default_rng(5), np.random.default_rng(5)
    for k in range(7):
        du = e.sample(k, 2, rng, trial=1)
        if k % 3 == 1:
            np.testing.assert_array_equal(du, ref.normal(0.0, 1.5, size=2))
        else:
            np.testing.assert_array_equal(du, np.zeros(2))
    assert not np.any(e.sample(1, 2, rng, trial=4))  # sigma 0 from trial 4 on: nothing drawn
    assert rng.bit_generator.state == ref.bit_generator.state


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (
            dict(decay="cubic"),
            "Exploration.decay must be one of 'none', 'exponential', 'linear', got 'cubic'",
        ),
        (
            dict(sigma=1.0, sigma_min=1.5),
            "Exploration.sigma_min must be a number in \\[0, sigma=1.0\\], got 1.5",
        ),
        (dict(sigma_min=-0.1), "Exploration.sigma_min"),
        (dict(decay_rate=0.0), "Exploration.decay_rate must be a number in \\(0, 1\\], got 0.0"),
        (dict(decay="exponential", decay_rate=1.0), "Exploration.decay_rate must be below 1"),
        (dict(decay_trials=0), "Exploration.decay_trials must be an integer >= 1, got 0"),
        (dict(decay_trials=2.5), "Exploration.decay_trials"),
        (
            dict(where="sometimes"),
            "Exploration.where must be 'always' or 'uncertain', got 'sometimes'",
        ),
        (
            dict(where="uncertain"),
            "Exploration.uncertainty_threshold must be a finite number >= 0 with where='uncertain'",
        ),
        (dict(where="uncertain", uncertainty_threshold=-1.0), "Exploration.uncertainty_threshold"),
        (dict(uncertainty_threshold=math.inf), "Exploration.uncertainty_threshold"),
        (dict(sigma=math.nan), "Exploration.sigma must be"),
        (dict(period=0), "Exploration.period"),
        (dict(period=3.0), "Exploration.period must be an integer >= 1, got 3.0"),
        (dict(phase=3), "Exploration.phase must be an integer in \\[0, period=3\\), got 3"),
    ],
)
def test_bad_exploration_names_the_field(kwargs, name):
    with pytest.raises(ValueError, match=name):
        Exploration(**kwargs)


def test_sac_refuses_uncertain_exploration_by_name():
    with pytest.raises(ValueError, match="StandardACConfig.exploration.where must be 'always'"):
        StandardACConfig(exploration=Exploration(where="uncertain", uncertainty_threshold=1.0))


# -- the uncertainty measure and the 'uncertain' rule ------------------------------------------------


def _dense_process_memory(memory):
    """Fill a process memory over [phi, omega, u] with a dense 4 x 4 x 4 grid around the origin
    (spacing 0.013 in every weighted input) mapping to next states of a made-up linear model."""
    g = np.linspace(-0.02, 0.02, 4)
    X = np.array([[p, w / 0.1, u] for p in g for w in g for u in g])
    Y = X[:, :2] + 0.05 * X[:, 2:3]
    memory.fit(X, Y)


def test_uncertainty_is_the_mean_distance_of_the_neighbours():
    memory = LLRMemory(
        3,
        2,
        capacity=200,
        n_neighbours=4,
        input_weights=[1.0, 0.1, 1.0],
        input_period=[2 * np.pi, 0.0, 0.0],
    )
    assert model_uncertainty(memory, np.zeros(3)) == math.inf  # empty: fewer than K samples
    memory.fit([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 1.0, 0.0]], np.zeros((3, 2)))
    assert model_uncertainty(memory, np.zeros(3)) == math.inf  # 3 < K = 4
    memory.insert([np.pi - 0.05, 0.0, 0.0], [0.0, 0.0])  # 0.05 + 0.05 across the seam
    # Weighted 1-norm distances from (-pi + 0.05, 0, 0): 0.1 (wrapped), pi - 0.05, pi + 0.05 - 0.1,
    # and pi - 0.05 + 0.1 (omega weighted by 0.1).
    xq = np.array([-np.pi + 0.05, 0.0, 0.0])
    expected = np.mean([0.1, np.pi - 0.05, np.pi - 0.05, np.pi + 0.05])
    assert model_uncertainty(memory, xq) == pytest.approx(expected)
    np.testing.assert_allclose(
        np.sort(memory.neighbour_distances(xq)),
        np.sort([0.1, np.pi - 0.05, np.pi - 0.05, np.pi + 0.05]),
    )


@pytest.mark.parametrize("backend", ["numba", "numpy"])
@pytest.mark.parametrize("learner", ["rmac", "mlac"])
def test_uncertain_rule_explores_far_from_memory_and_not_where_dense(learner, backend):
    """With a hand-built process memory dense around (0, 0, 0): a scheduled step in x = (0, 0) is
    greedy (uncertainty 0.02 below the threshold 0.5) and draws nothing; in x = (2, 0), 2 rad from
    every sample, it explores."""
    exploration = Exploration(where="uncertain", uncertainty_threshold=0.5)
    if learner == "rmac":
        agent = RMAC(PENDULUM, VOLTS, RMACConfig(exploration=exploration, backend=backend), seed=6)
    else:
        agent = MLAC(PENDULUM, VOLTS, MLACConfig(exploration=exploration, backend=backend), seed=6)
    _dense_process_memory(agent.process)
    near, far = np.zeros(2), np.array([2.0, 0.0])
    assert model_uncertainty(agent.process, np.r_[near, 0.0]) < 0.05
    assert model_uncertainty(agent.process, np.r_[far, 0.0]) > 1.9
    untouched = agent.rng.bit_generator.state
    u = agent.start(near)  # step 0 is scheduled (phase 0)
    assert agent.rng.bit_generator.state == untouched
    np.testing.assert_array_equal(u, agent.greedy_action(near))
    agent.stop(0.0, near)
    u = agent.start(far)
    draw = np.random.default_rng(6).normal(0.0, 1.0, size=1)  # the agent's first draw: +1.05
    assert agent.rng.bit_generator.state != untouched
    greedy = agent.greedy_action(far)
    assert not np.array_equal(u, greedy)
    np.testing.assert_allclose(u, np.clip(greedy + draw, -3.0, 3.0))


@pytest.mark.parametrize("learner", ["rmac", "mlac"])
def test_uncertain_with_threshold_zero_is_the_paper_schedule(learner):
    """Every uncertainty is >= 0, so threshold 0 explores on every scheduled step: the same draws and
    returns as where='always'."""
    make = (
        (lambda e: RMAC(PENDULUM, VOLTS, RMACConfig(exploration=e), seed=9))
        if learner == "rmac"
        else (lambda e: MLAC(PENDULUM, VOLTS, MLACConfig(exploration=e), seed=9))
    )
    always = make(Exploration())
    uncertain = make(Exploration(where="uncertain", uncertainty_threshold=0.0))
    assert _returns(always, 2) == _returns(uncertain, 2)
    assert always.rng.bit_generator.state == uncertain.rng.bit_generator.state


def test_uncertain_threshold_explores_less_and_learns_otherwise():
    """A high threshold skips most scheduled steps: fewer draws than the paper's schedule."""
    paper = RMAC(PENDULUM, VOLTS, RMACConfig(), seed=9)
    shy = RMAC(
        PENDULUM,
        VOLTS,
        RMACConfig(exploration=Exploration(where="uncertain", uncertainty_threshold=0.6)),
        seed=9,
    )
    draws = {}
    for name, agent in (("paper", paper), ("shy", shy)):
        counting = _CountingGenerator(agent.rng)
        agent.rng = counting
        _returns(agent, 3)
        draws[name] = counting.draws
    assert draws["paper"] == 3 * 20  # steps 0, 3, ..., 57 of each 60-step trial
    assert 0 < draws["shy"] < draws["paper"]


class _CountingGenerator:
    def __init__(self, rng):
        self.rng, self.draws = rng, 0

    def normal(self, *args, **kwargs):
        self.draws += 1
        return self.rng.normal(*args, **kwargs)

    @property
    def bit_generator(self):  # what a learner saves to put back after a refused step
        return self.rng.bit_generator


# -- the trial counter ----------------------------------------------------------------------------


@pytest.mark.parametrize("learner", ["rmac", "mlac", "sac"])
def test_trial_counter_round_trips_and_drives_the_decay(learner):
    exploration = Exploration(decay="exponential", decay_rate=0.5, sigma_min=0.05)
    cls, config_class = {
        "rmac": (RMAC, RMACConfig),
        "mlac": (MLAC, MLACConfig),
        "sac": (StandardActorCritic, StandardACConfig),
    }[learner]
    make = lambda seed: cls(PENDULUM, VOLTS, config_class(exploration=exploration), seed=seed)  # noqa
    a = make(1)
    assert a.trial == -1
    _returns(a, 3, steps=30)
    a.greedy_action(np.zeros(2))  # greedy actions (trials) do not count
    assert a.trial == 2 and int(a.state_dict()["trials"]) == 3
    b = make(2)
    b.load_state_dict(a.state_dict())
    assert b.trial == 2
    assert _returns(a, 2, steps=30) == _returns(b, 2, steps=30)
    # Without the counter the copy would restart the decay at sigma = 1: refused.
    state = a.state_dict()
    del state["trials"]
    with pytest.raises(ValueError, match="trials"):
        make(3).load_state_dict(state)
    # A learner whose exploration does not decay loads such an older state dict.
    plain = cls(PENDULUM, VOLTS, config_class(), seed=3)
    plain.load_state_dict(
        {
            k: v
            for k, v in cls(PENDULUM, VOLTS, config_class(), seed=4).state_dict().items()
            if k != "trials"
        }
    )


def test_decay_changes_the_noise_from_trial_to_trial():
    """With a decay, trial t's scheduled noise is sigma_t times the paper's draws."""
    decaying = RMAC(
        PENDULUM,
        VOLTS,
        RMACConfig(
            exploration=Exploration(decay="exponential", decay_rate=0.5, sigma_min=0.0),
            backend="numpy",
        ),
        seed=0,
    )
    ref = np.random.default_rng(0)
    for t in range(3):
        u0 = decaying.start(np.array([0.0, 0.0]))  # empty-ish model: greedy u_0 is 0 at first
        greedy = decaying.greedy_action(np.array([0.0, 0.0]))
        np.testing.assert_allclose(u0, np.clip(greedy + ref.normal(0.0, 0.5**t, size=1), -3, 3))
        decaying.stop(0.0, np.array([0.0, 0.0]))
