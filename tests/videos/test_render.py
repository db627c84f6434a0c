"""Off-screen rendering: frames show the pendulum where it is, videos read back, clear back-end errors."""

from __future__ import annotations

import imageio.v2 as imageio
import mujoco
import numpy as np
import pytest

from rmac_mj import _gl, tasks
from rmac_mj.rollout import run_trial
from rmac_mj.videos import encode as video
from rmac_mj.videos import render_episode, render_state, result_videos

SHORT = {"time_limit": 0.3}  # 10 control steps: enough to see motion, quick to render


from scripted import energy_pump_agent  # noqa: E402  (tests/ is on sys.path)


def _arm_rows(image: np.ndarray) -> np.ndarray:
    """Row indices of the arm's and mass's pixels (red/brass: strong red, weak blue)."""
    red, blue = image[..., 0].astype(int), image[..., 2].astype(int)
    return np.nonzero((red > 120) & (blue < 0.6 * red))[0]


@pytest.mark.slow
def test_frames_have_the_requested_size_and_are_not_blank():
    env = tasks.load("dc_pendulum", "swingup", task_kwargs=SHORT)
    episode = render_episode(env, energy_pump_agent(), width=160, height=120, overlay=False)
    assert episode.frames.shape == (11, 120, 160, 3) and episode.frames.dtype == np.uint8
    for frame in episode.frames:
        assert frame.std() > 10 and len(np.unique(frame.reshape(-1, 3), axis=0)) > 20
    assert episode.fps == pytest.approx(1 / 0.03)
    np.testing.assert_allclose(episode.times, 0.03 * np.arange(11), atol=1e-9)
    assert not np.array_equal(episode.frames[0], episode.frames[-1])  # it swung


@pytest.mark.slow
def test_arm_pixels_are_above_the_axis_upright_and_below_it_hanging():
    env = tasks.load("dc_pendulum", "swingup")
    up = render_state(env, 0.0, width=160, height=120)
    down = render_state(env, np.pi, width=160, height=120)
    rows_up, rows_down = _arm_rows(up), _arm_rows(down)
    assert len(rows_up) > 30 and len(rows_down) > 30
    assert rows_up.mean() + 10 < rows_down.mean()  # image rows grow downwards
    changed = np.any(up != down, axis=-1)
    assert 0.01 < changed.mean() < 0.2  # the arm moved; the rest of the scene did not


@pytest.mark.slow
def test_substep_frames_follow_the_physics_and_the_episode_is_env_step():
    env = tasks.load("dc_pendulum", "swingup", task_kwargs=SHORT)
    agent = energy_pump_agent()
    coarse = render_episode(env, agent, width=64, height=48, overlay=False)
    fine = render_episode(
        env, policy=agent.greedy_action, width=64, height=48, frames_per_step=3, overlay=False
    )
    assert fine.frames.shape[0] == 31 and fine.fps == pytest.approx(100.0)
    np.testing.assert_array_equal(fine.states[::3], coarse.states)
    np.testing.assert_array_equal(fine.actions[::3], coarse.actions)
    assert fine.total_return == coarse.total_return == run_trial(env, agent, learn=False)

    # The intermediate frames are the physics substeps: replay them by hand with mj_step.
    physics = env.physics
    env.reset()
    angles = [physics.angle()]
    for _ in range(10):
        physics.set_control(agent.greedy_action(physics.state()))
        for _ in range(3):
            mujoco.mj_step(physics.model.ptr, physics.data.ptr)
            angles.append(physics.angle())
    np.testing.assert_allclose(fine.states[:, 0], angles, atol=1e-12)


@pytest.mark.slow
def test_overlay_and_labels_draw_text():
    env = tasks.load("dc_pendulum", "swingup", task_kwargs={"time_limit": 0.03})
    plain = render_episode(env, energy_pump_agent(), width=160, height=120, overlay=False)
    text = render_episode(env, energy_pump_agent(), width=160, height=120, label="RMAC")
    differs = np.any(plain.frames[0] != text.frames[0], axis=-1)
    assert differs[:60, :40].any() and differs[:60, 100:].any()  # label top-left, numbers top-right
    assert not differs[80:].any()  # the rig below is untouched


