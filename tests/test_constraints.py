"""Parameter constraints declared once (issue 19 item 3): every config refuses a bad value the same
way, with one kind of message, and the sweep file checker reads the same tables."""

import dataclasses
import pathlib

import pytest

from rmac_mj import constraints
from rmac_mj.agents import Exploration, MLACConfig, RMACConfig, StandardACConfig, config_from_dict
from rmac_mj.approximators import LLRConfig, LLRMemory, TileCodingConfig
from rmac_mj.errors import UserInputError
from rmac_mj.sweeps import load_sweep

CONFIGS = (RMACConfig, StandardACConfig, MLACConfig, Exploration, TileCodingConfig, LLRConfig)
LEARNERS = (RMACConfig, StandardACConfig, MLACConfig)


def refusal(cls, **kwargs) -> str:
    """The message refusing ``kwargs`` (a nested config's as a dict of some of its fields)."""
    with pytest.raises(constraints.InvalidParameterError) as error:
        config_from_dict(cls, kwargs)
    return str(error.value)


@pytest.mark.parametrize("cls", CONFIGS)
def test_every_field_has_constraints_and_the_defaults_meet_them(cls):
    assert sorted(f.name for f in dataclasses.fields(cls)) == sorted(cls.parameter_constraints)
    cls()  # the paper's defaults pass their own table


@pytest.mark.parametrize("cls", LEARNERS)
def test_a_bool_is_no_learning_rate_in_any_learner(cls):
    # Every learner's critic rate is alpha_c, the paper's name (the actor's alpha_a, RMAC's alpha_r),
    # and a bool is none.
    assert (
        refusal(cls, alpha_c=True) == f"{cls.__name__}.alpha_c must be a number in [0, 1], got True"
    )


@pytest.mark.parametrize("cls", LEARNERS)
def test_gamma_1_is_refused_by_every_learner(cls):
    # The paper: gamma in [0, 1) (eq. 1).
    assert (
        refusal(cls, gamma=1.0)
        == f"{cls.__name__}.gamma must be a number in [0, 1), or None, got 1.0"
    )  # None: the task's
    assert cls(gamma=0.999).gamma == 0.999


@pytest.mark.parametrize("cls", (RMACConfig, MLACConfig))
def test_a_bool_norm_and_a_string_clip_are_refused_by_rmac_and_mlac_alike(cls):
    assert refusal(cls, norm=True) == f"{cls.__name__}.norm must be 1 or 2, got True"
    assert (
        refusal(cls, critic={"clip": "no"})
        == f"{cls.__name__}.critic.clip must be True or False or None, got 'no'"
    )


@pytest.mark.parametrize("cls", (RMACConfig, MLACConfig))
def test_a_string_action_cost_and_a_missing_rcond_are_named(cls):
    # Named, not a raw numpy TypeError.
    assert (
        refusal(cls, action_cost="1")
        == f"{cls.__name__}.action_cost must be a finite number >= 0 or a list of finite numbers >= 0 "
        "or None, got '1'"
    )
    assert refusal(cls, rcond=None) == f"{cls.__name__}.rcond must be a number in [0, 1), got None"


def test_integers_are_integers_everywhere():
    # A float is no integer, whichever config holds it.
    assert refusal(Exploration, period=3.0) == "Exploration.period must be an integer >= 1, got 3.0"
    assert (
        refusal(RMACConfig, critic={"capacity": 2000.0})
        == "RMACConfig.critic.capacity must be an integer >= 1 or None, got 2000.0"
    )
    assert (
        refusal(TileCodingConfig, num_tilings=16.0)
        == "TileCodingConfig.num_tilings must be an integer >= 1, got 16.0"
    )
    with pytest.raises(
        constraints.InvalidParameterError,
        match=r"^LLRMemory.capacity must be an integer >= 1, got 10.0$",
    ):
        LLRMemory(2, 1, 10.0, 3)


def test_a_bound_named_after_another_parameter_shows_its_value():
    assert (
        refusal(RMACConfig, critic={"capacity": 2000, "neighbours": 3000})
        == "RMACConfig.critic.neighbours must be an integer in [1, capacity=2000], or None, got 3000"
    )
    with pytest.raises(
        constraints.InvalidParameterError,
        match=r"LLRMemory.n_neighbours must be an integer in \[1, capacity=10\]",
    ):
        LLRMemory(2, 1, 10, 11)


