"""Off-screen rendered episodes: frames of greedy episodes with an overlay, pictures of models.

``mujoco.Renderer`` on the back end ``rmac_mj._gl`` chose, closed after every episode; the overlay
reads its labels from the task's ``learner_state``. ``render_episode(env, agent).frames``: (T, H, W,
3) uint8; encoding is :mod:`rmac_mj.videos.encode`'s.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
import re
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Union

import numpy as np
from dm_control.rl import control
from PIL import Image

from rmac_mj._gl import open_renderer
from rmac_mj.agents import Agent
from rmac_mj.constraints import VIDEO_BYTES
from rmac_mj.errors import UserInputError
from rmac_mj.rollout import learner_state_of, n_sub_steps, state_of, steps_per_trial
from rmac_mj.videos import encode as video

if TYPE_CHECKING:  # mujoco is imported after the GL back end is chosen (rmac_mj._gl)
    import mujoco

#: A policy as a plain function: state x (shape (n,)) -> action u (shape (m,)).
Policy = Callable[[np.ndarray], np.ndarray]

#: A camera: a name or id of the model's cameras, a ``mujoco.MjvCamera``, or None for the model's first
#: camera (the free camera if it has none).
Camera = Union[str, int, None, "mujoco.MjvCamera"]


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


def render_episode(
    env: control.Environment,
    agent: Agent | None = None,
    policy: Policy | None = None,
    width: int = 320,
    height: int = 240,
    camera: Camera = None,
    frames_per_step: int = 1,
    overlay: bool = True,
    label: str | None = None,
) -> RenderedEpisode:
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
    An outside environment without a MuJoCo physics (``rmac_mj.envs``, e.g. a Gymnasium one made to
    render) draws its own frames, one per control step, at its own size.
    """
    act = _acting_function(agent, policy)
    physics = getattr(env, "physics", None)
    if physics is None:
        if frames_per_step != 1:
            raise UserInputError(
                f"frames_per_step must be 1 for an environment that draws its own "
                f"frames, got {frames_per_step!r}"
            )
        return _render_own_frames(env, act, overlay, label)
    _check_frames_per_step(frames_per_step, n_sub_steps(env))
    recorder = _Recorder(learner_state_of(env))
    with open_renderer(physics.model.ptr, width, height) as renderer:  # checks the frame size
        _check_frames(1 + steps_per_trial(env) * frames_per_step, width, height)
        camera = _camera(physics.model.ptr, camera)

        def draw(source) -> np.ndarray:
            renderer.update_scene(source.data.ptr, camera=camera)
            return renderer.render()

        _run_drawn_episode(env, act, frames_per_step, recorder, draw)
    return recorder.episode(frames_per_step / env.control_timestep(), overlay, label)


def _check_frames_per_step(frames_per_step, n_sub: int) -> None:
    if (
        not isinstance(frames_per_step, (int, np.integer))
        or isinstance(frames_per_step, bool)
        or frames_per_step < 1
        or n_sub % frames_per_step
    ):
        raise UserInputError(
            f"frames_per_step must be a positive divisor of the {n_sub} physics substeps "
            f"per control step, got {frames_per_step!r}"
        )


def _action_bounds(env) -> tuple[np.ndarray, np.ndarray]:
    """The action spec's (low, high), each of its shape."""
    spec = env.action_spec()
    return np.broadcast_to(spec.minimum, spec.shape), np.broadcast_to(spec.maximum, spec.shape)


class _Recorder:
    """The frames of an episode as they are drawn, with the time, state, action and running
    return of each."""

    def __init__(self, learner_state) -> None:
        self.learner_state = learner_state
        self.frames, self.times, self.states, self.actions, self.returns = [], [], [], [], []

    def record(self, frame, time: float, x: np.ndarray, u: np.ndarray, total: float) -> None:
        self.frames.append(frame)
        self.times.append(time)
        self.states.append(x)
        self.actions.append(u)
        self.returns.append(total)

    def episode(self, fps: float, overlay: bool, label: str | None) -> RenderedEpisode:
        """The recorded episode, played at ``fps``; with its overlay drawn when ``overlay``."""
        episode = RenderedEpisode(
            frames=np.stack(self.frames),
            times=np.array(self.times),
            states=np.array(self.states),
            actions=np.array(self.actions).reshape(len(self.frames), -1),
            returns=np.array(self.returns),
            fps=fps,
            state_labels=self.learner_state.labels,
            action_labels=self.learner_state.action_labels,
        )
        if overlay:
            episode = dataclasses.replace(episode, frames=draw_overlay(episode, label=label))
        return episode


