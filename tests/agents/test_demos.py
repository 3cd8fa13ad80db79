"""Demonstrations: recorded files, their checks, the demonstration buffer, the Q-filtered BC loss, and
training with them (checkpoint, kill, resume; bit-identity when no demonstration row is used)."""

from __future__ import annotations

import json
import pickle
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from cli_runner import run_tsrl
from stable_baselines3.common.vec_env import DummyVecEnv
from training_helpers import fill_with_random_episodes, scalar_steps, tiny

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import TrainConfig, make_agent, make_env, make_vec_env, resume, train
from tsrl.agents.config import AgentConfig, DemoConfig
from tsrl.agents.demo_files import (
    DEMOS_RECORD,
    DemoFileError,
    Demonstrations,
    DemoSpec,
    demo_record,
    load_demos,
    save_demos,
)
from tsrl.agents.demonstrators import demo_seeds, record_demos
from tsrl.agents.demos import DemoReplayBuffer, q_filtered_bc_loss
from tsrl.agents.run_folder import latest_checkpoint
from tsrl.cli import main
from tsrl.envs import BUILTIN_TASKS, load_task
from tsrl.envs.keys import OBS_KEYS
from tsrl.envs.solvers import SOLVERS, solver_for
from tsrl.envs.tasks import builtin_task_path
from tsrl.exceptions import InvalidConfig

REACH, PICK = "tsrl/UR5eReach-v0", "tsrl/UR5ePickPlace-v0"


@pytest.fixture(scope="module")
def reach_demos(tmp_path_factory) -> Path:
    """6 scripted reach demonstrations (fs1), saved."""
    path = tmp_path_factory.mktemp("demos") / "reach.npz"
    return save_demos(record_demos(REACH, 6, obs="fs1", seed=0), path)


@pytest.fixture(scope="module")
def pick_demos() -> Demonstrations:
    return record_demos(PICK, 3, obs="fs1", seed=0)


# -- recording and files ---------------------------------------------------------------------------
def test_recorded_pick_and_place_demos_replay_exactly_and_succeed(pick_demos, tmp_path):
    d = pick_demos
    assert d.n_episodes == 3 and d.episode_steps == 50
    assert d.observation.shape == (3, 51, 15) and d.actions.shape == (3, 50, 4)
    assert d.is_success[:, -1].all()
    assert d.meta["env_id"] == PICK and d.meta["demonstrator"] == "scripted-pick-place"
    assert set(d.seeds.tolist()) <= set(demo_seeds(0, d.meta["attempted"]))
    # The stored actions, replayed on a fresh env of the same spec, give the stored observations.
    env = gym.make(PICK, obs="fs1")
    for i in range(d.n_episodes):
        obs, _ = env.reset(seed=int(d.seeds[i]))
        for t in range(d.episode_steps):
            for key in OBS_KEYS:
                np.testing.assert_array_equal(obs[key], getattr(d, key)[i, t])
            obs, reward, *_ = env.step(d.actions[i, t])
            assert reward == d.rewards[i, t]
    # Round trip through the file.
    loaded = load_demos(save_demos(d, tmp_path / "pick.npz"), DemoSpec.of(env))
    for name in ("observation", "actions", "rewards", "is_success", "seeds"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(d, name))
    assert loaded.meta == d.meta


def test_scripted_pick_and_place_acts_in_the_papers_action_holding_the_start_orientation():
    """taskspace_orient (TCP step, scalar products x.x, y.y, z.z, suction): the scripted controller
    holds the products at their start values (the diagonal of the TCP's rotation matrix at reset,
    read from MuJoCo) and still picks and places."""
    d = record_demos(PICK, 3, obs="pick_phi", action="taskspace_orient")
    assert d.n_episodes == 3 and d.meta["attempted"] == 3 and d.actions.shape == (3, 50, 7)
    env = gym.make(PICK, obs="pick_phi", action="taskspace_orient").unwrapped
    env.reset(seed=int(d.seeds[0]))
    rotation = env.data.site("tcp").xmat.reshape(3, 3)  # columns: TCP axes in world
    np.testing.assert_allclose(d.actions[0, :, 3:6], np.tile(np.diag(rotation), (50, 1)), atol=1e-6)
    assert set(np.unique(d.actions[0, :, 6])) == {-1.0, 1.0}  # suction off, on (and off again)
    env.close()