def test_an_unknown_name_suggests_the_closest_known_one():
    with pytest.raises(
        constraints.InvalidParameterError,
        match=r"^RMACConfig has no parameter 'alpha_x' \(did you mean 'alpha_r'\?\)$",
    ):
        config_from_dict(RMACConfig, {"alpha_x": 0.1})
    with pytest.raises(
        constraints.InvalidParameterError,
        match=r"^RMACConfig.exploration has no parameter 'sigmaa' \(did you mean 'sigma'\?\)$",
    ):
        config_from_dict(RMACConfig, {"exploration": {"sigmaa": 0.5}})


@pytest.mark.parametrize("cls, memory", [(RMACConfig, "reference"), (MLACConfig, "actor")])
def test_a_memory_setting_by_its_flat_name_is_told_its_nested_one(cls, memory):
    with pytest.raises(
        constraints.InvalidParameterError,
        match=rf"^{cls.__name__} has no parameter '{memory}_neighbours' "
        rf"\(did you mean '{memory}.neighbours'\?\)$",
    ):
        config_from_dict(cls, {f"{memory}_neighbours": 5})
    with pytest.raises(
        constraints.InvalidParameterError, match=r"\(did you mean 'rmac.critic.clip'\?\)$"
    ):
        constraints.lookup(RMACConfig, ["critic_clip"], "rmac.")


def test_sequences_are_kept_as_tuples_of_floats():
    config = RMACConfig(critic=LLRConfig(weights=[1, 0.1]))
    assert config.critic.weights == (1.0, 0.1) and hash(config)
    assert StandardACConfig(tile_low=[None, -5]).tile_low == (None, -5.0)
    assert (
        refusal(RMACConfig, critic={"weights": ()})
        == "RMACConfig.critic.weights must be a list of finite numbers >= 0 or None, got ()"
    )


def test_invalid_parameter_error_is_a_value_and_a_type_error():
    # Callers that catch either (the CLI's one-line messages, the sweep checker) see it.
    with pytest.raises(ValueError):
        MLACConfig(alpha_a="fast")
    with pytest.raises(TypeError):
        MLACConfig(alpha_a="fast")


@pytest.mark.parametrize(
    "key, value, cls, field",
    [
        ("rmac.alpha_r", "fast", RMACConfig, "alpha_r"),
        ("rmac.norm", True, RMACConfig, "norm"),
        ("rmac.exploration.period", 3.5, Exploration, "period"),
        ("s-ac.alpha_c", True, StandardACConfig, "alpha_c"),
        ("mlac.critic.clip", "no", LLRConfig, "clip"),
    ],
)
def test_the_sweep_checker_expects_what_the_config_expects(tmp_path, key, value, cls, field):
    """A sweep file's value is judged by the config's own table: the same words after 'expected'."""
    algorithm = key.split(".")[0]
    toml = {str: f'"{value}"', bool: str(value).lower()}.get(type(value), repr(value))
    path = pathlib.Path(tmp_path) / "sweep.toml"
    path.write_text(f'[protocol]\nalgorithms = ["{algorithm}"]\n[grid]\n"{key}" = [{toml}]\n')
    with pytest.raises(UserInputError) as error:
        load_sweep(path)
    expected = constraints.unmet(value, cls.parameter_constraints[field])
    assert expected is not None and f"expected {expected}, got {toml}" in str(error.value)
    assert f"{cls.__name__}.{field} must be {expected}, got {value!r}" == refusal(
        cls, **{field: value}
    )


def test_a_nested_setting_given_alone_keeps_the_learners_other_defaults():
    # `--set recommended.planning.model_capacity=120` changes one setting of MPC's planning
    # (30 steps from visited states), not of Planning()'s (no planning at all).
    from rmac_mj.agents import DynaACConfig, MPCConfig, Planning

    mpc = config_from_dict(MPCConfig, {"planning": {"model_capacity": 120}})
    assert mpc.planning == dataclasses.replace(MPCConfig().planning, model_capacity=120)
    assert mpc.planning != Planning(model_capacity=120)
    dyna = config_from_dict(DynaACConfig, {"planning": {"model_capacity": 120}, "lookahead": 3})
    assert (dyna.planning.steps, dyna.planning.model_capacity, dyna.lookahead) == (30, 120, 3)
    assert config_from_dict(MPCConfig, dataclasses.asdict(mpc)) == mpc