def test_invalid_arguments_are_rejected_with_their_names():
    env = tasks.load("dc_pendulum", "swingup", task_kwargs=SHORT)
    agent = energy_pump_agent()
    with pytest.raises(ValueError, match="frames_per_step"):
        render_episode(env, agent, frames_per_step=2)
    with pytest.raises(ValueError, match="width"):
        render_episode(env, agent, width=1000)
    with pytest.raises(ValueError, match="exactly one of agent"):
        render_episode(env, agent, policy=agent.greedy_action)


def _moving_square(frames: int, height: int, width: int) -> np.ndarray:
    clip = np.full((frames, height, width, 3), 30, dtype=np.uint8)
    for t in range(frames):
        clip[t, 10:20, 2 * t : 2 * t + 10] = (230, 80, 40)
    return clip


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_videos_are_written_and_read_back(tmp_path, suffix):
    clip = _moving_square(12, 49, 65)  # odd size: MP4 pads to even
    path = video.write_video(clip, tmp_path / f"clip{suffix}", fps=30)
    frames = imageio.mimread(path)
    assert len(frames) == 12
    expected = (50, 66) if suffix == ".mp4" else (49, 65)
    assert frames[0].shape[:2] == expected
    assert np.abs(frames[5][:49, :65, :3].astype(int) - clip[5]).mean() < 8  # same picture


def test_gif_can_be_made_smaller(tmp_path):
    clip = _moving_square(12, 48, 64)
    path = video.write_video(clip, tmp_path / "small.gif", fps=30, scale=0.5, frame_step=2)
    frames = imageio.mimread(path)
    assert len(frames) == 6 and frames[0].shape[:2] == (24, 32)


def test_unknown_video_format_is_rejected(tmp_path):
    with pytest.raises(ValueError, match=r"\.mp4"):
        video.write_video(_moving_square(2, 8, 8), tmp_path / "clip.avi", fps=30)


def test_side_by_side_and_sequence_compose_clips():
    a, b = _moving_square(5, 40, 60), _moving_square(3, 40, 60)
    both = video.side_by_side([a, b], labels=["S-AC", "RMAC"])
    assert both.shape == (5, 40, 60 + 4 + 60, 3)
    np.testing.assert_array_equal(
        both[4, 30:, 64:], b[2, 30:]
    )  # the short clip holds its last frame
    chain = video.sequence([a, b], hold=2)
    assert chain.shape == (5 + 2 + 3 + 2, 40, 60, 3)
    np.testing.assert_array_equal(chain[7], b[0])
    with pytest.raises(ValueError, match="frame size"):
        video.side_by_side([a, _moving_square(5, 40, 62)])


def _fake_results(tmp_path, monkeypatch, trials=(1, 10)):
    """A result directory of empty snapshot files that "load" as the scripted agent on a short task."""
    for algorithm in ("rmac", "s-ac"):
        for trial in trials:
            path = tmp_path / "snapshots" / algorithm / "exp_000" / f"trial_{trial:04d}.npz"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(b"")

    def load(path):
        algorithm, trial = path.parent.parent.name, int(path.stem.split("_")[1])
        return energy_pump_agent(), {
            "algorithm": algorithm,
            "domain": "dc_pendulum",
            "task": "swingup",
            "task_kwargs": {"time_limit": 0.09},
            "trial": trial,
        }

    monkeypatch.setattr(result_videos, "load_snapshot", load)
    return tmp_path


@pytest.mark.slow
def test_progression_and_comparison_from_a_result_directory(tmp_path, monkeypatch):
    results = _fake_results(tmp_path, monkeypatch)
    options = result_videos.VideoOptions(width=64, height=48, overlay=False)
    path = result_videos.render_progression(results, tmp_path / "progression.mp4", options=options)
    assert len(imageio.mimread(path)) == 2 * (4 + 17)  # 4 frames each, last held 0.5 s at 33.3 fps
    # (a GIF merges the held frames into one long frame, so its count would not tell)
    path = result_videos.render_comparison(results, tmp_path / "comparison.gif", options=options)
    assert imageio.mimread(path)[0].shape[:2] == (48, 64 + 4 + 64)
    with pytest.raises(FileNotFoundError, match=r"available: \[1, 10\]"):
        result_videos.render_progression(
            results, tmp_path / "p.gif", trials=(1, 600), options=options
        )


