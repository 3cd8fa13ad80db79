"""Demonstrations and rollouts as LeRobotDataset v3 folders (tsrl.agents.demo_lerobot): `tsrl demos record
--format lerobot`, the round trip record -> LeRobot -> train (the same demonstration buffer and networks as
from the .npz), the files read back with pyarrow and JSON alone against the v3 layout LeRobot documents
(the lerobot-dataset package pins numpy < 2.3 and needs torchvision, so it cannot sit beside tsrl's pins),
`tsrl evaluate --record`, and each bad dataset as one line naming the folder and what differs."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from cli_runner import run_tsrl
from training_helpers import assert_trains_as_the_npz, tiny

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import train
from tsrl.agents.config import DemoConfig
from tsrl.agents.demo_files import ARRAYS, DemoFileError, DemoSpec, demo_record, load_demos
from tsrl.agents.demo_lerobot import CODEBASE_VERSION, DATA, EPISODES, INFO, STATS, TASKS, unit
from tsrl.agents.demonstrators import record_demos
from tsrl.cli import main
from tsrl.envs.tasks import builtin_task_path

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")

REACH = "tsrl/UR5eReach-v0"
EPISODE_STEPS = 50


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> tuple[Path, Path]:
    """3 scripted reach episodes (fs1) recorded by the CLI as a .npz file and as a LeRobot dataset."""
    root = tmp_path_factory.mktemp("demos")
    npz, folder = root / "reach.npz", root / "reach-lerobot"
    common = ["demos", "record", "--env", REACH, "--obs", "fs1", "--episodes", "3"]
    assert main([*common, "--out", str(npz)]) == 0
    assert main([*common, "--out", str(folder), "--format", "lerobot"]) == 0
    return npz, folder


def reach_spec(obs: str = "fs1") -> DemoSpec:
    env = gym.make(REACH, obs=obs)
    spec = DemoSpec.of(env)
    env.close()
    return spec


def assert_same_demos(a, b) -> None:
    for name in ARRAYS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape, name
        np.testing.assert_array_equal(x, y, err_msg=name)


def table(folder: Path, name: str) -> dict[str, np.ndarray]:
    """A parquet file's columns as numpy arrays (lists stacked into (rows, width))."""
    t = pq.read_table(folder / name)
    return {c: np.array(t.column(c).to_pylist()) for c in t.column_names}


# -- the round trip --------------------------------------------------------------------------------
def test_record_as_lerobot_gives_the_same_demonstrations(recorded, capsys):
    npz, folder = recorded
    assert (folder / INFO).is_file() and not folder.with_suffix(".npz").exists()
    from_npz, from_lerobot = load_demos(npz, reach_spec()), load_demos(folder, reach_spec())
    assert from_npz.n_episodes == 3 and from_npz.is_success[:, -1].all()
    assert_same_demos(from_npz, from_lerobot)
    assert from_lerobot.meta == from_npz.meta


def test_training_on_the_lerobot_dataset_is_training_on_the_npz(recorded):
    """Same demonstration buffer contents, and then the same network after 150 env steps, bit for bit."""
    npz, folder = recorded
    assert_trains_as_the_npz(npz, folder)


def test_a_run_records_the_dataset(recorded, tmp_path):
    _, folder = recorded
    cfg = tiny(total=100, demos=DemoConfig(path=str(folder)))
    run_dir = train(cfg, tmp_path / "runs", progress_bar=False)
    record = json.loads((run_dir / "demos.json").read_text())
    assert record == demo_record(cfg) and record["episodes"] == 3 and len(record["sha256"]) == 64


