"""Videos: greedy episodes rendered off-screen (:func:`render_episode`, frames with an overlay),
encoded as MP4 or GIF (:func:`write_video`, clips side by side or in sequence), and the videos of a
result directory's snapshots (``rmac-mj render``).
"""

from rmac_mj.videos.encode import (
    VIDEO_SUFFIXES,
    check_video_path,
    draw_text,
    label_frames,
    sequence,
    side_by_side,
    write_video,
)
from rmac_mj.videos.render import (
    Camera,
    RenderedEpisode,
    draw_overlay,
    free_camera,
    measure_fps,
    model_picture,
    render_episode,
    render_state,
)
from rmac_mj.videos.result_videos import (
    VideoOptions,
    render_comparison,
    render_progression,
    render_snapshot,
    render_snapshot_episode,
)

__all__ = [
    # Rendering episodes and models
    "Camera",
    "RenderedEpisode",
    "draw_overlay",
    "free_camera",
    "measure_fps",
    "model_picture",
    "render_episode",
    "render_state",
    # Encoding
    "VIDEO_SUFFIXES",
    "check_video_path",
    "draw_text",
    "label_frames",
    "sequence",
    "side_by_side",
    "write_video",
    # Videos of a result directory's snapshots
    "VideoOptions",
    "render_comparison",
    "render_progression",
    "render_snapshot",
    "render_snapshot_episode",
]