def test_backend_selection_prefers_egl_then_osmesa(monkeypatch):
    monkeypatch.setattr(_gl, "has_display", lambda environ=None: False)
    monkeypatch.setattr(_gl, "can_load_library", lambda stem, sonames=(): True)
    environ = {}
    assert _gl.select_gl_backend(environ) == "egl"
    assert environ == {"MUJOCO_GL": "egl", "PYOPENGL_PLATFORM": "egl"}
    monkeypatch.setattr(_gl, "can_load_library", lambda stem, sonames=(): stem == "OSMesa")
    environ = {}
    assert _gl.select_gl_backend(environ) == "osmesa"
    assert environ == {"MUJOCO_GL": "osmesa", "PYOPENGL_PLATFORM": "osmesa"}
    monkeypatch.setattr(_gl, "can_load_library", lambda stem, sonames=(): True)
    monkeypatch.setattr(_gl, "egl_device_count", lambda sonames=(): 0)  # libEGL without a vendor
    assert _gl.select_gl_backend({}) == "osmesa"
    environ = {"MUJOCO_GL": "glfw"}  # the user's choice is kept
    assert _gl.select_gl_backend(environ) == "glfw" and environ == {"MUJOCO_GL": "glfw"}


def test_missing_backend_gives_one_clear_message(monkeypatch):
    monkeypatch.setattr(_gl, "has_display", lambda environ=None: False)
    monkeypatch.setattr(_gl, "can_load_library", lambda stem, sonames=(): False)
    environ = {}
    assert _gl.select_gl_backend(environ) is None and environ == {"MUJOCO_GL": "disable"}
    with pytest.raises(_gl.GLBackendError, match="apt-get install libegl1"):
        _gl.require_gl_backend(environ)
    with pytest.raises(_gl.GLBackendError, match="no display"):
        _gl.require_gl_backend({})
    # The renderers check before touching OpenGL (here MUJOCO_GL=egl, but libEGL "cannot load").
    env = tasks.load("dc_pendulum", "swingup", task_kwargs=SHORT)
    with pytest.raises(_gl.GLBackendError, match="libosmesa6"):
        render_episode(env, energy_pump_agent())


@pytest.mark.slow
@pytest.mark.parametrize("frames_per_step", [1, 3])
def test_a_3_s_episode_plays_3_s_as_a_gif(tmp_path, frames_per_step):
    """GIF delays are whole centiseconds: 1000/fps ms truncated played 1.5x too fast, and delays under
    2 cs (which browsers show as 10 cs) played 10x too slow."""
    from PIL import Image

    env = tasks.load("dc_pendulum", "swingup")  # the paper's 3 s trial
    episode = render_episode(
        env,
        energy_pump_agent(),
        width=32,
        height=24,
        overlay=False,
        frames_per_step=frames_per_step,
    )
    path = video.write_video(episode.frames, tmp_path / "swingup.gif", fps=episode.fps)
    delays = []
    with Image.open(path) as gif:
        for index in range(gif.n_frames):
            gif.seek(index)
            delays.append(gif.info["duration"])
    assert sum(delays) / 1000 == pytest.approx(3.0, abs=0.15)
    assert min(delays) >= 20


@pytest.mark.parametrize("fps", [100 / 3, 30.0, 60.0, 100.0])
def test_gif_delays_add_up_to_real_time(fps):
    step, delays = video.gif_timing(301, fps)
    assert delays.min() >= video.GIF_MIN_DELAY_CS
    assert delays.sum() / 100 == pytest.approx(len(range(0, 301, step)) * step / fps, abs=0.005)


@pytest.mark.slow
def test_the_camera_frames_the_pendulum():
    """Upright and hanging, the pendulum spans most of the frame's height, centred on the axis."""
    env = tasks.load("dc_pendulum", "swingup")
    rows = np.concatenate(
        [_arm_rows(render_state(env, phi, width=160, height=120)) for phi in (0.0, np.pi)]
    )
    assert rows.max() - rows.min() > 0.6 * 120
    assert 0.35 * 120 < (rows.max() + rows.min()) / 2 < 0.65 * 120