def test_failed_episodes_are_dropped_unless_kept(tmp_path):
    """An untrained policy (a run folder) fails: nothing kept by default, everything with keep_failed."""
    run_dir = train(tiny(total=100), tmp_path, progress_bar=False)
    none = record_demos(REACH, 2, policy=run_dir, max_attempts=2)
    assert none.n_episodes == 0 and none.meta["attempted"] == 2
    assert none.observation.shape == (0, 51, 15)
    kept = record_demos(REACH, 2, policy=run_dir, keep_failed=True)
    assert kept.n_episodes == 2 and not kept.is_success[:, -1].all()
    assert kept.meta["demonstrator"].startswith("policy:")
    load_demos(save_demos(none, tmp_path / "none.npz"))  # an empty file is valid


def test_a_policy_trained_on_a_task_file_records_demos_its_runs_accept(tmp_path):
    import dataclasses

    from tsrl.envs.tasks import builtin_task_path

    task = tmp_path / "reach.toml"
    task.write_text(
        builtin_task_path("UR5eReach-v0").read_text().replace('name = "UR5eReach-v0"', 'name = "R"')
    )
    cfg = dataclasses.replace(tiny(total=100), env_id=str(task), action="task")
    run_dir = train(cfg, tmp_path / "runs", progress_bar=False)
    demos = record_demos(str(task), 2, policy=run_dir, keep_failed=True)
    assert demos.n_episodes == 2 and demos.meta["env_id"] == "tsrl/Task-v0"
    path = save_demos(demos, tmp_path / "task.npz")
    with_demos = dataclasses.replace(
        cfg, agent=dataclasses.replace(cfg.agent, demos=DemoConfig(path=str(path)))
    )
    assert demo_record(with_demos)["episodes"] == 2


def test_cli_records_a_demo_file(tmp_path):
    out = tmp_path / "reach.npz"
    result = run_tsrl("demos", "record", "--env", REACH, "--episodes", "2", "--out", str(out))
    assert result.returncode == 0, result.stderr
    assert "2 episodes" in result.stdout and load_demos(out).n_episodes == 2


@pytest.mark.parametrize("name", list(SOLVERS))
def test_demos_record_works_for_every_built_in_task_with_a_solver(name, tmp_path, capsys):
    """`tsrl demos record --env tsrl/<task>` with its defaults (the task's own observation and action,
    as gym.make builds it): two
    successful episodes of the task's solver whose stored actions, replayed, give the stored
    observations."""
    env_id, out = f"tsrl/{name}", tmp_path / f"{name}.npz"
    assert main(["demos", "record", "--env", env_id, "--episodes", "2", "--out", str(out)]) == 0
    assert capsys.readouterr().out.startswith(f"wrote {out}: 2 episodes")
    env = gym.make(env_id)
    d = load_demos(out, DemoSpec.of(env))
    assert d.n_episodes == 2 and d.is_success[:, -1].all() and d.meta["demonstrator"] == SOLVERS[name].name
    for i in range(2):
        obs, _ = env.reset(seed=int(d.seeds[i]))
        for t in range(d.episode_steps):
            for key in OBS_KEYS:
                np.testing.assert_array_equal(obs[key], getattr(d, key)[i, t])
            obs, *_ = env.step(d.actions[i, t])
    env.close()


def randomized_pick_place_file(tmp_path: Path, solver: str) -> Path:
    """tsrl/UR5eBasePickPlace-v0's file with 5 mm of observation noise and the given `solver` key."""
    source = builtin_task_path("UR5eBasePickPlace-v0").read_text()
    text = source.replace('name = "UR5eBasePickPlace-v0"', f'name = "NoisyPickPlace"\nsolver = "{solver}"')
    path = tmp_path / "noisy_pick_place.toml"
    path.write_text(text + "\n[randomize]\nobservation_noise = 0.005\n")
    return path


