"""A policy map's resolution is checked before a grid of resolution**2 states is allocated."""

from __future__ import annotations

import pytest

from rmac_mj import constraints
from rmac_mj.figures import MapView


@pytest.mark.parametrize("resolution", [100_000, 1, 0, 2.5, True])
def test_a_map_resolution_beyond_its_limit_is_refused_naming_it(resolution):
    # Refused when the view is made: before any figure looks at it or builds a grid.
    with pytest.raises(ValueError) as refused:
        MapView(anchor=[0.0, 0.0], resolution=resolution)
    message = str(refused.value)
    assert message.startswith("MapView.resolution must be an integer in [2, 2000]")
    assert constraints.MAP_RESOLUTION.reason in message
