"""docs/images/tasks.png: a montage of a few registered tasks after a seeded reset, each rendered by the
env itself (render_mode="rgb_array", tsrl.rendering's default camera), with its id under it.

    MUJOCO_GL=egl python docs/images/render_tasks.py
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
from PIL import Image, ImageDraw

import tsrl  # noqa: F401 (registers the tsrl/ ids)

TASKS = (
    "tsrl/UR5eReach-v0",
    "tsrl/UR5ePickPlace-v0",
    "tsrl/UR5eObstacleReach-v1",
    "tsrl/PandaPush-v0",
    "tsrl/PandaPickPlaceGripper-v0",
    "tsrl/PandaStack-v0",
    "tsrl/PandaPegInsert-v0",
    "tsrl/PandaPoseReach-v0",
)
WIDTH, HEIGHT, COLUMNS, LABEL = 320, 240, 4, 18  # one tile [px], tiles per row, label strip [px]


def tile(env_id: str) -> Image.Image:
    """The task after reset(seed=0), WIDTH x HEIGHT, with its id written below."""
    env = gym.make(env_id, render_mode="rgb_array", width=WIDTH, height=HEIGHT)
    env.reset(seed=0)
    frame = np.asarray(env.render())
    env.close()
    image = Image.new("RGB", (WIDTH, HEIGHT + LABEL), "white")
    image.paste(Image.fromarray(frame), (0, 0))
    ImageDraw.Draw(image).text((6, HEIGHT + 3), env_id, fill="black")
    return image


def main() -> None:
    tiles = [tile(env_id) for env_id in TASKS]
    rows = -(-len(tiles) // COLUMNS)
    montage = Image.new("RGB", (COLUMNS * WIDTH, rows * (HEIGHT + LABEL)), "white")
    for i, image in enumerate(tiles):
        montage.paste(image, ((i % COLUMNS) * WIDTH, (i // COLUMNS) * (HEIGHT + LABEL)))
    out = Path(__file__).with_name("tasks.png")
    montage.save(out, optimize=True)
    print(f"{out}: {out.stat().st_size} bytes")


if __name__ == "__main__":
    main()