# -- the files, read as LeRobot documents v3 ------------------------------------------------------
def test_the_files_follow_the_v3_layout(recorded):
    """What an external reader sees, with pyarrow and JSON alone: the same episodes, lengths, actions
    and rewards, frames in order, timestamps at the control period, the task, stats and the task file."""
    npz, folder = recorded
    d = load_demos(npz)
    n, t = d.n_episodes, EPISODE_STEPS
    info = json.loads((folder / INFO).read_text())
    assert info["codebase_version"] == CODEBASE_VERSION == "v3.0"
    assert (info["fps"], info["robot_type"], info["total_episodes"], info["total_frames"]) == (
        25,
        "ur5e",
        n,
        n * t,
    )
    assert info["splits"] == {"train": f"0:{n}"} and info["total_tasks"] == 1
    assert info["data_path"].format(chunk_index=0, file_index=0) == DATA
    # Every data column is a feature, of the declared dtype and shape.
    frames = pq.read_table(folder / DATA)
    assert set(frames.column_names) == set(info["features"])
    for name, feature in info["features"].items():
        column = frames.column(name)
        width = column.type.list_size if pa.types.is_fixed_size_list(column.type) else 1
        value_type = (
            column.type.value_type if width > 1 or pa.types.is_fixed_size_list(column.type) else column.type
        )
        assert [width] == feature["shape"] and str(value_type.to_pandas_dtype().__name__) == feature[
            "dtype"
        ], name
    f = table(folder, DATA)
    assert f["index"].tolist() == list(range(n * t))
    assert f["episode_index"].tolist() == np.repeat(np.arange(n), t).tolist()
    assert f["frame_index"].tolist() == np.tile(np.arange(t), n).tolist()
    np.testing.assert_array_equal(f["timestamp"], (f["frame_index"] * 0.04).astype(np.float32))
    assert (f["task_index"] == 0).all()
    # The episodes' table says where each episode's frames are; they hold its actions and rewards.
    e = table(folder, EPISODES)
    assert e["episode_index"].tolist() == list(range(n)) and e["length"].tolist() == [t] * n
    assert (e["data/chunk_index"] == 0).all() and (e["data/file_index"] == 0).all()
    assert e["seed"].tolist() == d.seeds.tolist()
    for i in range(n):
        rows = slice(e["dataset_from_index"][i], e["dataset_to_index"][i])
        assert (f["episode_index"][rows] == i).all()
        np.testing.assert_array_equal(f["action"][rows], d.actions[i])
        np.testing.assert_array_equal(f["next.reward"][rows], d.rewards[i])
        np.testing.assert_array_equal(f["observation.state"][rows], d.observation[i, :-1])
        np.testing.assert_array_equal(e["final.observation.state"][i], d.observation[i, -1])
        assert (
            f["next.done"][rows].tolist() == [False] * (t - 1) + [True] == f["next.truncated"][rows].tolist()
        )
        assert e["tasks"][i].tolist() == [info["tsrl"]["task"]]
    # Each task map of the observation is its own column, with its rows' names and its unit.
    structure = info["tsrl"]["observation_structure"]  # fs1: five maps, 15 rows
    assert list(structure) == [
        "position(tcp)",
        "position(target)",
        "positionDiff(tcp, target)",
        "velocity(position(tcp))",
        "velocity(positionDiff(tcp, target))",
    ]
    for name, (a, b) in structure.items():
        np.testing.assert_array_equal(f[f"observation.{name}"], f["observation.state"][:, a:b], err_msg=name)
    assert info["features"]["observation.position(tcp)"]["unit"] == "m"
    assert info["features"]["observation.velocity(position(tcp))"]["unit"] == "m/s"
    assert info["features"]["observation.state"]["names"][9] == "velocity(position(tcp))[0]"
    # tasks.parquet: the task's language string -> task_index, as pandas reads it.
    import pandas as pd

    tasks = pd.read_parquet(folder / TASKS)
    assert tasks.index.tolist() == [info["tsrl"]["task"]] and tasks["task_index"].tolist() == [0]
    assert info["tsrl"]["task"].startswith("UR5e reach")
    stats = json.loads((folder / STATS).read_text())
    np.testing.assert_allclose(stats["action"]["mean"], d.actions.reshape(-1, 3).mean(axis=0), rtol=1e-6)
    assert stats["action"]["min"] == d.actions.reshape(-1, 3).min(axis=0).tolist()
    assert stats["next.reward"]["count"] == [n * t]
    # tsrl's task file and its hash travel with the dataset.
    text = builtin_task_path("UR5eReach-v0").read_text(encoding="utf-8")
    assert info["tsrl"]["task_file_text"] == text
    assert info["tsrl"]["task_file_sha256"] == hashlib.sha256(text.encode()).hexdigest()
    assert info["tsrl"]["control_dt"] == 0.04 and info["tsrl"]["demos"] == d.meta


def test_units_of_the_task_maps():
    assert unit("position(tcp)") == "m" and unit("velocity(position(tcp))") == "m/s"
    assert unit("quaternionDiff(tcp, target)") == "1" and unit("scalarProductZZ(tcp, target)") == "1"
    assert unit("velocity(jointState)") == "(rad (hinge) or m (slide))/s"
    assert unit("previous_actions") == "1 (action units)" and unit("gripperWidth(fingers)") is None


def test_an_empty_dataset_reads_as_the_empty_npz(tmp_path):
    from tsrl.agents.config import TrainConfig
    from tsrl.agents.demo_files import save_demos
    from tsrl.agents.demo_lerobot import save_lerobot

    empty = record_demos(REACH, 0, obs="fs1", seed=0)
    from_npz = load_demos(save_demos(empty, tmp_path / "empty.npz"))
    from_lerobot = load_demos(save_lerobot(empty, tmp_path / "empty", TrainConfig(obs="fs1")), reach_spec())
    assert from_lerobot.n_episodes == 0
    assert_same_demos(from_npz, from_lerobot)


# -- rollouts of a trained policy ------------------------------------------------------------------
def test_evaluate_record_writes_the_policys_rollouts(tmp_path, capsys):
    run_dir = train(tiny(total=100), tmp_path / "runs", progress_bar=False)
    out = tmp_path / "rollouts"
    assert main(["evaluate", str(run_dir), "--episodes", "2", "--record", str(out)]) == 0
    assert "wrote " + str(out) in capsys.readouterr().out
    rollouts = load_demos(out, reach_spec())
    assert rollouts.n_episodes == 2 and rollouts.meta["demonstrator"].startswith("policy:")
    assert rollouts.meta["successful_only"] is False
    # The policy replays its own rollouts: the env from the recorded seed, the recorded actions.
    env = gym.make(REACH, obs="fs1")
    obs, _ = env.reset(seed=int(rollouts.seeds[1]))
    for step in range(EPISODE_STEPS):
        np.testing.assert_array_equal(obs["observation"], rollouts.observation[1, step])
        obs, reward, *_ = env.step(rollouts.actions[1, step])
        assert reward == rollouts.rewards[1, step]
    env.close()


