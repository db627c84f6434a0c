"""Off-screen rendered episodes: frames of greedy episodes, labelled clips, MP4 and GIF files.

The renderer is ``mujoco.Renderer`` on the back end chosen by ``rmac_mj._gl`` (EGL, then OSMesa, on a
machine without a display); it is closed after every episode so nothing is left to tear down at exit. Any task of the suite
renders: the overlay reads the state and action labels from the task's ``learner_state``.

    from rmac_mj import tasks
    from rmac_mj.experiments import render
    episode = render.render_episode(tasks.load("dc_pendulum", "swingup"), agent, frames_per_step=3)
    render.write_video(episode.frames, "swingup.mp4", fps=episode.fps)

Result directories (``rmac-mj reproduce``) keep snapshots at
``RESULT_DIR/snapshots/<algorithm>/exp_<iii>/trial_<tttt>.npz``; :func:`render_progression` and
:func:`render_comparison` find them there.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import pathlib
import re
import time
from typing import TYPE_CHECKING, Callable, Sequence, Union

import numpy as np
from dm_control.rl import control
from PIL import Image, ImageDraw, ImageFont

from rmac_mj import _gl
from rmac_mj.errors import MissingInputError, UserInputError
from rmac_mj.agents import display_name
from rmac_mj.agents.base import Agent
from rmac_mj.experiments.episode import learner_state_of, n_sub_steps, state_of

if TYPE_CHECKING:  # mujoco is imported after the GL back end is chosen (rmac_mj._gl)
    import mujoco

#: Video formats :func:`write_video` writes, by file suffix.
VIDEO_SUFFIXES: tuple[str, ...] = (".mp4", ".gif")

#: A policy as a plain function: state x (shape (n,)) -> action u (shape (m,)).
Policy = Callable[[np.ndarray], np.ndarray]

#: A camera: a name or id of the model's cameras, a ``mujoco.MjvCamera``, or None for the model's first
#: camera (the free camera if it has none).
Camera = Union[str, int, None, "mujoco.MjvCamera"]

_PANEL_GAP = 4                       # px of background between side-by-side panels
_BACKGROUND = (24, 24, 28)           # RGB of gaps and padding
_TEXT_COLOUR = (240, 240, 240)
_BOX_SHADE = 0.35                    # brightness factor of the box behind overlay text


@dataclasses.dataclass(frozen=True)
class RenderedEpisode:
    """One rendered greedy episode; frame i shows the state at ``times[i]``.

    Attributes:
      frames: uint8 ndarray of shape (T, H, W, 3), T = 1 + steps * frames_per_step (the first frame
        is the start state).
      times: ndarray of shape (T,), simulated time of each frame (s).
      states: ndarray of shape (T, n), the learners' state x in each frame (the task's
        ``learner_state``).
      actions: ndarray of shape (T, m), the action being applied, saturated to the action bounds (0 in
        the start frame).
      returns: ndarray of shape (T,), running sum of rewards of the steps completed so far.
      fps: frames per second of simulated time (real-time playback rate).
      state_labels, action_labels: the task's labels of x and u, e.g. "angle phi [rad]".
    """

    frames: np.ndarray
    times: np.ndarray
    states: np.ndarray
    actions: np.ndarray
    returns: np.ndarray
    fps: float
    state_labels: tuple[str, ...] = ()
    action_labels: tuple[str, ...] = ()

    @property
    def total_return(self) -> float:
        """Sum of rewards of the whole episode."""
        return float(self.returns[-1])


# --------------------------------------------------------------------------------------------------
# Rendering


def open_renderer(model, width: int, height: int):
    """A ``mujoco.Renderer`` of ``model`` (an ``MjModel``) at ``width`` x ``height`` pixels.

    Use it as a context manager so its GL context is freed. Raises :class:`rmac_mj._gl.GLBackendError`
    (naming the system packages to install) when no GL back end can start.
    """
    _check_size(model, width, height)
    backend = _gl.require_gl_backend()
    import mujoco
    from mujoco.rendering.classic import gl_context

    context_class = getattr(gl_context, "GLContext", None)
    if context_class is None:
        raise _gl.GLBackendError(f"MuJoCo could not import its {backend} back end.\n{_gl.INSTALL_HINT}")
    if context_class.__module__.startswith("mujoco.glfw") and not _gl.has_display():
        # mujoco was imported before rmac_mj chose a back end (it reads MUJOCO_GL only then).
        raise _gl.GLBackendError("mujoco was imported before an off-screen back end was chosen, and "
                                 "there is no display for its default (GLFW): set MUJOCO_GL=egl "
                                 f"before starting Python, or import rmac_mj first.\n{_gl.INSTALL_HINT}")
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as error:  # context creation fails in many library-specific ways
        raise _gl.GLBackendError(f"the {backend} back end failed to start: {error}\n"
                                 f"{_gl.INSTALL_HINT}") from error


def _check_size(model, width: int, height: int) -> None:
    for name, value, limit, attribute in (("width", width, model.vis.global_.offwidth, "offwidth"),
                                          ("height", height, model.vis.global_.offheight, "offheight")):
        if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or not 0 < value <= limit:
            raise ValueError(f"{name} must be an integer in [1, {limit}] (the model's <global "
                             f"{attribute}>), got {value!r}")


def render_episode(env: control.Environment, agent: Agent | None = None, policy: Policy | None = None,
                   width: int = 320, height: int = 240, camera: Camera = None,
                   frames_per_step: int = 1, overlay: bool = True,
                   label: str | None = None) -> RenderedEpisode:
    """Run one greedy episode of ``env`` and render it.

    Args:
      env: an environment of the suite (its task has a ``learner_state``).
      agent: acts with ``agent.greedy_action(x)`` (no exploration, no learning); or give ``policy``.
      policy: a function x -> u, shapes (n,) -> (m,); exactly one of ``agent`` and ``policy``.
      width, height: frame size in pixels (at most the model's off-screen buffer).
      camera: see :data:`Camera`; by default the model's first camera.
      frames_per_step: frames per control step; it must divide the physics substeps per control
        step: 1 gives the control rate, the number of substeps every physics step.
      overlay: draw time, the state, the action and the running sum of rewards on every frame.
      label: text drawn in the top-left corner (e.g. "RMAC, trial 600"), when ``overlay``.

    Intermediate frames come from a scratch copy of the physics stepped with the same control, so the
    episode itself is exactly ``env.step``'s (the same return as ``run_trial(env, agent, learn=False)``).
    """
    act = _acting_function(agent, policy)
    physics = env.physics
    learner_state = learner_state_of(env)
    n_sub = n_sub_steps(env)
    if (not isinstance(frames_per_step, (int, np.integer)) or isinstance(frames_per_step, bool)
            or frames_per_step < 1 or n_sub % frames_per_step):
        raise ValueError(f"frames_per_step must be a positive divisor of the {n_sub} physics substeps "
                         f"per control step, got {frames_per_step!r}")
    import mujoco

    spec = env.action_spec()
    a_low, a_high = np.broadcast_to(spec.minimum, spec.shape), np.broadcast_to(spec.maximum, spec.shape)
    substeps_per_frame = n_sub // frames_per_step
    frames, times, states, actions, returns = [], [], [], [], []
    total = 0.0
    with open_renderer(physics.model.ptr, width, height) as renderer:
        camera = _camera(physics.model.ptr, camera)

        def record(source, x: np.ndarray, u: np.ndarray) -> None:
            renderer.update_scene(source.data.ptr, camera=camera)
            frames.append(renderer.render())
            times.append(float(source.data.time))
            states.append(x)
            actions.append(u)
            returns.append(total)

        timestep = env.reset()
        record(physics, state_of(timestep.observation, learner_state), np.zeros(spec.shape))
        scratch = physics.copy(share_model=True) if frames_per_step > 1 else None
        while not timestep.last():
            u = act(state_of(timestep.observation, learner_state))
            if scratch is not None:
                mujoco.mj_copyData(scratch.data.ptr, physics.model.ptr, physics.data.ptr)
            timestep = env.step(u)
            applied = np.clip(np.asarray(u, dtype=float).reshape(spec.shape), a_low, a_high)
            if scratch is not None:
                scratch.data.ctrl[:] = physics.data.ctrl
                for substep in range(1, n_sub):
                    mujoco.mj_step(scratch.model.ptr, scratch.data.ptr)
                    if substep % substeps_per_frame == 0:
                        mujoco.mj_forward(scratch.model.ptr, scratch.data.ptr)  # positions for drawing
                        record(scratch, state_of(env.task.get_observation(scratch), learner_state),
                               applied)
            total += float(timestep.reward)
            record(physics, state_of(timestep.observation, learner_state), applied)
    episode = RenderedEpisode(frames=np.stack(frames), times=np.array(times), states=np.array(states),
                              actions=np.array(actions).reshape(len(frames), -1),
                              returns=np.array(returns), fps=frames_per_step / env.control_timestep(),
                              state_labels=learner_state.labels,
                              action_labels=learner_state.action_labels)
    if overlay:
        episode = dataclasses.replace(episode, frames=draw_overlay(episode, label=label))
    return episode


def _camera(model, camera):
    """``camera`` as ``mujoco.Renderer.update_scene`` takes it; None: the first camera, else free."""
    if camera is None:
        return 0 if model.ncam > 0 else -1
    return camera


def _acting_function(agent: Agent | None, policy: Policy | None) -> Policy:
    if (agent is None) == (policy is None):
        raise ValueError("give exactly one of agent (an Agent) and policy (a function x -> u), got "
                         f"agent={agent!r}, policy={policy!r}")
    if agent is not None:
        if not isinstance(agent, Agent):
            raise TypeError(f"agent must be an rmac_mj Agent, got {type(agent).__name__}")
        agent.begin_greedy_trial()
        return agent.greedy_action
    if not callable(policy):
        raise TypeError(f"policy must be a function x -> u, got {type(policy).__name__}")
    return policy


def render_state(env: control.Environment, qpos, width: int = 480, height: int = 360,
                 camera: Camera = None) -> np.ndarray:
    """One picture of ``env``'s model at rest at joint positions ``qpos`` (shape (nq,), or a scalar
    for a one-joint model); uint8 (H, W, 3)."""
    import mujoco

    physics = env.physics.copy(share_model=True)
    model, data = physics.model.ptr, physics.data.ptr
    data.qpos[:] = np.broadcast_to(np.asarray(qpos, dtype=float), (model.nq,))
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)
    with open_renderer(model, width, height) as renderer:
        renderer.update_scene(data, camera=_camera(model, camera))
        return renderer.render()


def free_camera(model, azimuth: float = 65.0, elevation: float = -12.0, zoom: float = 1.0):
    """A free ``mujoco.MjvCamera`` on the model's centre, from ``azimuth``/``elevation`` (degrees);
    ``zoom`` > 1 comes closer than MuJoCo's default distance."""
    import mujoco

    camera = mujoco.MjvCamera()
    mujoco.mjv_defaultFreeCamera(model, camera)
    camera.azimuth, camera.elevation = azimuth, elevation
    camera.distance /= zoom
    return camera


