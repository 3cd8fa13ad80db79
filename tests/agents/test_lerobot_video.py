"""Camera video in LeRobot datasets (tsrl.agents.lerobot_video, `tsrl demos record --format lerobot
--camera NAME`): one MP4 per camera holding every episode in order, each frame the state before its
step (checked against fresh renders of the replayed states), located per episode by from/to timestamps
as LeRobot v3 reads it; an unknown camera and a replay that differs are refused in one line."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from cli_runner import run_tsrl
from training_helpers import tiny

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import train
from tsrl.agents.config import TrainConfig
from tsrl.agents.demo_files import ARRAYS, load_demos
from tsrl.agents.lerobot_video import VIDEO_PATH, WORKSPACE, video_key, write_camera_video
from tsrl.cli import main
from tsrl.envs.keys import OBS_KEYS
from tsrl.exceptions import InvalidConfig

pytest.importorskip("pyarrow")
imageio = pytest.importorskip("imageio.v2")

REACH = "tsrl/UR5eReach-v0"
SIZE = (64, 48)  # width, height
STEPS = 6  # steps per episode of the hand-made episodes (renders are the cost)


def rollouts(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """n episodes of STEPS random actions on the reach task: the arrays of a demonstration file."""
    env = gym.make(REACH, obs="fs1")
    rng = np.random.default_rng(seed)
    arrays: dict[str, list] = {name: [] for name in ARRAYS}
    for i in range(n):
        obs, _ = env.reset(seed=100 + i)
        episode = {key: [obs[key]] for key in OBS_KEYS}
        actions = rng.uniform(-1, 1, (STEPS, 3)).astype(np.float32)
        rewards, success = [], []
        for a in actions:
            obs, reward, _, _, info = env.step(a)
            for key in OBS_KEYS:
                episode[key].append(obs[key])
            rewards.append(reward)
            success.append(info["is_success"])
        for key in OBS_KEYS:
            arrays[key].append(np.array(episode[key]))
        arrays["actions"].append(actions)
        arrays["rewards"].append(np.array(rewards, dtype=np.float32))
        arrays["is_success"].append(np.array(success, dtype=bool))
        arrays["seeds"].append(100 + i)
    env.close()
    return {name: np.array(values) for name, values in arrays.items()}


def reference_frames(arrays: dict[str, np.ndarray]) -> np.ndarray:
    """(N STEPS, H, W, 3): a fresh render of the state before each step, episodes in order."""
    env = gym.make(REACH, obs="fs1", render_mode="rgb_array", width=SIZE[0], height=SIZE[1])
    frames = []
    for i, seed in enumerate(arrays["seeds"]):
        env.reset(seed=int(seed))
        for a in arrays["actions"][i]:
            frames.append(env.render())
            env.step(a)
    env.close()
    return np.array(frames, dtype=np.float64)


def test_each_frame_is_the_state_before_its_step_located_by_timestamps(tmp_path):
    arrays = rollouts(3)
    feature, columns = write_camera_video(
        tmp_path, arrays, TrainConfig(env_id=REACH, obs="fs1"), WORKSPACE, fps=25, size=SIZE
    )
    key = video_key(WORKSPACE)
    assert key == "observation.images.workspace"
    assert feature["dtype"] == "video" and feature["shape"] == [48, 64, 3]
    assert feature["names"] == ["height", "width", "channels"]
    assert feature["info"]["video.fps"] == 25 and feature["info"]["video.codec"] == "h264"
    np.testing.assert_allclose(columns[f"videos/{key}/from_timestamp"], [0, 6 / 25, 12 / 25])
    np.testing.assert_allclose(columns[f"videos/{key}/to_timestamp"], [6 / 25, 12 / 25, 18 / 25])
    assert (
        columns[f"videos/{key}/chunk_index"].tolist()
        == columns[f"videos/{key}/file_index"].tolist()
        == [0] * 3
    )
    video = tmp_path / VIDEO_PATH.format(video_key=key, chunk_index=0, file_index=0)
    with imageio.get_reader(video) as reader:
        assert reader.get_meta_data()["fps"] == 25
        frames = np.array([f for f in reader], dtype=np.float64)
    reference = reference_frames(arrays)
    assert frames.shape == reference.shape == (3 * STEPS, 48, 64, 3)
    # Each frame is its own state, up to the codec's loss, and closer to it than to the other states.
    errors = np.abs(frames[:, None] - reference[None]).mean(axis=(2, 3, 4))  # (frame, reference)
    assert errors.diagonal().max() < 4, errors.diagonal()
    assert (errors.argmin(axis=1) == np.arange(len(frames))).mean() > 0.8, errors.argmin(axis=1)
    # The first frame of an episode is its own reset (another seed: another goal marker).
    assert errors[6, 6] < errors[6, 0] and errors[12, 12] < errors[12, 6]


def test_a_replay_that_differs_is_refused(tmp_path):
    arrays = rollouts(2)
    arrays["actions"][1, 2] *= 0.5  # the recorded observations no longer follow from the actions
    with pytest.raises(
        InvalidConfig, match=r"replaying episode 1 \(seed 101\) does not reproduce its observation at step 3"
    ):
        write_camera_video(
            tmp_path, arrays, TrainConfig(env_id=REACH, obs="fs1"), WORKSPACE, fps=25, size=SIZE
        )


def test_demos_record_with_a_camera_writes_a_v3_video_dataset(tmp_path, capsys):
    folder = tmp_path / "reach"
    args = ["demos", "record", "--env", REACH, "--obs", "fs1", "--episodes", "1", "--format", "lerobot"]
    assert main([*args, "--out", str(folder), "--camera", WORKSPACE]) == 0
    info = json.loads((folder / "meta" / "info.json").read_text())
    key = video_key(WORKSPACE)
    assert info["video_path"] == VIDEO_PATH and info["features"][key]["dtype"] == "video"
    video = folder / info["video_path"].format(video_key=key, chunk_index=0, file_index=0)
    with imageio.get_reader(video) as reader:
        assert sum(1 for _ in reader) == info["total_frames"] == 50
    import pyarrow.parquet as pq

    episode = pq.read_table(folder / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pylist()[0]
    assert (episode[f"videos/{key}/from_timestamp"], episode[f"videos/{key}/to_timestamp"]) == (0.0, 2.0)
    # The dataset still reads as the demonstrations (the video is beside the frames, not in them).
    plain = tmp_path / "plain"
    assert main([*args, "--out", str(plain)]) == 0
    with_video, without = load_demos(folder), load_demos(plain)
    for name in ARRAYS:
        np.testing.assert_array_equal(getattr(with_video, name), getattr(without, name), err_msg=name)


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--format", "lerobot", "--camera", "nope"], "unknown camera 'nope'"),
        (["--format", "npz", "--camera", WORKSPACE], "--camera: video goes into a LeRobot dataset (--format lerobot); got --format npz"),
    ],
)  # fmt: skip
def test_a_bad_camera_exits_2_in_one_line(tmp_path, args, expected):
    out = tmp_path / "out"
    result = run_tsrl("demos", "record", "--env", REACH, "--episodes", "1", "--out", str(out), *args)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], lines
    assert not out.exists() and list(Path(tmp_path).iterdir()) == []


def test_evaluate_record_with_a_camera_writes_the_rollouts_video(tmp_path, capsys):
    run_dir = train(tiny(total=100), tmp_path / "runs", progress_bar=False)
    out = tmp_path / "rollouts"
    assert (
        main(["evaluate", str(run_dir), "--episodes", "1", "--record", str(out), "--camera", WORKSPACE]) == 0
    )
    assert "wrote " + str(out) in capsys.readouterr().out
    info = json.loads((out / "meta" / "info.json").read_text())
    video = out / info["video_path"].format(video_key=video_key(WORKSPACE), chunk_index=0, file_index=0)
    with imageio.get_reader(video) as reader:
        assert sum(1 for _ in reader) == info["total_frames"] == 50
    assert main(["evaluate", str(run_dir), "--camera", WORKSPACE]) == 2
    assert (
        "--camera workspace: video of the rollouts of --record; give --record DIR" in capsys.readouterr().err
    )