def test_a_task_file_naming_a_solver_is_demonstrated_by_it(tmp_path):
    """A task file with `solver = "<built-in task>"` (here a randomised copy of the base pick-and-place)
    is recorded by that task's solver, and its demonstrations succeed in the file's own world."""
    path = randomized_pick_place_file(tmp_path, "UR5eBasePickPlace-v0")
    assert solver_for(str(path)) is SOLVERS["UR5eBasePickPlace-v0"]
    d = record_demos(str(path), 2, obs="baseline")
    assert d.n_episodes == 2 and d.is_success[:, -1].all()
    assert d.meta["demonstrator"] == SOLVERS["UR5eBasePickPlace-v0"].name
    bare = tmp_path / "bare.toml"
    bare.write_text(
        builtin_task_path("UR5eBasePickPlace-v0").read_text().replace("UR5eBasePickPlace-v0", "Bare")
    )
    with pytest.raises(
        InvalidConfig, match=r"a task file needs solver = a built-in task, .*bare.toml has none"
    ):
        solver_for(str(bare))


def test_a_solver_key_that_is_not_a_built_in_task_is_one_error(tmp_path):
    path = randomized_pick_place_file(tmp_path, "PickPlace")
    with pytest.raises(
        InvalidConfig, match=r"solver = 'PickPlace'; accepted: the built-in task whose solver"
    ):
        load_task(path)


@pytest.mark.parametrize(
    ("env_id", "action", "expected"),
    [
        ("tsrl/Task-v0", "task", "no scripted solver for 'tsrl/Task-v0'; solved: tsrl/UR5eReach-v0"),
        (PICK, "joint", "pick-place solver of tsrl/UR5ePickPlace-v0 acts in action taskspace or taskspace_orient;"),
        ("tsrl/UR5ePoseReach-v0", "taskspace", "acts in action task (its task's own action); got 'taskspace'"),
    ],
)  # fmt: skip
def test_a_task_without_a_solver_for_the_action_is_one_error_naming_what_is_accepted(
    env_id, action, expected
):
    assert set(SOLVERS) <= set(BUILTIN_TASKS)
    with pytest.raises(InvalidConfig, match=re.escape(expected)):
        solver_for(env_id, action)
    if env_id != "tsrl/Task-v0":  # the recorder raises the same error
        with pytest.raises(InvalidConfig, match=re.escape(expected)):
            record_demos(env_id, 1, action=action)


def corrupt(path: Path, out: Path, **changes: object) -> Path:
    with np.load(path) as f:
        arrays = dict(f)
    for name, value in changes.items():
        if value is None:
            del arrays[name]
        elif callable(value):
            arrays[name] = value(arrays[name])
        else:
            arrays[name] = value
    np.savez(out, **arrays)
    return out


def with_nan(a: np.ndarray) -> np.ndarray:
    a = a.copy()
    a[1, 7, 0] = np.nan
    return a


def other_meta(**changes: str):
    return lambda meta: np.array(json.dumps(json.loads(str(meta)) | changes))


@pytest.mark.parametrize(
    ("make", "expected"),
    [
        (lambda p, t: t / "missing.npz", "no such file"),
        (lambda p, t: _truncated(p, t / "cut.npz"), "unreadable (truncated or corrupt?)"),
        (lambda p, t: _write(t / "text.npz", b"not a zip"), "unreadable"),
        (
            lambda p, t: corrupt(p, t / "nan.npz", observation=with_nan),
            "observation holds NaN or inf (episode 1)",
        ),
        (lambda p, t: corrupt(p, t / "nokey.npz", actions=None), "no actions"),
        (lambda p, t: corrupt(p, t / "short.npz", rewards=lambda r: r[:, :-1]), "rewards has shape"),
        (lambda p, t: corrupt(p, t / "big.npz", actions=lambda a: 2 * a + 1.5), "actions outside [-1, 1]"),
        (
            lambda p, t: corrupt(p, t / "env.npz", meta=other_meta(env_id=PICK)),
            "env_id 'tsrl/UR5ePickPlace-v0' (this run: 'tsrl/UR5eReach-v0')",
        ),
        (lambda p, t: corrupt(p, t / "obs.npz", meta=other_meta(obs_spec="position(tcp)")), "obs_spec"),
        (lambda p, t: corrupt(p, t / "fmt.npz", meta=other_meta(format="x")), "not a tsrl-demos file"),
    ],
)
def test_bad_demo_files_are_one_clear_error(reach_demos, tmp_path, make, expected):
    path = make(reach_demos, tmp_path)
    with pytest.raises(DemoFileError, match="demonstration file") as err:
        load_demos(path, DemoSpec.of(gym.make(REACH, obs="fs1")))
    assert expected in str(err.value)


