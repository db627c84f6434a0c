"""Videos: text on frames, clips composed side by side or in sequence, MP4 and GIF files.

Frames are uint8 ndarrays of shape (T, H, W, 3) (e.g. ``render.RenderedEpisode.frames``). MP4 is
written with imageio-ffmpeg (which ships its own ffmpeg), GIF with Pillow; both play in real time.
"""

from __future__ import annotations

import functools
import math
import os
import pathlib
from collections.abc import Sequence

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from rmac_mj.errors import UserInputError

#: Video formats :func:`write_video` writes, by file suffix.
VIDEO_SUFFIXES: tuple[str, ...] = (".mp4", ".gif")

_PANEL_GAP = 4  # px of background between side-by-side panels
_BACKGROUND = (24, 24, 28)  # RGB of gaps and padding
_TEXT_COLOUR = (240, 240, 240)
_BOX_SHADE = 0.35  # brightness factor of the box behind overlay text


# --------------------------------------------------------------------------------------------------
# Text on frames, composition


@functools.lru_cache(maxsize=8)
def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow without FreeType: a fixed bitmap font
        return ImageFont.load_default()


_MEASURE = ImageDraw.Draw(Image.new("RGB", (1, 1)))


def draw_text(frame: np.ndarray, lines: Sequence[str], corner: str = "top-left") -> np.ndarray:
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
    out[y : y + box_h, x : x + box_w] = (out[y : y + box_h, x : x + box_w] * _BOX_SHADE).astype(
        np.uint8
    )
    image = Image.fromarray(out)
    ImageDraw.Draw(image).multiline_text(
        (x + margin - left, y + margin - top), text, font=font, fill=_TEXT_COLOUR, spacing=2
    )
    return np.asarray(image)


def label_frames(frames: np.ndarray, label: str) -> np.ndarray:
    """``frames`` (T, H, W, 3) with ``label`` in the top-left corner of each."""
    frames = _check_frames(frames, "frames")
    return np.stack([draw_text(frame, [label]) for frame in frames])


def _check_frames(frames, name: str) -> np.ndarray:
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[-1] != 3 or frames.dtype != np.uint8 or len(frames) == 0:
        raise ValueError(
            f"{name} must be a non-empty uint8 array of shape (T, H, W, 3), got "
            f"dtype {frames.dtype} and shape {frames.shape}"
        )
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


def _check_clips(clips: Sequence[np.ndarray], caller: str) -> list[np.ndarray]:
    """``clips`` checked as frames of one size, at least one (``caller`` names who needs them)."""
    clips = [_check_frames(clip, f"clips[{i}]") for i, clip in enumerate(clips)]
    if not clips:
        raise ValueError(f"{caller} needs at least one clip")
    if len({clip.shape[1:] for clip in clips}) != 1:
        raise ValueError(
            f"clips must share one frame size, got {[clip.shape[1:3] for clip in clips]}"
        )
    return clips


def side_by_side(
    clips: Sequence[np.ndarray], labels: Sequence[str] | None = None, gap: int = _PANEL_GAP
) -> np.ndarray:
    """Clips of one frame size played together, left to right; uint8 (T, H, W_total, 3).

    Shorter clips hold their last frame; ``labels`` (one per clip) are drawn top-left of each panel.
    """
    clips = _check_clips(clips, "side_by_side")
    labels = _check_labels(labels, len(clips))
    length = max(len(clip) for clip in clips)
    panels = [
        _pad_time(label_frames(clip, label) if label else clip, length)
        for clip, label in zip(clips, labels)
    ]
    _, height, _, _ = panels[0].shape
    spacer = np.empty((length, height, gap, 3), dtype=np.uint8)
    spacer[:] = _BACKGROUND
    parts = [panels[0]]
    for panel in panels[1:]:
        parts += [spacer, panel]
    return np.concatenate(parts, axis=2)


def sequence(
    clips: Sequence[np.ndarray], labels: Sequence[str] | None = None, hold: int = 0
) -> np.ndarray:
    """Clips of one frame size played one after another; uint8 (sum T_i + hold * n, H, W, 3).

    ``labels`` (one per clip) are drawn top-left; each clip's last frame is held ``hold`` extra frames.
    """
    clips = _check_clips(clips, "sequence")
    if not isinstance(hold, (int, np.integer)) or hold < 0:
        raise ValueError(f"hold must be an integer >= 0 (frames), got {hold!r}")
    labels = _check_labels(labels, len(clips))
    parts = [
        _pad_time(label_frames(clip, label) if label else clip, len(clip) + hold)
        for clip, label in zip(clips, labels)
    ]
    return np.concatenate(parts, axis=0)


# --------------------------------------------------------------------------------------------------
# Video files


def write_video(
    frames: np.ndarray, path: str | os.PathLike, fps: float, scale: float = 1.0, frame_step: int = 1
) -> pathlib.Path:
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
        frames = np.stack(
            [np.asarray(Image.fromarray(f).resize(size, Image.Resampling.LANCZOS)) for f in frames]
        )
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
    writer = imageio_ffmpeg.write_frames(
        str(path),
        (frames.shape[2], frames.shape[1]),
        fps=fps,
        codec="libx264",
        pix_fmt_out="yuv420p",
        macro_block_size=1,
        quality=7,
        ffmpeg_log_level="error",
    )
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
    images[0].save(
        path,
        save_all=True,
        append_images=images[1:],
        loop=0,
        optimize=True,
        disposal=1,
        duration=[int(10 * d) for d in delays],
    )  # ms, whole centiseconds


def check_video_path(out_path) -> None:
    """UserInputError unless ``out_path`` ends in one of :data:`VIDEO_SUFFIXES` (check it before
    rendering anything)."""
    if pathlib.Path(out_path).suffix.lower() not in VIDEO_SUFFIXES:
        raise UserInputError(f"out_path must end in one of {VIDEO_SUFFIXES}, got {str(out_path)!r}")