def model_picture(domain: str, task: str, out_path: str | os.PathLike, qpos=None,
                  camera: Camera = None, width: int = 480, height: int = 360) -> pathlib.Path:
    """Write a picture of a domain's model (e.g. the one in its ``models/<name>/README.md``).

    ``qpos`` (default: the task's start) poses the model; ``camera`` as in :func:`render_state`.
    Example: ``model_picture("dc_pendulum", "swingup", "pendulum.png", qpos=2.3,
    camera=free_camera(model, zoom=3))``.
    """
    from rmac_mj import tasks

    env = tasks.load(domain, task)
    if qpos is None:
        env.reset()
        qpos = env.physics.data.qpos.copy()
    image = render_state(env, qpos, width, height, camera=camera)
    out_path = pathlib.Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(image).save(out_path, optimize=True)
    return out_path


def measure_fps(domain: str = "dc_pendulum", task: str = "swingup", width: int = 320,
                height: int = 240, frames: int = 200) -> float:
    """Frames per second of the off-screen renderer here (scene update + render + read-back)."""
    from rmac_mj import tasks

    physics = tasks.load(domain, task).physics
    import mujoco

    model, data = physics.model.ptr, physics.data.ptr
    rng = np.random.default_rng(0)
    with open_renderer(model, width, height) as renderer:
        camera = _camera(model, None)
        renderer.update_scene(data, camera=camera)
        renderer.render()  # warm-up: first-frame compilation of shaders
        start = time.perf_counter()
        for _ in range(frames):
            data.qpos[:] = rng.uniform(-np.pi, np.pi, model.nq)  # a new pose every frame
            mujoco.mj_kinematics(model, data)
            renderer.update_scene(data, camera=camera)
            renderer.render()
        return frames / (time.perf_counter() - start)


