"""Tasks as data: task files, pose and penalty goals, exact relabelling, the built-in tasks' solvers, bad input."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import tsrl
from tsrl.envs import TASK_ENV_ID, load_task
from tsrl.envs.solvers import SOLVERS, ObstacleReachSolver, PickPlaceSolver
from tsrl.envs.tasks import builtin_task_path
from tsrl.exceptions import InvalidConfig, ModelLoadError, NotRelabelable

REACH_TOML = """
name = "MyReach"
scene = "reach"
observation = "fs1"
episode_steps = 20

[goal]
map = "position(tcp)"

[goal.position]
center = [-0.49, -0.13, 0.42]
half_extent = [0.1, 0.1, 0.05]

[success]
position = 0.03
reward = "-1/0"
"""


def _run(env, seed, steps=6):
    obs, _ = env.reset(seed=seed)
    env.action_space.seed(seed)
    for _ in range(steps):
        obs, *_ = env.step(env.action_space.sample())
    return obs


def test_a_task_file_in_a_folder_builds_an_environment(tmp_path):
    path = tmp_path / "my_reach.toml"
    path.write_text(REACH_TOML)
    env = gym.make(TASK_ENV_ID, task=str(path), max_episode_steps=20)
    check_env(env.unwrapped, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert obs["observation"].shape == (15,) and env.action_space.shape == (3,)
    truncated, steps, rewards = False, 0, set()
    while not truncated:
        obs, reward, _, truncated, _ = env.step(np.zeros(3))
        steps += 1
        rewards.add(reward)
    assert steps == 20 and rewards <= {-1.0, 0.0}
    assert np.all(np.abs(obs["desired_goal"] - [-0.49, -0.13, 0.42]) <= [0.1, 0.1, 0.05])


@pytest.mark.parametrize("env_id", ["tsrl/UR5ePoseReach-v0", "tsrl/UR5eObstacleReach-v0"])
def test_relabel_equals_moving_the_target(env_id):
    env = gym.make(env_id).unwrapped
    obs = _run(env, seed=3)
    other = _run(gym.make(env_id).unwrapped, seed=11)  # an achieved goal of another state
    new_goal = other["achieved_goal"]
    relabelled = env.relabel(obs, new_goal)
    observed = env.move_target(new_goal)
    np.testing.assert_allclose(relabelled["observation"], observed["observation"], atol=1e-12)
    np.testing.assert_allclose(relabelled["desired_goal"], observed["desired_goal"], atol=1e-12)
    np.testing.assert_array_equal(relabelled["achieved_goal"], obs["achieved_goal"])


def test_batched_pose_relabel_equals_single_relabels():
    env = gym.make("tsrl/UR5ePoseReach-v0").unwrapped
    singles = [_run(env, seed=s) for s in range(4)]
    batch = {k: np.stack([o[k] for o in singles]) for k in singles[0]}
    new_goals = np.stack([o["achieved_goal"] for o in singles[::-1]])
    batched = env.relabel(batch, new_goals)
    for i, obs in enumerate(singles):
        single = env.relabel(obs, new_goals[i])
        for key in single:
            np.testing.assert_allclose(batched[key][i], single[key], atol=1e-15)


@pytest.mark.parametrize(
    "env_id", ["tsrl/UR5ePoseReach-v0", "tsrl/UR5eObstacleReach-v0", "tsrl/UR5eReach-v0"]
)
def test_compute_reward_equals_the_step_reward_per_sample(env_id):
    env = gym.make(env_id).unwrapped
    achieved, desired, rewards = [], [], []
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        env.action_space.seed(seed)
        for _ in range(15):
            obs, reward, *_ = env.step(env.action_space.sample())
            achieved.append(obs["achieved_goal"])
            desired.append(obs["desired_goal"])
            rewards.append(reward)
    batched = env.compute_reward(np.array(achieved), np.array(desired), {})
    np.testing.assert_array_equal(batched, np.array(rewards, dtype=np.float32))
    assert batched.shape == (45,)
    for a, d, r in zip(achieved[:5], desired[:5], rewards[:5]):
        assert env.compute_reward(a, d, {}) == r


def test_pose_success_needs_both_tolerances():
    env = gym.make("tsrl/UR5ePoseReach-v0").unwrapped
    q = np.array([0.0, 0.7071067811865476, 0.7071067811865476, 0.0])
    turned = np.array([np.cos(np.radians(10)), 0, 0, np.sin(np.radians(10))])  # 20 deg about z
    goal = np.concatenate([[0.0, 0.0, 0.0], q])
    w, x, y, z = turned
    a, b, c, d = q  # turned * q
    q20 = np.array(
        [
            w * a - x * b - y * c - z * d,
            w * b + x * a + y * d - z * c,
            w * c - x * d + y * a + z * b,
            w * d + x * c - y * b + z * a,
        ]
    )
    cases = [
        (np.concatenate([[0.04, 0, 0], q]), 1.0),  # within 5 cm, same orientation
        (np.concatenate([[0.06, 0, 0], q]), 0.0),  # too far
        (np.concatenate([[0.0, 0, 0], -q]), 1.0),  # -q is the same orientation
        (np.concatenate([[0.0, 0, 0], q20]), 0.0),  # 20 deg > 15 deg
    ]
    for achieved, expected in cases:
        assert env.compute_reward(achieved, goal, {}) == expected


def test_collision_penalty_stays_exact_under_relabelling():
    env = gym.make("tsrl/UR5eObstacleReach-v0").unwrapped
    obs, _ = env.reset(seed=0)
    col = env.goal_structure["accumulatedCollisions"].start
    touching = obs["achieved_goal"].copy()
    touching[col] = 0.01  # penetrating 1 cm
    relabelled = env.relabel({**obs, "achieved_goal": touching}, touching)
    assert relabelled["desired_goal"][col] == 0.0  # the desired value of a penalty map
    # at the goal but touching: success (1) plus the penalty (-1); not touching: 1
    assert env.compute_reward(touching, relabelled["desired_goal"], {}) == 0.0
    assert (
        env.compute_reward(obs["achieved_goal"], env.relabel(obs, obs["achieved_goal"])["desired_goal"], {})
        == 1.0
    )


@pytest.mark.parametrize(  # pick-and-place: >= 95 of 100, tests/envs/test_pick_place_scripted.py
    ("env_id", "solver"),
    [(f"tsrl/{name}", solver) for name, solver in SOLVERS.items() if solver is not PickPlaceSolver],
)
def test_scripted_solvers_reach_the_sampled_goals(env_id, solver, episodes=100, at_least=99):
    env = gym.make(env_id)
    s = solver(env.unwrapped)
    successes = 0
    for seed in range(episodes):
        obs, _ = env.reset(seed=seed)
        s.reset(obs)
        truncated = False
        while not truncated:
            obs, _, _, truncated, info = env.step(s.act(obs))
        successes += info["is_success"]
    assert successes >= at_least, f"{successes}/{episodes}"


def _touching_episodes(env_id: str, seeds: range) -> tuple[int, int]:
    """Episodes whose start state has the obstacle in a contact, and episodes whose last step under the
    obstacle solver is penalised (the robot resting on the obstacle at the goal)."""
    env = gym.make(env_id)
    u = env.unwrapped
    obstacle = u.model.geom(u.task.obstacle.geom).id
    solver = ObstacleReachSolver(u)
    at_start = at_goal = 0
    for seed in seeds:
        obs, _ = env.reset(seed=seed)
        mujoco.mj_collision(u.model, u.data)
        at_start += any(obstacle in c.geom for c in u.data.contact[: u.data.ncon])
        solver.reset(obs)
        truncated = False
        while not truncated:
            obs, _, _, truncated, info = env.step(solver.act(obs))
        at_goal += info["penalty"] != 0
    return at_start, at_goal


@pytest.mark.parametrize("robot", ["UR5e", "Panda"])
def test_v1_obstacles_leave_the_robot_free_at_the_start_and_at_the_goal(robot):
    seeds = range(60)
    start_v0, goal_v0 = _touching_episodes(f"tsrl/{robot}ObstacleReach-v0", seeds)
    start_v1, goal_v1 = _touching_episodes(f"tsrl/{robot}ObstacleReach-v1", seeds)
    assert start_v1 == 0 and goal_v1 <= 1, (start_v1, goal_v1)
    assert start_v0 + goal_v0 >= 5  # v0 keeps obstacles that do not hold: the check can fail


def test_clear_at_goal_needs_a_tcp_position_goal(tmp_path):
    text = builtin_task_path("UR5eObstacleReach-v1").read_text()
    text = text.replace('map = "position(tcp)"', 'map = "position(flange)"')
    with pytest.raises(InvalidConfig, match=r"clear_at_goal needs the goal map position\(tcp\)"):
        gym.make(TASK_ENV_ID, task=_task_file(tmp_path, text))


def test_an_obstacle_that_never_fits_is_an_error_not_a_silent_violation(tmp_path):
    text = builtin_task_path("UR5eObstacleReach-v1").read_text()
    text = text.replace("clear_at_goal = true", "clear_at_goal = true\ngoal_clearance = 1.0")
    path = _task_file(tmp_path, text)
    env = gym.make(TASK_ENV_ID, task=path)
    with pytest.raises(InvalidConfig) as err:
        env.reset(seed=0)
    message = str(err.value)
    assert (
        message.startswith(f"{path}: obstacle: no goal and obstacle drawn in 100 tries")
        and "\n" not in message
    )
    assert "1.0 m of room (goal_clearance)" in message


def _task_file(tmp_path, text: str) -> str:
    path = tmp_path / "task.toml"
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (
            lambda t: t.replace('observation = "fs1"', 'observation = "fs1"\ncolour = "red"'),
            r"unknown key 'colour'",
        ),
        (
            lambda t: t.replace("episode_steps = 20", 'episode_steps = "twenty"'),
            r"episode_steps must be an integer",
        ),
        (lambda t: t.replace('reward = "-1/0"', 'reward = "1/2"'), r"success.reward = '1/2'; accepted"),
        (
            lambda t: t.replace("half_extent = [0.1, 0.1, 0.05]", "half_extent = [0.6, 0.1, 0.05]"),
            r"leaves the workspace",
        ),
        (lambda t: t.replace('map = "position(tcp)"', 'map = "velocity(position(tcp))"'), r"not a goal map"),
        (lambda t: t.replace('scene = "reach"', 'scene = "missing.xml"'), r"neither a built-in scene"),
        (lambda t: t[: t.index("[goal]")], r"missing key 'goal'$"),
        (
            lambda t: t.replace("[0.1, 0.1, 0.05]", "[0.1, 0.1]"),
            r"goal.position.half_extent must have 3 entries",
        ),
    ],
)
def test_bad_task_files_fail_with_one_line_naming_the_file_and_key(tmp_path, edit, message):
    path = _task_file(tmp_path, edit(REACH_TOML))
    with pytest.raises(InvalidConfig, match=message) as err:
        gym.make(TASK_ENV_ID, task=path)
    assert str(err.value).startswith(f"{path}: ") and "\n" not in str(err.value)


def test_unknown_maps_frames_and_unloadable_models_are_named(tmp_path):
    with pytest.raises(tsrl.TsrlError, match=r"unknown task map 'postion'"):
        gym.make(TASK_ENV_ID, task=_task_file(tmp_path, REACH_TOML.replace('"fs1"', '"postion(tcp)"')))
    with pytest.raises(tsrl.TsrlError, match=r"unknown frame 'gripper'") as err:
        gym.make(TASK_ENV_ID, task=_task_file(tmp_path, REACH_TOML.replace('"fs1"', '"position(gripper)"')))
    frames = str(err.value).split("the model's frames: ")[1].split(", ")
    assert "target" in frames and len(frames) == len(set(frames))  # `target` is a site and a body: once
    (tmp_path / "broken.xml").write_text("<mujoco><worldbody><geom type='sphere'/></worldbody>")
    with pytest.raises(ModelLoadError, match=r"broken.xml"):
        gym.make(TASK_ENV_ID, task=_task_file(tmp_path, REACH_TOML.replace('"reach"', '"broken.xml"')))


def test_conflicting_held_values_are_refused(tmp_path):
    text = REACH_TOML.replace(
        "[goal]\n",
        '[[action.parts]]\nmap = "position(tcp)"\nstep = 0.05\n'
        '[[action.hold]]\nmap = "vectorZ(tcp)"\nvalue = [0.0, 0.0, -1.0]\n'
        '[[action.hold]]\nmap = "scalarProductZZ(world, tcp)"\nvalue = [1.0]\n\n[goal]\n',
    )
    with pytest.raises(InvalidConfig, match=r"cannot hold .*conflicting"):
        gym.make(TASK_ENV_ID, task=_task_file(tmp_path, text))


def test_an_observation_that_cannot_be_relabelled_is_refused_at_construction():
    with pytest.raises(NotRelabelable, match=r"positionRel\(target, tcp\).*orientation of frame 'tcp'"):
        gym.make("tsrl/UR5eReach-v0", obs="fs1, positionRel(target, tcp)")
    env = gym.make("tsrl/UR5eReach-v0", obs="positionRel(tcp, target)").unwrapped  # accepted: exact
    obs = _run(env, seed=0)
    new_goal = obs["desired_goal"] + [0.05, -0.02, 0.03]
    np.testing.assert_allclose(
        env.relabel(obs, new_goal)["observation"], env.move_target(new_goal)["observation"], atol=1e-12
    )


def test_built_in_tasks_load_from_package_data():
    for name in ("UR5eReach-v0", "UR5ePickPlace-v0", "UR5ePoseReach-v0", "UR5eObstacleReach-v0"):
        task = load_task(name)
        assert task.name == name and task.source is not None and task.source.suffix == ".toml"


def test_a_user_task_file_trains_through_the_cli_and_resumes(tmp_path):
    from cli_runner import TINY, run_tsrl

    task = tmp_path / "my_reach.toml"
    task.write_text(REACH_TOML)
    out = tmp_path / "runs"
    args = ["train", "--task", str(task), "--obs", "fs0", "--action", "task", *TINY, "--out-dir", str(out)]
    done = run_tsrl(*args, "--total-timesteps", "300")
    assert done.returncode == 0, done.stderr
    (run_dir,) = out.iterdir()
    assert run_dir.name == "task-my_reach__fs0__task__ddpg__s0"
    config = (run_dir / "config.json").read_text()
    assert str(task) in config and '"action": "task"' in config
    resumed = run_tsrl("train", "--resume", str(run_dir), "--total-timesteps", "400", "--no-progress")
    assert resumed.returncode == 0, resumed.stderr
    assert "400 env steps" in resumed.stdout
    missing = run_tsrl("train", "--task", str(tmp_path / "nope.toml"), *TINY)
    assert missing.returncode == 2 and "nope.toml" in missing.stderr and missing.stderr.count("\n") == 1


def test_the_documented_example_task_builds_and_passes_the_checker():
    from cli_runner import REPO

    env = gym.make(TASK_ENV_ID, task=str(REPO / "examples" / "tasks" / "my_reach.toml"), max_episode_steps=50)
    check_env(env.unwrapped, skip_render_check=True)
    assert env.unwrapped.task.success.position == 0.03
