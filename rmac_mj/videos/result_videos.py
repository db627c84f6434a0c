"""Videos of a result directory's snapshots: one snapshot's greedy episode, an experiment's
progression over its snapshots, learners side by side after the same trial (``rmac-mj render``).

The snapshots are found through the directory's :class:`~rmac_mj.results.store.ResultStore`,
rendered by :mod:`rmac_mj.videos.render` and written by :mod:`rmac_mj.videos.encode`; how, is one
:class:`VideoOptions` for all three.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
from collections.abc import Callable, Sequence

from rmac_mj.agents import display_name
from rmac_mj.errors import MissingInputError, UserInputError
from rmac_mj.results.snapshots import load_snapshot, snapshot_environment
from rmac_mj.results.store import ResultStore
from rmac_mj.videos import encode as video
from rmac_mj.videos.render import Camera, RenderedEpisode, render_episode


@dataclasses.dataclass(frozen=True)
class VideoOptions:
    """How the videos of a result directory's snapshots are rendered, on which environment, and
    written (``rmac-mj render``'s options).

    Attributes:
      width, height, camera, frames_per_step, overlay: the frames, as for
        :func:`~rmac_mj.videos.render.render_episode`.
      scale, frame_step: the written video, as for :func:`~rmac_mj.videos.encode.write_video`.
      env: run the episodes on this outside environment (a SPEC) instead of the snapshot's task;
        the learner's state and action must have the same dimensions there.
      trust_env: run an outside environment of the user's code that the snapshot names without
        ``env`` naming it again (:func:`~rmac_mj.results.snapshots.snapshot_environment`).
      log: hears the environment's notes.
    """

    width: int = 320
    height: int = 240
    camera: Camera = None
    frames_per_step: int = 1
    overlay: bool = True
    scale: float = 1.0
    frame_step: int = 1
    env: str | None = None
    trust_env: bool = False
    log: Callable[[str], None] | None = None

    def write(self, frames, out_path: str | os.PathLike, fps: float) -> pathlib.Path:
        """Write ``frames`` to ``out_path`` at ``fps`` (:func:`~rmac_mj.videos.encode.write_video`)."""
        return video.write_video(
            frames, out_path, fps, scale=self.scale, frame_step=self.frame_step
        )


def render_snapshot_episode(
    snapshot_path: str | os.PathLike,
    options: VideoOptions = VideoOptions(),
    label: str | None = None,
    domain: str | None = None,
    task: str | None = None,
) -> RenderedEpisode:
    """Render the greedy episode of the agent saved at ``snapshot_path``.

    The episode runs on the task the agent learned on, or on ``domain``/``task`` when given (with
    their default task_kwargs), or on the outside environment ``options.env``.
    ``label`` defaults to e.g. "RMAC, trial 600" from the snapshot's meta data.
    """
    agent, meta = load_snapshot(snapshot_path)
    env = snapshot_environment(
        agent,
        meta,
        domain,
        task,
        options.env,
        render=True,
        trust_env=options.trust_env,
        log=options.log,
    )
    if label is None:
        label = display_name(meta["algorithm"])
        if meta.get("trial") is not None:
            label += f", trial {meta['trial']}"
    return render_episode(
        env,
        agent,
        width=options.width,
        height=options.height,
        camera=options.camera,
        frames_per_step=options.frames_per_step,
        overlay=options.overlay,
        label=label,
    )


def render_snapshot(
    snapshot_path: str | os.PathLike,
    out_path: str | os.PathLike,
    options: VideoOptions = VideoOptions(),
    domain: str | None = None,
    task: str | None = None,
) -> pathlib.Path:
    """Render a snapshot's greedy episode to ``out_path`` (.mp4 or .gif) at real-time speed (on
    ``domain``/``task`` or ``options.env`` when given, see :func:`render_snapshot_episode`)."""
    video.check_video_path(out_path)
    episode = render_snapshot_episode(snapshot_path, options, domain=domain, task=task)
    return options.write(episode.frames, out_path, episode.fps)


def _pick_trials(
    available: dict[int, pathlib.Path], trials: Sequence[int], where: str
) -> list[int]:
    missing = [t for t in trials if t not in available]
    if missing:
        raise MissingInputError(
            f"no snapshot after trial(s) {missing} in {where}; available: {sorted(available)}"
        )
    return list(trials)


def render_progression(
    result_dir: str | os.PathLike,
    out_path: str | os.PathLike,
    experiment: int = 0,
    algorithm: str | None = None,
    trials: Sequence[int] | None = None,
    layout: str = "sequence",
    options: VideoOptions = VideoOptions(),
) -> pathlib.Path:
    """One experiment's greedy episode after several trials, labelled, to ``out_path``.

    Args:
      algorithm: "rmac", "s-ac", ...; None picks "rmac" when it has snapshots, else the only one.
      trials: which snapshots (trial numbers); None takes all of them (1, 10, 50, 200 and the last,
        with the runner's defaults).
      layout: "sequence" (one after another, each last frame held 0.5 s) or "side_by_side".
    """
    video.check_video_path(out_path)
    if layout not in ("sequence", "side_by_side"):
        raise UserInputError(f"layout must be 'sequence' or 'side_by_side', got {layout!r}")
    if algorithm is None:
        algorithm = _snapshot_algorithm(result_dir)
    available = ResultStore(result_dir).snapshot_trials(algorithm, experiment)
    chosen = _pick_trials(
        available,
        list(available) if trials is None else list(trials),
        f"{result_dir} ({algorithm}, experiment {experiment})",
    )
    episodes = [
        render_snapshot_episode(available[t], options, f"{display_name(algorithm)}, trial {t}")
        for t in chosen
    ]
    clips = [episode.frames for episode in episodes]
    fps = episodes[0].fps
    frames = (
        video.sequence(clips, hold=int(round(0.5 * fps)))
        if layout == "sequence"
        else video.side_by_side(clips)
    )
    return options.write(frames, out_path, fps)


def _snapshot_algorithm(result_dir: str | os.PathLike) -> str:
    """The learner whose snapshots a directory's videos show: "rmac" when it has snapshots, else
    the only one; UserInputError when several others have them."""
    algorithms = ResultStore(result_dir).snapshot_algorithms()
    if not algorithms:
        raise MissingInputError(
            f"no snapshots in {result_dir} (expected {result_dir}/snapshots/"
            "<algorithm>/exp_<iii>/trial_<tttt>.npz)"
        )
    if "rmac" not in algorithms and len(algorithms) > 1:
        raise UserInputError(
            f"several algorithms have snapshots in {result_dir} ({algorithms}); "
            "choose one with algorithm="
        )
    return "rmac" if "rmac" in algorithms else algorithms[0]


def render_comparison(
    result_dir: str | os.PathLike,
    out_path: str | os.PathLike,
    trial: int | None = None,
    experiment: int = 0,
    algorithms: Sequence[str] = ("s-ac", "rmac"),
    options: VideoOptions = VideoOptions(),
) -> pathlib.Path:
    """``algorithms`` side by side after the same ``trial`` (None: the last both have), to
    ``out_path``."""
    video.check_video_path(out_path)
    store = ResultStore(result_dir)
    available = {a: store.snapshot_trials(a, experiment) for a in algorithms}
    if trial is None:
        common = set.intersection(*(set(trials) for trials in available.values()))
        if not common:
            raise MissingInputError(
                f"{list(algorithms)} share no snapshot trial in {result_dir} "
                f"(experiment {experiment}): "
                f"{ {a: sorted(t) for a, t in available.items()} }"
            )
        trial = max(common)
    for algorithm, trials in available.items():
        _pick_trials(trials, [trial], f"{result_dir} ({algorithm}, experiment {experiment})")
    episodes = [render_snapshot_episode(available[a][trial], options) for a in algorithms]
    frames = video.side_by_side([episode.frames for episode in episodes])
    return options.write(frames, out_path, episodes[0].fps)