def _run_drawn_episode(env, act: Policy, frames_per_step: int, recorder: _Recorder, draw) -> None:
    """One greedy episode of ``env`` into ``recorder``, ``draw(physics)`` giving a frame: the
    start state, then ``frames_per_step`` frames per control step, the ones between steps from a
    scratch copy of the physics stepped with the same control."""
    import mujoco

    physics, learner_state = env.physics, recorder.learner_state
    n_sub = n_sub_steps(env)
    substeps_per_frame = n_sub // frames_per_step
    a_low, a_high = _action_bounds(env)
    total = 0.0

    def record(source, x: np.ndarray, u: np.ndarray) -> None:
        recorder.record(draw(source), float(source.data.time), x, u, total)

    timestep = env.reset()
    record(physics, state_of(timestep.observation, learner_state), np.zeros(a_low.shape))
    scratch = physics.copy(share_model=True) if frames_per_step > 1 else None
    # The observation of the scratch physics: the task's, or an outside environment's (rmac_mj.envs)
    observe = getattr(env, "observation_at", None) or env.task.get_observation
    while not timestep.last():
        u = act(state_of(timestep.observation, learner_state))
        if scratch is not None:
            mujoco.mj_copyData(scratch.data.ptr, physics.model.ptr, physics.data.ptr)
        timestep = env.step(u)
        applied = np.clip(np.asarray(u, dtype=float).reshape(a_low.shape), a_low, a_high)
        if scratch is not None:
            scratch.data.ctrl[:] = physics.data.ctrl
            for substep in range(1, n_sub):
                mujoco.mj_step(scratch.model.ptr, scratch.data.ptr)
                if substep % substeps_per_frame == 0:
                    mujoco.mj_forward(scratch.model.ptr, scratch.data.ptr)  # positions for drawing
                    record(scratch, state_of(observe(scratch), learner_state), applied)
        total += float(timestep.reward)
        record(physics, state_of(timestep.observation, learner_state), applied)


def _check_frames(count: int, width: int, height: int) -> None:
    """Refuse an episode whose ``count`` frames of ``width`` x ``height`` cannot be kept in memory,
    before the first is drawn."""
    size = count * int(width) * int(height) * 3
    if size > VIDEO_BYTES.value:
        raise UserInputError(
            VIDEO_BYTES.refusal(f"the frames ({count} of {width}x{height} pixels) in bytes", size)
            + ": render fewer frames per step or smaller ones"
        )


def _render_own_frames(env, act: Policy, overlay: bool, label: str | None) -> RenderedEpisode:
    """A greedy episode of an environment that draws its own frames (``env.render_frame()``)."""
    recorder = _Recorder(learner_state_of(env))
    a_low, a_high = _action_bounds(env)
    dt = env.control_timestep()
    total, u = 0.0, np.zeros(a_low.shape)
    timestep = env.reset()
    while True:
        x = state_of(timestep.observation, recorder.learner_state)
        recorder.record(env.render_frame(), dt * len(recorder.frames), x, u, total)
        if timestep.last():
            break
        u = np.clip(np.asarray(act(x), dtype=float).reshape(a_low.shape), a_low, a_high)
        timestep = env.step(u)
        total += float(timestep.reward)
    return recorder.episode(1.0 / dt, overlay, label)


def _camera(model, camera):
    """``camera`` as ``mujoco.Renderer.update_scene`` takes it; None: the first camera, else free."""
    if camera is None:
        return 0 if model.ncam > 0 else -1
    return camera


def _acting_function(agent: Agent | None, policy: Policy | None) -> Policy:
    if (agent is None) == (policy is None):
        raise ValueError(
            "give exactly one of agent (an Agent) and policy (a function x -> u), got "
            f"agent={agent!r}, policy={policy!r}"
        )
    if agent is not None:
        if not isinstance(agent, Agent):
            raise TypeError(f"agent must be an rmac_mj Agent, got {type(agent).__name__}")
        agent.begin_greedy_trial()
        return agent.greedy_action
    if not callable(policy):
        raise TypeError(f"policy must be a function x -> u, got {type(policy).__name__}")
    return policy


def render_state(
    env: control.Environment, qpos, width: int = 480, height: int = 360, camera: Camera = None
) -> np.ndarray:
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


def model_picture(
    domain: str,
    task: str,
    out_path: str | os.PathLike,
    qpos=None,
    camera: Camera = None,
    width: int = 480,
    height: int = 360,
) -> pathlib.Path:
    """Write a picture of a domain's model (e.g. the one in its ``models/<name>/README.md``).

    ``qpos`` (default: the task's start) poses the model; ``camera`` as in :func:`render_state`.
    Example: ``model_picture(domain, task, "model.png", qpos=2.3, camera=free_camera(model, zoom=3))``.
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


def measure_fps(
    domain: str | None = None,
    task: str | None = None,
    width: int = 320,
    height: int = 240,
    frames: int = 200,
) -> float:
    """Frames per second of the off-screen renderer here (scene update + render + read-back), on
    ``domain``/``task`` (default: the suite's default task)."""
    from rmac_mj import tasks

    physics = tasks.load(domain or tasks.DEFAULT_TASK[0], task or tasks.DEFAULT_TASK[1]).physics
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
    state_labels = (
        episode.state_labels if len(episode.state_labels) == n else [f"x{k + 1}" for k in range(n)]
    )
    action_labels = (
        episode.action_labels
        if len(episode.action_labels) == m
        else [f"u{k + 1}" for k in range(m)]
    )
    out = np.empty_like(episode.frames)
    for i, frame in enumerate(episode.frames):
        lines = [f"t = {episode.times[i]:4.2f} s"]
        lines += [_value_line(text, v) for text, v in zip(state_labels, episode.states[i])]
        lines += [_value_line(text, v) for text, v in zip(action_labels, episode.actions[i])]
        lines.append(f"sum r = {episode.returns[i]:.1f}")
        framed = video.draw_text(frame, lines, corner="top-right")
        out[i] = video.draw_text(framed, [label], corner="top-left") if label else framed
    return out
