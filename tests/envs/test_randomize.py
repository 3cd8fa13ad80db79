"""A task's [randomize]: each key changes what it says and nothing else, HER stays exact with all of
them on, an empty table is today's task, and bad values are one line naming the key."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from tsrl.envs.base import TaskEnv
from tsrl.envs.tasks import Randomize, load_task
from tsrl.exceptions import InvalidConfig

PICK = "UR5ePickPlace-v0"
#: Every key at a magnitude that shows.
ALL_ON = Randomize(
    object_mass=(0.5, 2.0),
    object_size=(0.8, 1.2),
    object_friction=(0.5, 1.5),
    servo_gain=(0.5, 2.0),
    joint_damping=(0.0, 2.0),
    tcp_offset=0.01,
    observation_noise=0.005,
    action_latency=2,
    control_jitter=0.2,
    goal_offset=0.02,
)


def _env(task: str = PICK, obs: str | None = "pick_phi", **randomize) -> TaskEnv:
    base = load_task(task)
    return TaskEnv(dataclasses.replace(base, randomize=Randomize(**randomize)), obs=obs)


def _model_params(env: TaskEnv) -> dict[str, np.ndarray]:
    m = env.model
    return {
        "body_mass": m.body_mass.copy(),
        "body_inertia": m.body_inertia.copy(),
        "geom_size": m.geom_size.copy(),
        "geom_friction": m.geom_friction.copy(),
        "actuator_gainprm": m.actuator_gainprm.copy(),
        "actuator_biasprm": m.actuator_biasprm.copy(),
        "dof_damping": m.dof_damping.copy(),
        "site_pos": m.site_pos.copy(),
    }


#: key -> (its value, the model arrays it may change)
MODEL_KEYS = {
    "object_mass": ((0.5, 2.0), {"body_mass", "body_inertia"}),
    "object_size": ((0.8, 1.2), {"geom_size"}),
    "object_friction": ((0.5, 1.5), {"geom_friction"}),
    "servo_gain": ((0.5, 2.0), {"actuator_gainprm", "actuator_biasprm"}),
    "joint_damping": ((0.5, 2.0), {"dof_damping"}),  # added [N m s/rad]
    "tcp_offset": (0.01, {"site_pos"}),
}


@pytest.mark.parametrize("key", MODEL_KEYS)
def test_each_model_key_changes_its_parameters_and_nothing_else(key):
    value, changes = MODEL_KEYS[key]
    nominal = _model_params(_env())
    env = _env(**{key: value})
    for seed in range(3):
        env.reset(seed=seed)
        params = _model_params(env)
        for name, array in params.items():
            if name in changes:
                assert not np.array_equal(array, nominal[name]), (key, name)
            else:
                np.testing.assert_array_equal(array, nominal[name], err_msg=f"{key} changed {name}")
    m, box = env.model, env.model.body("box").id
    if key == "object_mass":
        assert 0.5 <= m.body_mass[box] / nominal["body_mass"][box] <= 2.0
    if key == "servo_gain":  # stiffness and damping scaled alike: kp = -biasprm[1], kv = -biasprm[2]
        ratio = m.actuator_gainprm[:6, 0] / nominal["actuator_gainprm"][:6, 0]
        np.testing.assert_allclose(m.actuator_biasprm[:6, 2] / nominal["actuator_biasprm"][:6, 2], ratio)
        assert np.all((ratio >= 0.5) & (ratio <= 2.0))
    if key == "joint_damping":
        added = m.dof_damping - nominal["dof_damping"]
        assert np.all((added[:6] >= 0.5) & (added[:6] <= 2.0)) and not added[6:].any()  # the box's dofs
    if key == "tcp_offset":
        tcp = m.site("tcp").id
        assert np.all(np.abs(m.site_pos[tcp] - nominal["site_pos"][tcp]) <= 0.01)


def test_a_bigger_box_starts_resting_on_the_table():
    env = _env(object_size=(1.2, 1.2))
    env.reset(seed=0)
    box = env.model.body("box").id
    assert env.data.xpos[box][2] == pytest.approx(0.024)  # half-height 0.02 x 1.2, on the table top z = 0


def test_observation_noise_is_in_the_rows_only_and_its_size_is_the_std():
    plain, noisy = _env(), _env(observation_noise=0.005)
    diffs = []
    for seed in range(20):
        a, _ = plain.reset(seed=seed)
        b, _ = noisy.reset(seed=seed)
        np.testing.assert_array_equal(a["achieved_goal"], b["achieved_goal"])
        np.testing.assert_array_equal(a["desired_goal"], b["desired_goal"])
        diffs.append(b["observation"] - a["observation"])
    diffs = np.concatenate(diffs)
    assert 0.004 < diffs.std() < 0.006 and abs(diffs.mean()) < 0.001


def test_action_latency_holds_the_first_actions_and_applies_them_late():
    plain = _env(obs="fs1")
    late = _env(obs="fs1", action_latency=3)
    late.reset(seed=5)
    k = len(late._perturb._latency)  # this episode's latency, drawn in 0..3
    plain.reset(seed=5)
    actions = np.random.default_rng(0).uniform(-1, 1, (8, 4))
    zeros = [plain.step(np.zeros(4))[0] for _ in range(k)]
    late_obs = [late.step(a)[0] for a in actions]
    plain_obs = zeros + [plain.step(a)[0] for a in actions[: 8 - k]]
    for x, y in zip(late_obs, plain_obs, strict=True):
        np.testing.assert_array_equal(x["observation"], y["observation"])


def test_action_latency_as_a_range_draws_within_it_and_a_pair_fixes_it():
    fixed, ranged = _env(obs="fs1", action_latency=(2, 2)), _env(obs="fs1", action_latency=(1, 3))
    drawn = set()
    for seed in range(30):
        fixed.reset(seed=seed)
        ranged.reset(seed=seed)
        assert len(fixed._perturb._latency) == 2
        drawn.add(len(ranged._perturb._latency))
    assert drawn == {1, 2, 3}


def test_control_jitter_varies_the_physics_time_per_step():
    env = _env(control_jitter=0.2)
    env.reset(seed=0)
    durations = set()
    for _ in range(20):
        t = env.data.time
        env.step(np.zeros(4))
        durations.add(round(env.data.time - t, 6))
    assert len(durations) > 1 and all(0.032 - 1e-9 <= d <= 0.048 + 1e-9 for d in durations)


def test_goal_offset_moves_what_the_policy_sees_and_info_measures_the_true_goal():
    plain, offset = _env(), _env(goal_offset=0.02)
    a, _ = plain.reset(seed=2)
    b, info = offset.reset(seed=2)
    shift = b["desired_goal"] - a["desired_goal"]
    assert 0 < np.abs(shift).max() <= 0.02
    assert info["true_distance"] == pytest.approx(np.linalg.norm(b["achieved_goal"] - a["desired_goal"]))


def test_relabelling_stays_exact_with_every_perturbation_on():
    no_objects = dataclasses.replace(ALL_ON, object_mass=(1, 1), object_size=(1, 1), object_friction=(1, 1))
    for task, obs, randomize in ((PICK, "pick_phi_plus", ALL_ON), ("UR5ePoseReach-v0", None, no_objects)):
        env = TaskEnv(dataclasses.replace(load_task(task), randomize=randomize), obs=obs)
        rng = np.random.default_rng(1)
        obs_, _ = env.reset(seed=1)
        for _ in range(6):
            obs_, *_ = env.step(rng.uniform(-1, 1, env.action_space.shape))
        for _ in range(4):
            goal = obs_["desired_goal"] + rng.normal(0, 0.05, obs_["desired_goal"].shape)
            if env.goal.pose:
                goal[3:7] /= np.linalg.norm(goal[3:7])
            relabelled = env.relabel(obs_, goal)
            moved = env.move_target(goal)
            np.testing.assert_allclose(relabelled["observation"], moved["observation"], atol=1e-12)
            np.testing.assert_array_equal(relabelled["desired_goal"], moved["desired_goal"])


def test_an_empty_randomize_table_is_the_task_bit_for_bit(tmp_path):
    source = load_task("UR5eReach-v0").source
    path = tmp_path / "reach.toml"
    path.write_text(source.read_text() + "\n[randomize]\n")
    with_table, without = TaskEnv(path), TaskEnv("UR5eReach-v0")
    assert with_table._perturb is None
    for env in (with_table, without):
        env.reset(seed=3)
        env.action_space.seed(3)
    for _ in range(20):
        a = without.action_space.sample()
        x, y = with_table.step(a)[0], without.step(a)[0]
        for key in x:
            assert x[key].tobytes() == y[key].tobytes()
    assert mujoco.mj_name2id(with_table.model, mujoco.mjtObj.mjOBJ_SITE, "tcp") >= 0


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("observation_noise = -0.01", "randomize.observation_noise = -0.01; accepted: 0 to 0.1"),
        ("action_latency = 50", "randomize.action_latency = 50; accepted: 0 to 49"),
        (
            "action_latency = [3, 1]",
            "randomize.action_latency = [3, 1]; accepted: 0 to 49 control periods, or [low, high]",
        ),
        ("servo_gain = [2.0, 0.5]", "randomize.servo_gain = [2, 0.5]; accepted: scales 0 < low <= high"),
        ("tcp_shift = 0.01", "unknown key 'tcp_shift' in [randomize]"),
    ],
)
def test_bad_randomize_values_are_one_line_naming_the_file_and_key(tmp_path, line, message):
    path = tmp_path / "bad.toml"
    path.write_text(load_task("UR5eReach-v0").source.read_text() + f"\n[randomize]\n{line}\n")
    with pytest.raises(InvalidConfig) as err:
        load_task(path)
    text = str(err.value)
    assert "\n" not in text and str(path) in text and message in text