# --------------------------------------------------------------------------------------------------
# Text on frames, composition


@functools.lru_cache(maxsize=8)
def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow without FreeType: a fixed bitmap font
        return ImageFont.load_default()


_MEASURE = ImageDraw.Draw(Image.new("RGB", (1, 1)))


def _draw_text(frame: np.ndarray, lines: Sequence[str], corner: str = "top-left") -> np.ndarray:
    """A copy of ``frame`` (uint8, (H, W, 3)) with ``lines`` on a darkened box in a corner."""
    height, width, _ = frame.shape
    font = _font(max(10, height // 20))
    text = "\n".join(lines)
    left, top, right, bottom = _MEASURE.multiline_textbbox((0, 0), text, font=font, spacing=2)
    margin = max(3, height // 60)
    box_w, box_h = right - left + 2 * margin, bottom - top + 2 * margin
    x = margin if corner.endswith("left") else max(0, width - box_w - margin)
    y = margin if corner.startswith("top") else max(0, height - box_h - margin)
    out = frame.copy()
    out[y:y + box_h, x:x + box_w] = (out[y:y + box_h, x:x + box_w] * _BOX_SHADE).astype(np.uint8)
    image = Image.fromarray(out)
    ImageDraw.Draw(image).multiline_text((x + margin - left, y + margin - top), text, font=font,
                                         fill=_TEXT_COLOUR, spacing=2)
    return np.asarray(image)


_LABEL = re.compile(r"^(?P<name>.*?)\s*\[(?P<unit>[^\]]*)\]\s*$")


def short_label(label: str) -> tuple[str, str]:
    """(symbol, unit) of a task's axis label "description symbol [unit]": its last word and its unit,
    e.g. "angle phi [rad]" -> ("phi", "rad"), "u [V]" -> ("u", "V")."""
    match = _LABEL.match(label)
    name, unit = (match.group("name"), match.group("unit")) if match else (label, "")
    words = name.split()
    return (words[-1] if words else label), unit


def _value_line(label: str, value: float) -> str:
    symbol, unit = short_label(label)
    return f"{symbol} = {value:+5.2f}" + (f" {unit}" if unit else "")


def draw_overlay(episode: RenderedEpisode, label: str | None = None) -> np.ndarray:
    """The episode's frames with time, state, action and running sum of rewards; (T, H, W, 3).

    Each state and action dimension is shown by its label's symbol and unit (see :func:`short_label`);
    without labels, as x1, x2, ... and u1, ....
    """
    n, m = episode.states.shape[1], episode.actions.shape[1]
    state_labels = episode.state_labels if len(episode.state_labels) == n else [
        f"x{k + 1}" for k in range(n)]
    action_labels = episode.action_labels if len(episode.action_labels) == m else [
        f"u{k + 1}" for k in range(m)]
    out = np.empty_like(episode.frames)
    for i, frame in enumerate(episode.frames):
        lines = [f"t = {episode.times[i]:4.2f} s"]
        lines += [_value_line(text, v) for text, v in zip(state_labels, episode.states[i])]
        lines += [_value_line(text, v) for text, v in zip(action_labels, episode.actions[i])]
        lines.append(f"sum r = {episode.returns[i]:.1f}")
        framed = _draw_text(frame, lines, corner="top-right")
        out[i] = _draw_text(framed, [label], corner="top-left") if label else framed
    return out


def label_frames(frames: np.ndarray, label: str) -> np.ndarray:
    """``frames`` (T, H, W, 3) with ``label`` in the top-left corner of each."""
    frames = _check_frames(frames, "frames")
    return np.stack([_draw_text(frame, [label]) for frame in frames])


def _check_frames(frames, name: str) -> np.ndarray:
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[-1] != 3 or frames.dtype != np.uint8 or len(frames) == 0:
        raise ValueError(f"{name} must be a non-empty uint8 array of shape (T, H, W, 3), got "
                         f"dtype {frames.dtype} and shape {frames.shape}")
    return frames


def _check_labels(labels: Sequence[str] | None, count: int) -> list[str | None]:
    if labels is None:
        return [None] * count
    labels = list(labels)
    if len(labels) != count:
        raise ValueError(f"labels must give one label per clip ({count}), got {len(labels)}")
    return labels


def _pad_time(frames: np.ndarray, length: int) -> np.ndarray:
    """Hold the last frame so that the clip has ``length`` frames."""
    if len(frames) == length:
        return frames
    return np.concatenate([frames, np.repeat(frames[-1:], length - len(frames), axis=0)])


def side_by_side(clips: Sequence[np.ndarray], labels: Sequence[str] | None = None,
                 gap: int = _PANEL_GAP) -> np.ndarray:
    """Clips of one frame size played together, left to right; uint8 (T, H, W_total, 3).

    Shorter clips hold their last frame; ``labels`` (one per clip) are drawn top-left of each panel.
    """
    clips = [_check_frames(clip, f"clips[{i}]") for i, clip in enumerate(clips)]
    if not clips:
        raise ValueError("side_by_side needs at least one clip")
    if len({clip.shape[1:] for clip in clips}) != 1:
        raise ValueError(f"clips must share one frame size, got {[clip.shape[1:3] for clip in clips]}")
    labels = _check_labels(labels, len(clips))
    length = max(len(clip) for clip in clips)
    panels = [_pad_time(label_frames(clip, label) if label else clip, length)
              for clip, label in zip(clips, labels)]
    _, height, _, _ = panels[0].shape
    spacer = np.empty((length, height, gap, 3), dtype=np.uint8)
    spacer[:] = _BACKGROUND
    parts = [panels[0]]
    for panel in panels[1:]:
        parts += [spacer, panel]
    return np.concatenate(parts, axis=2)


def sequence(clips: Sequence[np.ndarray], labels: Sequence[str] | None = None,
             hold: int = 0) -> np.ndarray:
    """Clips of one frame size played one after another; uint8 (sum T_i + hold * n, H, W, 3).

    ``labels`` (one per clip) are drawn top-left; each clip's last frame is held ``hold`` extra frames.
    """
    clips = [_check_frames(clip, f"clips[{i}]") for i, clip in enumerate(clips)]
    if not clips:
        raise ValueError("sequence needs at least one clip")
    if len({clip.shape[1:] for clip in clips}) != 1:
        raise ValueError(f"clips must share one frame size, got {[clip.shape[1:3] for clip in clips]}")
    if not isinstance(hold, (int, np.integer)) or hold < 0:
        raise ValueError(f"hold must be an integer >= 0 (frames), got {hold!r}")
    labels = _check_labels(labels, len(clips))
    parts = [_pad_time(label_frames(clip, label) if label else clip, len(clip) + hold)
             for clip, label in zip(clips, labels)]
    return np.concatenate(parts, axis=0)


# --------------------------------------------------------------------------------------------------
# Video files


def write_video(frames: np.ndarray, path: str | os.PathLike, fps: float, scale: float = 1.0,
                frame_step: int = 1) -> pathlib.Path:
    """Write ``frames`` (uint8, (T, H, W, 3)) to ``path``: ``.mp4`` (H.264) or ``.gif``.

    Args:
      fps: playback frames per second of ``frames`` (e.g. ``RenderedEpisode.fps`` for real time).
      scale: resize factor in (0, 1] (GIFs grow fast: 0.5 quarters the pixels).
      frame_step: keep every ``frame_step``-th frame (the playback rate is divided too, so the clip
        keeps its duration).

    MP4 goes through imageio-ffmpeg's bundled ffmpeg (libx264, yuv420p; odd sizes are padded to even),
    GIF through Pillow (identical consecutive frames are merged into one longer frame) with delays in
    whole centiseconds that add up to real time (:func:`gif_timing`; above 50 fps every other frame
    is dropped, since browsers slow down shorter delays).
    """
    frames = _check_frames(frames, "frames")
    path = pathlib.Path(path)
    suffix = path.suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise UserInputError(f"path must end in one of {VIDEO_SUFFIXES}, got {str(path)!r}")
    if not (np.isscalar(fps) and np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps!r}")
    if not (np.isscalar(scale) and 0 < scale <= 1):
        raise ValueError(f"scale must be in (0, 1], got {scale!r}")
    if not isinstance(frame_step, (int, np.integer)) or frame_step < 1:
        raise ValueError(f"frame_step must be a positive integer, got {frame_step!r}")
    frames = frames[::frame_step]
    fps = fps / frame_step
    if scale != 1:
        _, height, width, _ = frames.shape
        size = (max(2, round(width * scale)), max(2, round(height * scale)))
        frames = np.stack([np.asarray(Image.fromarray(f).resize(size, Image.Resampling.LANCZOS))
                           for f in frames])
    path.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".mp4":
        _write_mp4(frames, path, fps)
    else:
        _write_gif(frames, path, fps)
    return path


def _write_mp4(frames: np.ndarray, path: pathlib.Path, fps: float) -> None:
    import imageio_ffmpeg

    _, height, width, _ = frames.shape
    # yuv420p halves the chroma resolution, so H.264 needs even sizes: pad with the last row/column.
    frames = np.pad(frames, ((0, 0), (0, height % 2), (0, width % 2), (0, 0)), mode="edge")
    writer = imageio_ffmpeg.write_frames(str(path), (frames.shape[2], frames.shape[1]), fps=fps,
                                         codec="libx264", pix_fmt_out="yuv420p", macro_block_size=1,
                                         quality=7, ffmpeg_log_level="error")
    writer.send(None)  # start ffmpeg
    try:
        for frame in frames:
            writer.send(np.ascontiguousarray(frame))
    finally:
        writer.close()


#: Browsers play a GIF frame delay below 2 cs as 10 cs: no frame is ever shorter.
GIF_MIN_DELAY_CS = 2


def gif_timing(count: int, fps: float) -> tuple[int, np.ndarray]:
    """How to play ``count`` frames at ``fps`` in real time as a GIF, whose delays are whole
    centiseconds of at least :data:`GIF_MIN_DELAY_CS`.

    Returns (step, delays): keep every ``step``-th frame (1 unless ``fps`` > 50) and show kept frame
    i for ``delays[i]`` cs. Frame i ends at ``round((i + 1) * 100 / fps')`` cs (fps' = fps / step), so
    the delays are the frame period rounded up or down in turn and the clip's length is right to
    within half a centisecond, not off by the truncation of every frame (1000/fps ms at 33.3 fps is
    29.99 ms, which Pillow would store as 2 cs, 1.5x too fast).
    """
    step = max(1, math.ceil(GIF_MIN_DELAY_CS * fps / 100.0 - 1e-9))
    kept = -(-count // step)
    ends = np.round(np.arange(1, kept + 1) * 100.0 * step / fps).astype(int)
    return step, np.diff(ends, prepend=0)


def _write_gif(frames: np.ndarray, path: pathlib.Path, fps: float) -> None:
    step, delays = gif_timing(len(frames), fps)
    images = [Image.fromarray(frame) for frame in frames[::step]]
    images[0].save(path, save_all=True, append_images=images[1:], loop=0, optimize=True, disposal=1,
                   duration=[int(10 * d) for d in delays])  # ms, whole centiseconds


# --------------------------------------------------------------------------------------------------
# Snapshots and result directories (what the ``rmac-mj render`` command calls)

def render_snapshot_episode(snapshot_path: str | os.PathLike, width: int = 320, height: int = 240,
                            camera: Camera = None, frames_per_step: int = 1,
                            overlay: bool = True, label: str | None = None,
                            domain: str | None = None, task: str | None = None) -> RenderedEpisode:
    """Render the greedy episode of the agent saved at ``snapshot_path``.

    The episode runs on the task the agent learned on, or on ``domain``/``task`` when given (with
    their default task_kwargs; the learner's state and action must have the same dimensions there).
    ``label`` defaults to e.g. "RMAC, trial 600" from the snapshot's meta data.
    """
    from rmac_mj.experiments.snapshots import load_snapshot

    agent, meta = load_snapshot(snapshot_path)
    env = snapshot_environment(agent, meta, domain, task)
    if label is None:
        label = display_name(meta["algorithm"])
        if meta.get("trial") is not None:
            label += f", trial {meta['trial']}"
    return render_episode(env, agent, width=width, height=height, camera=camera,
                          frames_per_step=frames_per_step, overlay=overlay, label=label)


def snapshot_environment(agent: Agent, meta: dict, domain: str | None = None,
                         task: str | None = None) -> control.Environment:
    """The environment a snapshot's agent acts in: the one it learned on (its domain, task and
    task_kwargs), or ``domain``/``task`` with their defaults; UserInputError if its state or action
    dimensions differ from the agent's."""
    from rmac_mj import tasks
    from rmac_mj.experiments.episode import action_space_of, state_space_of

    domain = domain or meta["domain"]
    task = task or (meta["task"] if domain == meta["domain"] else None)
    if task is None:
        raise UserInputError(f"give the task of domain {domain!r} too (the snapshot learned "
                             f"{meta['domain']}/{meta['task']})")
    own = (domain, task) == (meta["domain"], meta["task"])
    try:
        env = tasks.load(domain, task, task_kwargs=meta.get("task_kwargs") if own else None)
    except ValueError as error:
        raise UserInputError(str(error)) from None
    if own:
        return env
    n, m = state_space_of(env).dim, action_space_of(env).dim
    if (n, m) != (agent.state_space.dim, agent.action_space.dim):
        raise UserInputError(f"{domain}/{task} has {n} state and {m} action dimensions, the agent "
                             f"(learned on {meta['domain']}/{meta['task']}) "
                             f"{agent.state_space.dim} and {agent.action_space.dim}")
    return env


def render_snapshot(snapshot_path: str | os.PathLike, out_path: str | os.PathLike, width: int = 320,
                    height: int = 240, camera: Camera = None, frames_per_step: int = 1,
                    overlay: bool = True, scale: float = 1.0, frame_step: int = 1,
                    domain: str | None = None, task: str | None = None) -> pathlib.Path:
    """Render a snapshot's greedy episode to ``out_path`` (.mp4 or .gif) at real-time speed (on
    ``domain``/``task`` when given, see :func:`render_snapshot_episode`)."""
    _check_video_path(out_path)
    episode = render_snapshot_episode(snapshot_path, width, height, camera, frames_per_step, overlay,
                                      domain=domain, task=task)
    return write_video(episode.frames, out_path, episode.fps, scale=scale, frame_step=frame_step)


def _check_video_path(out_path) -> None:
    if pathlib.Path(out_path).suffix.lower() not in VIDEO_SUFFIXES:  # fail before rendering
        raise UserInputError(f"out_path must end in one of {VIDEO_SUFFIXES}, got {str(out_path)!r}")


_TRIAL_FILE = re.compile(r"trial_(\d+)\.npz")


def snapshot_trials(result_dir: str | os.PathLike, algorithm: str,
                    experiment: int = 0) -> dict[int, pathlib.Path]:
    """Trial number -> snapshot path, for one algorithm and experiment of a result directory."""
    from rmac_mj.experiments.runner import snapshot_dir

    folder = snapshot_dir(result_dir, algorithm, experiment)
    found = {int(match.group(1)): path for path in folder.glob("trial_*.npz")
             if (match := _TRIAL_FILE.fullmatch(path.name))}
    if not found:
        available = sorted(p.name for p in (pathlib.Path(result_dir) / "snapshots").glob("*"))
        raise MissingInputError(f"no snapshots in {folder} (algorithms with snapshots in "
                                f"{result_dir}: {available or 'none'})")
    return dict(sorted(found.items()))


def _pick_trials(available: dict[int, pathlib.Path], trials: Sequence[int], where: str) -> list[int]:
    missing = [t for t in trials if t not in available]
    if missing:
        raise MissingInputError(f"no snapshot after trial(s) {missing} in {where}; "
                                f"available: {sorted(available)}")
    return list(trials)


def render_progression(result_dir: str | os.PathLike, out_path: str | os.PathLike, experiment: int = 0,
                       algorithm: str | None = None, trials: Sequence[int] | None = None,
                       layout: str = "sequence", width: int = 320, height: int = 240,
                       frames_per_step: int = 1, overlay: bool = True, scale: float = 1.0,
                       frame_step: int = 1) -> pathlib.Path:
    """One experiment's greedy episode after several trials, labelled, to ``out_path``.

    Args:
      algorithm: "rmac", "s-ac", ...; None picks "rmac" when it has snapshots, else the only one.
      trials: which snapshots (trial numbers); None takes all of them (1, 10, 50, 200 and the last,
        with the runner's defaults).
      layout: "sequence" (one after another, each last frame held 0.5 s) or "side_by_side".
    """
    _check_video_path(out_path)
    if layout not in ("sequence", "side_by_side"):
        raise UserInputError(f"layout must be 'sequence' or 'side_by_side', got {layout!r}")
    if algorithm is None:
        algorithms = sorted(p.name for p in (pathlib.Path(result_dir) / "snapshots").glob("*") if p.is_dir())
        if not algorithms:
            raise MissingInputError(f"no snapshots in {result_dir} (expected {result_dir}/snapshots/"
                                    "<algorithm>/exp_<iii>/trial_<tttt>.npz)")
        if "rmac" not in algorithms and len(algorithms) > 1:
            raise UserInputError(f"several algorithms have snapshots in {result_dir} ({algorithms}); "
                             "choose one with algorithm=")
        algorithm = "rmac" if "rmac" in algorithms else algorithms[0]
    available = snapshot_trials(result_dir, algorithm, experiment)
    chosen = _pick_trials(available, list(available) if trials is None else list(trials),
                          f"{result_dir} ({algorithm}, experiment {experiment})")
    episodes = [render_snapshot_episode(available[t], width, height, frames_per_step=frames_per_step,
                                        overlay=overlay, label=f"{display_name(algorithm)}, trial {t}")
                for t in chosen]
    clips = [episode.frames for episode in episodes]
    fps = episodes[0].fps
    frames = (sequence(clips, hold=int(round(0.5 * fps))) if layout == "sequence"
              else side_by_side(clips))
    return write_video(frames, out_path, fps, scale=scale, frame_step=frame_step)


def render_comparison(result_dir: str | os.PathLike, out_path: str | os.PathLike, trial: int | None = None,
                      experiment: int = 0, algorithms: Sequence[str] = ("s-ac", "rmac"),
                      width: int = 320, height: int = 240, frames_per_step: int = 1,
                      overlay: bool = True, scale: float = 1.0, frame_step: int = 1) -> pathlib.Path:
    """``algorithms`` side by side after the same ``trial`` (None: the last both have), to ``out_path``."""
    _check_video_path(out_path)
    available = {a: snapshot_trials(result_dir, a, experiment) for a in algorithms}
    if trial is None:
        common = set.intersection(*(set(trials) for trials in available.values()))
        if not common:
            raise MissingInputError(f"{list(algorithms)} share no snapshot trial in {result_dir} "
                                    f"(experiment {experiment}): "
                                    f"{ {a: sorted(t) for a, t in available.items()} }")
        trial = max(common)
    for algorithm, trials in available.items():
        _pick_trials(trials, [trial], f"{result_dir} ({algorithm}, experiment {experiment})")
    episodes = [render_snapshot_episode(available[a][trial], width, height,
                                        frames_per_step=frames_per_step, overlay=overlay)
                for a in algorithms]
    frames = side_by_side([episode.frames for episode in episodes])
    return write_video(frames, out_path, episodes[0].fps, scale=scale, frame_step=frame_step)