def test_evaluate_record_refuses_another_task(tmp_path, capsys):
    assert main(["evaluate", str(tmp_path), "--record", str(tmp_path / "x"), "--env", REACH]) == 2
    assert "--record writes rollouts on the run's own task" in capsys.readouterr().err


# -- bad input -------------------------------------------------------------------------------------
def _info(folder: Path, edit) -> Path:
    path = folder / INFO
    info = json.loads(path.read_text())
    edit(info)
    path.write_text(json.dumps(info))
    return folder


def _frames(folder: Path, edit) -> Path:
    t = pq.read_table(folder / DATA)
    pq.write_table(edit(t), folder / DATA)
    return folder


def _set(name: str, row: int, value):
    """Sets one value (a scalar column's row, or the first entry of a list column's row)."""

    def edit(t):
        values = t.column(name).to_pylist()
        if isinstance(values[row], list):
            values[row][0] = value
        else:
            values[row] = value
        return t.set_column(t.column_names.index(name), name, pa.array(values, type=t.column(name).type))

    return edit


def _foreign(info: dict) -> None:
    del info["tsrl"]
    info["robot_type"] = "so100_follower"


@pytest.mark.parametrize(
    ("damage", "expected"),
    [
        (lambda p: _info(p, lambda i: i["tsrl"]["demos"].update(env_id="tsrl/UR5ePickPlace-v0")), "env_id 'tsrl/UR5ePickPlace-v0' (this run: 'tsrl/UR5eReach-v0')"),
        (lambda p: _info(p, lambda i: i["tsrl"]["demos"].update(obs_spec="position(tcp)")), "recorded for another environment: obs_spec 'position(tcp)'"),
        (lambda p: _info(p, _foreign), "a LeRobot dataset of robot_type 'so100_follower' not written by tsrl"),
        (lambda p: _info(p, lambda i: i.update(codebase_version="v2.1")), "LeRobot dataset version 'v2.1'; tsrl reads 'v3.0'"),
        (lambda p: _frames(p, _set("observation.state", 57, float("nan"))), "observation holds NaN or inf (episode 1)"),
        (lambda p: _frames(p, _set("action", 120, float("inf"))), "actions holds NaN or inf (episode 2)"),
        (lambda p: _frames(p, _set("next.truncated", 49, False)), "episode 0 does not end by its time limit"),
        (lambda p: _frames(p, _set("next.done", 70, True)), "episode 1 ends at frame 20 (next.done), before its end"),
        (lambda p: _frames(p, lambda t: t.drop_columns(["action"])), "no column 'action'"),
        (lambda p: _frames(p, lambda t: t.slice(0, 140)), "140 frames; 3 episodes of 50 steps are 150"),
        (lambda p: (p / DATA).write_bytes(b"PAR1 cut") or p, "unreadable parquet file"),
        (lambda p: (p / INFO).write_text("{") or p, "meta/info.json is not valid JSON"),
    ],
)  # fmt: skip
def test_a_bad_dataset_is_one_line_naming_the_folder_and_what_differs(recorded, tmp_path, damage, expected):
    folder = tmp_path / "bad"
    shutil.copytree(recorded[1], folder)
    damage(folder)
    with pytest.raises(DemoFileError) as err:
        load_demos(folder, reach_spec())
    message = str(err.value)
    assert message.startswith(f"demonstration file {folder}: ") and expected in message, message
    assert "\n" not in message


def test_another_observation_spec_is_refused(recorded):
    with pytest.raises(DemoFileError, match=r"obs_spec .*; obs_dim 15 \(this run: 9\)"):
        load_demos(recorded[1], reach_spec("fs0"))


def test_cli_train_with_another_robots_dataset_exits_2_in_one_line(recorded, tmp_path):
    folder = _info(shutil.copytree(recorded[1], tmp_path / "so100"), _foreign)
    out = tmp_path / "runs"
    result = run_tsrl(
        "train", "--out-dir", str(out), "--total-timesteps", "100", "--no-progress", "--demos", str(folder)
    )
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{folder}: a LeRobot dataset of robot_type 'so100_follower'" in lines[0], (
        lines
    )
    assert not out.exists()


def test_writing_over_a_folder_that_is_not_a_tsrl_dataset_is_refused(tmp_path, capsys):
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "notes.txt").write_text("keep me")
    args = ["demos", "record", "--env", REACH, "--episodes", "1", "--format", "lerobot", "--out", str(folder)]
    assert main(args) == 2
    assert f"{folder} exists and is not a tsrl LeRobot dataset" in capsys.readouterr().err
    assert (folder / "notes.txt").read_text() == "keep me" and len(list(tmp_path.iterdir())) == 1
