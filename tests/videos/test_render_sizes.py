"""render's sizes are refused as one-line user errors, before the first frame is drawn."""

from __future__ import annotations

import time

import pytest
from test_render import energy_pump_agent

from rmac_mj import constraints, tasks
from rmac_mj.errors import UserInputError
from rmac_mj.videos import render_episode

SHORT = {"time_limit": 0.3}


@pytest.mark.parametrize(
    "options, named",
    [
        ({"width": 30000}, "width must be an integer in [1, 640]"),
        ({"height": 100000}, "height must be an integer in [1, 480]"),
        ({"frames_per_step": 2}, "frames_per_step must be a positive divisor of the 3"),
        ({"frames_per_step": 10**9}, "frames_per_step must be a positive divisor of the 3"),
    ],
)
def test_a_frame_size_the_model_cannot_draw_is_a_user_error(options, named):
    env = tasks.load("dc_pendulum", "swingup", task_kwargs=SHORT)
    with pytest.raises(UserInputError) as refused:
        render_episode(env, energy_pump_agent(), **options)
    assert str(refused.value).startswith(named)


def test_an_episode_whose_frames_cannot_be_kept_is_refused_before_the_first():
    # a day of swing-up at 3 frames per control step: 8.6 million frames of 640 x 480
    env = tasks.load("dc_pendulum", "swingup", task_kwargs={"time_limit": 86400.0})
    started = time.perf_counter()
    with pytest.raises(UserInputError) as refused:
        render_episode(env, energy_pump_agent(), width=640, height=480, frames_per_step=3)
    assert time.perf_counter() - started < 5.0
    message = str(refused.value)
    assert f"must be at most {constraints.VIDEO_BYTES.value}" in message
    assert constraints.VIDEO_BYTES.reason in message and "8640001 of 640x480" in message
