"""Camera video of LeRobot datasets (tsrl.agents.demo_lerobot, `--camera NAME`): each episode replayed
from its seed and actions on the environment it was recorded on, rendered off-screen from a camera of
the task's model before every step (frame t shows the state of observation t), and written as one MP4
per camera holding every episode in order (LeRobot v3: all episodes in one file, each located by its
from/to timestamps).

```
DIR/videos/observation.images.<camera>/chunk-000/file-000.mp4   H.264, yuv420p, fps of the dataset
```
A replay that does not reproduce the recorded observations bit for bit (demonstrations recorded on
another version of the task) is refused: its frames would show another episode.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from ..envs.keys import OBS_KEYS
from ..exceptions import InvalidConfig
from ..rendering import named_camera
from .config import TrainConfig

VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
CODEC = "h264"
#: The camera name of the task's default view: a free camera aimed at its workspace (the goal box and
#: the TCP at home, as `tsrl render` without --camera); any other name is a camera of the task's model.
WORKSPACE = "workspace"
#: Frame width and height [pixels].
SIZE = (128, 128)


def video_key(camera: str) -> str:
    """The dataset feature of a camera's frames: observation.images.<camera>."""
    return f"observation.images.{camera}"


def check_camera(recorded_with: TrainConfig, camera: str) -> None:
    """Raises UnknownName, listing the model's cameras, unless `camera` is WORKSPACE or a camera of the
    model of the task `recorded_with` makes (checked before episodes are recorded)."""
    if camera == WORKSPACE:
        return
    env = gym.make(recorded_with.gym_id, **recorded_with.env_kwargs)
    try:
        named_camera(env.unwrapped.model, camera)  # type: ignore[attr-defined]  # a TaskEnv's model
    finally:
        env.close()


def write_camera_video(
    root: Path,
    arrays: Mapping[str, np.ndarray],
    recorded_with: TrainConfig,
    camera: str,
    fps: float,
    size: tuple[int, int] = SIZE,
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Renders the N episodes of `arrays` (demo_files.ARRAYS), replayed on the environment
    `recorded_with` makes, from `camera` (WORKSPACE or a camera of the task's model; an unknown one
    raises UnknownName listing the model's cameras) at `size` (width, height) into the dataset folder
    `root`, `fps` frames per second. Returns the camera's info.json feature and its meta/episodes
    columns: videos/<key>/chunk_index, file_index, from_timestamp and to_timestamp [s]."""
    import imageio.v2 as imageio

    key = video_key(camera)
    n, t = arrays["actions"].shape[:2]
    width, height = size
    env = gym.make(
        recorded_with.gym_id,
        render_mode="rgb_array",
        width=width,
        height=height,
        camera=None if camera == WORKSPACE else camera,
        **recorded_with.env_kwargs,
    )
    out = root / VIDEO_PATH.format(video_key=key, chunk_index=0, file_index=0)
    out.parent.mkdir(parents=True, exist_ok=True)
    writer: Any = imageio.get_writer(
        out, fps=fps, codec="libx264", pixelformat="yuv420p", macro_block_size=1, quality=8
    )
    try:
        with writer:
            for i in range(n):
                obs, _ = env.reset(seed=int(arrays["seeds"][i]))
                for step in range(t):
                    _check_replay(obs, arrays, i, step)
                    writer.append_data(env.render())
                    obs = env.step(arrays["actions"][i, step])[0]
                _check_replay(obs, arrays, i, t)
    finally:
        env.close()
    feature = {
        "dtype": "video",
        "shape": [height, width, 3],
        "names": ["height", "width", "channels"],
        "info": {
            "video.height": height,
            "video.width": width,
            "video.codec": CODEC,
            "video.pix_fmt": "yuv420p",
            "video.is_depth_map": False,
            "video.fps": fps,
            "video.channels": 3,
            "has_audio": False,
        },
    }
    starts = np.arange(n, dtype=np.float64) * t / fps
    columns = {
        f"videos/{key}/chunk_index": np.zeros(n, dtype=np.int64),
        f"videos/{key}/file_index": np.zeros(n, dtype=np.int64),
        f"videos/{key}/from_timestamp": starts,
        f"videos/{key}/to_timestamp": starts + t / fps,
    }
    return feature, columns


def _check_replay(obs: Mapping[str, np.ndarray], arrays: Mapping[str, np.ndarray], i: int, step: int) -> None:
    for name in OBS_KEYS:
        if not np.array_equal(obs[name], arrays[name][i, step]):
            raise InvalidConfig(
                f"--camera: replaying episode {i} (seed {int(arrays['seeds'][i])}) does not reproduce its "
                f"{name} at step {step}; camera frames need demonstrations this environment reproduces"
            )