def test_demos_of_another_observation_spec_are_refused(reach_demos):
    with pytest.raises(DemoFileError, match=r"obs_spec .*; obs_dim 15 \(this run: 9\)"):
        load_demos(reach_demos, DemoSpec.of(gym.make(REACH, obs="fs0")))


def _truncated(path: Path, out: Path) -> Path:
    data = path.read_bytes()
    return _write(out, data[: len(data) // 2])


def _write(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--demos", "no/such.npz"], "no such file"),
        (["--obs", "fs0", "--demos", "{reach}"], "recorded for another environment"),
    ],
)
def test_cli_train_with_a_bad_demo_file_exits_2_without_a_run_folder(reach_demos, tmp_path, args, expected):
    out = tmp_path / "runs"
    args = [a.replace("{reach}", str(reach_demos)) for a in args]
    result = run_tsrl("train", "--out-dir", str(out), "--total-timesteps", "100", "--no-progress", *args)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0] and "Traceback" not in result.stderr
    assert not out.exists()


def test_cli_records_bad_input_as_one_line(tmp_path):
    result = run_tsrl(
        "demos", "record", "--env", REACH, "--action", "joint", "--out", str(tmp_path / "x.npz")
    )
    assert result.returncode == 2 and "taskspace" in result.stderr and "Traceback" not in result.stderr


# -- the demonstration buffer ----------------------------------------------------------------------
def test_demo_rows_are_relabelled_like_env_relabel(pick_demos):
    venv = DummyVecEnv([lambda: gym.make(PICK, obs="fs1")])
    buffer = DemoReplayBuffer(
        1000, venv.observation_space, venv.action_space, venv, device="cpu", demo_share=0.5
    )
    buffer.set_demos(pick_demos)
    fill_with_random_episodes(buffer, venv, 2)
    env = venv.envs[0].unwrapped
    np.random.seed(2)
    batch = buffer.sample(256)
    n = buffer.demo_rows(256)
    assert n == 128
    demo = buffer.last_demo_batch
    assert demo is not None
    for key in batch.observations:  # the demonstration rows are the last n of the batch
        assert th.equal(batch.observations[key][-n:], demo.observations[key])
    n_real = n - int(buffer.demo_buffer.her_ratio * n)
    d = pick_demos
    flat_actions = d.actions.reshape(-1, d.actions.shape[-1])
    flat_obs = {k: getattr(d, k)[:, :-1].reshape(-1, getattr(d, k).shape[-1]) for k in ("observation",)}
    relabelled = 0
    for i in range(n):
        obs = {k: v[i].numpy() for k, v in demo.observations.items()}
        next_obs = {k: v[i].numpy() for k, v in demo.next_observations.items()}
        row = _stored_row(flat_obs["observation"], flat_actions, obs, demo.actions[i].numpy(), env)
        e, t = divmod(row, d.episode_steps)
        stored = {k: getattr(d, k)[e, t] for k in OBS_KEYS}
        stored_next = {k: getattr(d, k)[e, t + 1] for k in OBS_KEYS}
        goal = obs["desired_goal"]
        if i >= n_real:
            expected, expected_next = env.relabel(stored, goal), env.relabel(stored_next, goal)
            relabelled += not np.allclose(goal, stored["desired_goal"])
            # HER's future strategy: the new goal was achieved later in the same demonstration.
            assert any(np.array_equal(goal, g) for g in d.achieved_goal[e, t + 1 :])
        else:
            expected, expected_next = stored, stored_next
        for key, value in obs.items():
            np.testing.assert_allclose(value, expected[key], rtol=0, atol=1e-12)
            np.testing.assert_allclose(next_obs[key], expected_next[key], rtol=0, atol=1e-12)
        assert demo.rewards[i, 0].item() == env.compute_reward(next_obs["achieved_goal"], goal, {})
    assert relabelled > (n - n_real) // 2


def _stored_row(observations, actions, obs, action, env) -> int:
    """Row of the demonstration transition with this action and these goal-independent features."""
    cols = np.r_[
        env.observation_structure["position(tcp)"], env.observation_structure["velocity(position(tcp))"]
    ]
    same = np.all(observations[:, cols] == obs["observation"][cols], axis=1) & np.all(
        actions == action, axis=1
    )
    rows = np.flatnonzero(same)
    assert len(rows) >= 1
    return int(rows[0])


