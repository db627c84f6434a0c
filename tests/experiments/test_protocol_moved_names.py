"""The names that left ``rmac_mj.experiments.protocol`` are refused there with their new module."""

import importlib

import pytest

from rmac_mj.experiments import experiment, experiment_loop, protocol


@pytest.mark.parametrize(
    "name, home",
    [
        ("build_experiment", experiment),
        ("experiment_seeds", experiment),
        ("demonstration_for", experiment),
        ("fresh_learners", experiment),
        ("run_experiment", experiment_loop),
        ("ExperimentSpec", experiment_loop),
    ],
)
def test_a_moved_name_is_refused_naming_its_new_module(name, home):
    assert hasattr(home, name)
    with pytest.raises(protocol.MovedName, match=home.__name__):
        getattr(protocol, name)
    with pytest.raises(ImportError, match=rf"from {home.__name__} import {name}"):
        exec(f"from rmac_mj.experiments.protocol import {name}", {})


def test_an_unknown_name_is_a_plain_attribute_error():
    module = importlib.import_module("rmac_mj.experiments.protocol")
    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        module.no_such_name  # noqa: B018
