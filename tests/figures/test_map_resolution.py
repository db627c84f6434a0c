"""A policy map's resolution is checked before a grid of resolution**2 states is allocated."""

from __future__ import annotations

import pytest

from rmac_mj import constraints
from rmac_mj.figures import policies_figure


@pytest.mark.parametrize("resolution", [100_000, 1, 0, 2.5, True])
def test_a_map_resolution_beyond_its_limit_is_refused_naming_it(resolution):
    # Nothing else is looked at first: the refusal comes before any grid is built.
    with pytest.raises(ValueError) as refused:
        policies_figure([], None, None, resolution=resolution)
    message = str(refused.value)
    assert message.startswith("policies_figure.resolution must be an integer in [2, 2000]")
    assert constraints.MAP_RESOLUTION.reason in message