# -- the Q-filtered BC loss ------------------------------------------------------------------------
def test_q_filter_masks_rows_where_the_actor_is_rated_higher():
    actor = th.tensor([[0.0, 0.0], [1.0, 1.0], [0.5, -0.5], [0.2, 0.2]])
    demo = th.tensor([[1.0, 0.0], [0.0, 0.0], [0.5, 0.5], [0.2, 0.2]])
    q_demo = th.tensor([[2.0], [1.0], [3.0], [0.0]])
    q_actor = th.tensor([[1.0], [1.0], [4.0], [-1.0]])  # demo better, tie, actor better, demo better
    loss, mask = q_filtered_bc_loss(actor, demo, (q_demo, q_actor))
    assert mask.tolist() == [True, False, False, True]
    assert loss.item() == pytest.approx((1.0 + 0.0) / 4)  # mean over all 4 rows of the masked errors
    loss, mask = q_filtered_bc_loss(actor, demo)
    assert mask.all() and loss.item() == pytest.approx((1.0 + 2.0 + 1.0 + 0.0) / 4)


@pytest.mark.parametrize("algo", ["ddpg", "td3", "sac"])
def test_actor_step_follows_the_gradient_of_actor_loss_plus_weighted_bc(reach_demos, algo):
    weight = 2.5
    demos = DemoConfig(path=str(reach_demos), batch_share=0.5, bc_weight=weight, q_filter=False)
    cfg = tiny(demos=demos, algo=algo)
    model = make_agent(cfg, make_vec_env(cfg))
    model.learn(150)  # fills the buffer, a first update
    model.replay_buffer.sample(64, model._vec_normalize_env)
    demo = model.replay_buffer.last_demo_batch
    actor, critic = model.actor, model.critic
    params = [p for p in actor.parameters() if p.requires_grad]

    def pi(obs):
        return actor(obs, deterministic=True) if algo == "sac" else actor(obs)

    # Expected: grad of (actor_loss + weight * L_BC) with SB3's actor loss stand-in -mean Q1(s, pi(s)).
    obs = demo.observations
    actor.optimizer.zero_grad()
    bc, _ = q_filtered_bc_loss(pi(obs), demo.actions)
    (-critic.q1_forward(obs, pi(obs)).mean() + weight * bc).backward()
    expected = grads(params)
    # Actual: the actor loss alone backward, then the hooked optimizer step (grads captured before Adam).
    actor.optimizer.zero_grad()
    (-critic.q1_forward(obs, pi(obs)).mean()).backward()
    captured = []
    handle = actor.optimizer.register_step_pre_hook(lambda *_: captured.append(grads(params)))
    actor.optimizer.step()
    handle.remove()
    for got, want in zip(captured[0], expected, strict=True):
        th.testing.assert_close(got, want, rtol=1e-5, atol=1e-7)
    assert bc.item() > 0


def grads(params: list[th.Tensor]) -> list[th.Tensor]:
    """Copies of the gradients (zeros where a parameter got none, e.g. SAC's log_std)."""
    return [th.zeros_like(p) if p.grad is None else p.grad.clone() for p in params]


# -- training ---------------------------------------------------------------------------------------
def _parameters_after_updates(cfg: TrainConfig) -> dict[str, th.Tensor]:
    model = make_agent(cfg, make_vec_env(cfg))
    model.learn(300)
    return {k: v.clone() for k, v in model.policy.state_dict().items()}


def test_no_demonstration_rows_means_todays_agent_bit_for_bit(reach_demos, tmp_path):
    empty = save_demos(record_demos(REACH, 0, obs="fs1", seed=0), tmp_path / "empty.npz")
    today = _parameters_after_updates(tiny())
    variants = [
        DemoConfig(path=str(empty), batch_share=0.25, bc_weight=1.0),  # a file with zero demonstrations
        DemoConfig(path=str(reach_demos), batch_share=0.0, bc_weight=0.0),  # demonstrations never drawn
        DemoConfig(path=str(reach_demos), batch_share=0.25, bc_weight=0.0),  # a BC weight of 0: off
    ]
    for demos in variants:
        got = _parameters_after_updates(tiny(demos=demos))
        assert got.keys() == today.keys()
        for key in today:
            assert th.equal(got[key], today[key]), (demos, key)
    with_demos = _parameters_after_updates(tiny(demos=DemoConfig(path=str(reach_demos))))
    assert not all(th.equal(with_demos[k], today[k]) for k in today)  # the test can fail


