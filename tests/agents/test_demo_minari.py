"""Demonstrations as Minari datasets (tsrl.agents.demo_minari): `tsrl demos record --format minari|both`,
the round trip record -> Minari -> train (the same arrays and demonstration buffer as from the .npz),
Minari's own tools reading what tsrl writes and tsrl reading what Minari's writes, and each bad dataset
as one line naming the folder and what differs."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from cli_runner import run_tsrl
from training_helpers import assert_trains_as_the_npz, tiny

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import resume, train
from tsrl.agents.config import DemoConfig
from tsrl.agents.demo_files import ARRAYS, DemoFileError, DemoSpec, demo_record, load_demos, save_demos
from tsrl.agents.demo_minari import minari_path
from tsrl.agents.demonstrators import record_demos
from tsrl.cli import main
from tsrl.envs.keys import OBS_KEYS
from tsrl.exceptions import InvalidConfig

minari = pytest.importorskip("minari")
h5py = pytest.importorskip("h5py")

REACH = "tsrl/UR5eReach-v0"
DATASET_ID = "tsrl/UR5eReach/reach-v0"  # reach.minari's dataset


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> tuple[Path, Path]:
    """3 scripted reach episodes (fs1) recorded by the CLI as both formats: (reach.npz, reach.minari)."""
    out = tmp_path_factory.mktemp("demos") / "reach.npz"
    args = [
        "demos",
        "record",
        "--env",
        REACH,
        "--obs",
        "fs1",
        "--episodes",
        "3",
        "--out",
        str(out),
        "--format",
        "both",
    ]
    assert main(args) == 0
    return out, minari_path(out)


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


# -- the round trip --------------------------------------------------------------------------------
def test_record_as_both_formats_gives_the_same_demonstrations(recorded, capsys):
    npz, folder = recorded
    assert npz.is_file() and folder.is_dir() and folder.name == "reach.minari"
    from_npz, from_minari = load_demos(npz, reach_spec()), load_demos(folder, reach_spec())
    assert from_npz.n_episodes == 3 and from_npz.is_success[:, -1].all()
    assert_same_demos(from_npz, from_minari)
    assert from_minari.meta == from_npz.meta
    # The default format writes the .npz alone, as before.
    out = npz.with_name("only.npz")
    assert (
        main(["demos", "record", "--env", REACH, "--obs", "fs1", "--episodes", "1", "--out", str(out)]) == 0
    )
    assert out.is_file() and not minari_path(out).exists()
    assert capsys.readouterr().out.count("wrote ") == 1


def test_minaris_own_api_reads_the_dataset(recorded, monkeypatch):
    npz, folder = recorded
    d = load_demos(npz)
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(folder))
    assert DATASET_ID in minari.list_local_datasets()
    dataset = minari.load_dataset(DATASET_ID)
    assert dataset.total_episodes == 3 and dataset.total_steps == 3 * 50
    seeds = [m["seed"] for m in dataset.storage.get_episode_metadata(range(3))]
    assert seeds == d.seeds.tolist()
    for i, episode in enumerate(dataset.iterate_episodes()):
        for key in OBS_KEYS:
            np.testing.assert_array_equal(episode.observations[key], getattr(d, key)[i])
        np.testing.assert_array_equal(episode.actions, d.actions[i])
        np.testing.assert_array_equal(episode.rewards, d.rewards[i])
        assert not episode.terminations.any() and episode.truncations.tolist() == [False] * 49 + [True]
    # The dataset's EnvSpec remakes the recording environment, which replays the first episode.
    env = dataset.recover_environment()
    assert DemoSpec.of(env) == reach_spec()
    obs, _ = env.reset(seed=seeds[0])
    for t in range(50):
        np.testing.assert_array_equal(obs["observation"], d.observation[0, t])
        obs, *_ = env.step(d.actions[0, t])
    env.close()


def test_training_on_the_minari_dataset_is_training_on_the_npz(recorded):
    """Same demonstration buffer contents, and then the same network after 150 env steps, bit for bit."""
    npz, folder = recorded
    assert_trains_as_the_npz(npz, folder)


def test_a_run_records_the_dataset_and_notices_it_changed(recorded, tmp_path):
    _, folder = recorded
    copy = tmp_path / "reach.minari"
    shutil.copytree(folder, copy)
    cfg = tiny(total=100, demos=DemoConfig(path=str(copy)))
    run_dir = train(cfg, tmp_path / "runs", progress_bar=False)
    record = json.loads((run_dir / "demos.json").read_text())
    assert record == demo_record(cfg) and record["episodes"] == 3 and len(record["sha256"]) == 64
    shutil.rmtree(run_dir / "checkpoints")  # as if killed before the first checkpoint
    save_demos(record_demos(REACH, 1, obs="fs1", seed=5), copy)  # a tsrl dataset is replaced
    assert load_demos(copy).n_episodes == 1
    with pytest.raises(DemoFileError, match="changed since the run started"):
        resume(run_dir, progress_bar=False)


def test_an_empty_dataset_reads_as_the_empty_npz(tmp_path):
    empty = record_demos(REACH, 0, obs="fs1", seed=0)
    from_npz = load_demos(save_demos(empty, tmp_path / "empty.npz"))
    from_minari = load_demos(save_demos(empty, tmp_path / "empty.minari"), reach_spec())
    assert from_minari.n_episodes == 0
    assert_same_demos(from_npz, from_minari)


def test_a_dataset_written_by_minaris_own_tools_is_read(recorded, tmp_path, monkeypatch):
    """Episodes collected without tsrl's recorder (the simulator replaying the recorded seeds and actions,
    infos with the reset's first, as Minari's DataCollector records them) read as the recorded demos."""
    d = load_demos(recorded[0])
    env = gym.make(REACH, obs="fs1")
    buffers = []
    for i in range(d.n_episodes):
        obs, info = env.reset(seed=int(d.seeds[i]))
        observations, success, rewards, truncations = [obs], [info["is_success"]], [], []
        for action in d.actions[i]:
            obs, reward, terminated, truncated, info = env.step(action)
            assert not terminated
            observations.append(obs)
            success.append(info["is_success"])
            rewards.append(reward)
            truncations.append(truncated)
        buffers.append(
            minari.data_collector.EpisodeBuffer(
                seed=int(d.seeds[i]),
                observations={k: np.array([o[k] for o in observations]) for k in OBS_KEYS},
                actions=d.actions[i],
                rewards=np.array(rewards),  # float64, as the env returns them
                terminations=np.zeros(len(rewards), dtype=bool),
                truncations=np.array(truncations),
                infos={"is_success": np.array(success)},
            )
        )
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    with pytest.warns(UserWarning):  # Minari's warnings about the fields left empty
        minari.create_dataset_from_buffers("elsewhere/reach-v0", buffers, env=env, algorithm_name="replay")
    env.close()
    loaded = load_demos(tmp_path / "elsewhere" / "reach-v0", reach_spec())
    assert_same_demos(loaded, d)
    assert loaded.meta["demonstrator"] == "minari:elsewhere/reach-v0"
    assert loaded.meta["obs_spec"] == d.meta["obs_spec"] and loaded.meta["kept"] == 3


# -- bad input -------------------------------------------------------------------------------------
def _episode(root: Path, i: int):
    """(h5py file, group) of episode i of the one dataset under `root`, open for writing."""
    (data,) = root.rglob("main_data.hdf5")
    f = h5py.File(data, "r+")
    return f, f[f"episode_{i}"]


def _edit(root: Path, i: int, edit) -> Path:
    f, group = _episode(root, i)
    with f:
        edit(group)
    return root


def _set(name: str, index: tuple, value):
    def edit(group):
        dataset = group[name]
        data = dataset[()]
        data[index] = value
        dataset[...] = data

    return edit


def _meta(root: Path, **changes) -> Path:
    (path,) = root.rglob("data/metadata.json")
    metadata = json.loads(path.read_text())
    metadata["tsrl"] |= changes
    path.write_text(json.dumps(metadata))
    return root


def _cut(root: Path) -> Path:
    (data,) = root.rglob("main_data.hdf5")
    data.write_bytes(data.read_bytes()[:1000])
    return root


@pytest.mark.parametrize(
    ("damage", "expected"),
    [
        (lambda p: _meta(p, env_id="tsrl/UR5ePickPlace-v0"), "env_spec has env_id 'tsrl/UR5eReach-v0' but its tsrl metadata 'tsrl/UR5ePickPlace-v0'"),
        (lambda p: _meta(p, obs="fs0"), "env_spec has obs 'fs1' but its tsrl metadata 'fs0'"),
        (lambda p: _meta(p, obs_spec="position(tcp)"), "recorded for another environment: obs_spec 'position(tcp)'"),
        (lambda p: _edit(p, 1, _set("observations/observation", (7, 0), np.nan)), "observation holds NaN or inf (episode 1)"),
        (lambda p: _edit(p, 2, _set("actions", (3, 1), np.inf)), "actions holds NaN or inf (episode 2)"),
        (lambda p: _edit(p, 0, _set("truncations", (49,), False)), "episode 0 does not end by its time limit (truncations[49] is False)"),
        (lambda p: _edit(p, 1, _set("truncations", (20,), True)), "episode 1 is truncated at step 20, before its end"),
        (lambda p: _edit(p, 2, _set("terminations", (10,), True)), "episode 2 terminates at step 10"),
        (lambda p: _edit(p, 1, lambda g: g.attrs.__delitem__("seed")), "episode 1 has no seed"),
        (lambda p: _edit(p, 0, lambda g: g["infos"].__delitem__("is_success")), "episode 0's infos['is_success'] has none"),
        (lambda p: _cut(p), "unreadable Minari dataset"),
        (lambda p: shutil.rmtree(p / "tsrl") or p, "holds no Minari dataset (no data/metadata.json)"),
    ],
)  # fmt: skip
def test_a_bad_dataset_is_one_line_naming_the_folder_and_what_differs(recorded, tmp_path, damage, expected):
    folder = tmp_path / "bad.minari"
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


def test_cli_train_with_a_bad_dataset_exits_2_in_one_line(recorded, tmp_path):
    folder = tmp_path / "nan.minari"
    shutil.copytree(recorded[1], folder)
    _edit(folder, 0, _set("observations/desired_goal", (3, 2), np.nan))
    out = tmp_path / "runs"
    result = run_tsrl(
        "train", "--out-dir", str(out), "--total-timesteps", "100", "--no-progress", "--demos", str(folder)
    )
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{folder}: desired_goal holds NaN or inf (episode 0)" in lines[0], lines
    assert not out.exists()


def test_writing_over_a_folder_that_is_not_a_tsrl_dataset_is_refused(tmp_path):
    folder = tmp_path / "mine.minari"
    folder.mkdir()
    (folder / "notes.txt").write_text("keep me")
    with pytest.raises(InvalidConfig, match="exists and is not a tsrl Minari dataset"):
        save_demos(record_demos(REACH, 1, obs="fs1", seed=0), folder)
    assert (folder / "notes.txt").read_text() == "keep me" and len(list(tmp_path.iterdir())) == 1