def _buffer(run_dir: Path):
    with open(latest_checkpoint(run_dir) / "replay_buffer.pkl", "rb") as f:
        return pickle.load(f)


def test_training_with_demos_is_killed_and_resumes_with_the_demo_buffer_intact(reach_demos, tmp_path):
    demos = load_demos(reach_demos)
    cfg = tiny(total=2000, demos=DemoConfig(path=str(reach_demos)))
    run_dir = tmp_path / cfg.run_name
    assert run_dir.name.endswith("__s0__demos")
    proc = subprocess.Popen(
        [sys.executable, "-m", "tsrl.cli", "train", "--out-dir", str(tmp_path), "--demos", str(reach_demos),
         "--obs", "fs1", "--total-timesteps", "2000", "--learning-starts", "100", "--gradient-steps", "10", "--batch-size", "64",
         "--eval-freq", "100", "--eval-episodes", "2", "--checkpoint-freq", "100", "--no-progress"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    end = time.monotonic() + 90
    while latest_checkpoint(run_dir) is None or int(latest_checkpoint(run_dir).name[5:]) < 200:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < end
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.communicate()
    record = json.loads((run_dir / DEMOS_RECORD).read_text())
    assert (
        record["path"] == str(reach_demos.resolve())
        and record["episodes"] == 6
        and len(record["sha256"]) == 64
    )
    resume(run_dir, total_timesteps=500, progress_bar=False)
    buffer = _buffer(run_dir)
    assert isinstance(buffer, DemoReplayBuffer) and buffer.pos == 500
    stored = buffer.demo_buffer
    assert stored.n_stored == demos.n_transitions
    np.testing.assert_array_equal(stored.actions[:, 0], demos.actions.reshape(-1, demos.actions.shape[-1]))
    np.testing.assert_array_equal(
        stored.observations["observation"][:, 0], demos.observation[:, :-1].reshape(-1, 15)
    )
    # The resumed session trained with the BC loss: TensorBoard has train/bc_loss after the kill.
    steps = scalar_steps(run_dir, "train/bc_loss")
    assert max(steps) == 500


def test_a_changed_demo_file_stops_a_restart_from_scratch(reach_demos, tmp_path):
    copy = tmp_path / "demos.npz"
    copy.write_bytes(reach_demos.read_bytes())
    cfg = tiny(total=100, demos=DemoConfig(path=str(copy)))
    run_dir = train(cfg, tmp_path, progress_bar=False)
    shutil.rmtree(run_dir / "checkpoints")  # as if killed before the first checkpoint
    save_demos(record_demos(REACH, 1, obs="fs1", seed=5), copy)
    with pytest.raises(DemoFileError, match="changed since the run started"):
        resume(run_dir, progress_bar=False)


@pytest.mark.parametrize("name", ["PandaStack-v0", "UR5eReach-v0"])
def test_defaults_are_the_tasks_own_so_recorded_demos_fit_a_default_run(name, tmp_path):
    """`tsrl demos record --env ID` and `tsrl train --env ID` given no --obs/--action both take the task's
    own observation and action (as gym.make(ID) builds it): the file's layout is the run's."""
    env_id, out = f"tsrl/{name}", tmp_path / "demos.npz"
    task = load_task(name)
    cfg = TrainConfig(env_id=env_id)
    assert cfg.obs == task.observation
    assert cfg.action == (task.action if isinstance(task.action, str) else "task")
    assert main(["demos", "record", "--env", env_id, "--episodes", "1", "--out", str(out)]) == 0
    with_demos = TrainConfig(env_id=env_id, agent=AgentConfig(demos=DemoConfig(path=str(out))))
    assert demo_record(with_demos)["episodes"] == 1  # load_demos checks the layout against the run's env
    assert DemoSpec.of(gym.make(env_id)) == DemoSpec.of(make_env(with_demos))
