"""The one typed loader (tsrl.configs): every kind of bad table is one line naming the file and the key,
for the loader itself and for each file kind (task, robot, run config.json, experiment)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import pytest

from tsrl.configs import load_file, load_table, read_toml
from tsrl.exceptions import InvalidConfig


@dataclass(frozen=True)
class Inner:
    center: tuple[float, float, float]
    count: int = 1

    def __post_init__(self) -> None:
        if self.count > 9:
            raise InvalidConfig(f"count must be <= 9; got {self.count}")


@dataclass(frozen=True)
class Outer:
    name: str
    inner: Inner
    mode: Literal["a", "b"] = "a"
    flag: bool = False
    scale: float = 1.0
    sizes: tuple[int, ...] = ()
    items: tuple[Inner, ...] = ()
    choice: Inner | str = "none"
    maybe: float | None = None
    path: Path | None = None
    origin: str = field(default="", compare=False)


GOOD = {
    "name": "x",
    "inner": {"center": [1, 2.5, 3]},
    "mode": "b",
    "flag": True,
    "scale": 2,
    "sizes": [3, 4],
    "items": [{"center": [0, 0, 0], "count": 2}],
    "choice": {"center": [1, 1, 1]},
    "maybe": None,
    "path": "models/arm.xml",
}


def test_a_good_table_builds_nested_frozen_dataclasses_with_converted_values():
    loaded = load_table(Outer, GOOD, extra={"origin": "here"})
    assert loaded == Outer(
        name="x",
        inner=Inner(center=(1.0, 2.5, 3.0)),
        mode="b",
        flag=True,
        scale=2.0,
        sizes=(3, 4),
        items=(Inner(center=(0.0, 0.0, 0.0), count=2),),
        choice=Inner(center=(1.0, 1.0, 1.0)),
        path=Path("models/arm.xml"),
    )
    assert loaded.origin == "here"
    # ints become floats where a float is declared (equal, and of the declared type)
    assert type(loaded.scale) is float and all(type(c) is float for c in loaded.inner.center)
    assert load_table(Outer, GOOD | {"choice": "other", "maybe": 0.5}).choice == "other"


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"colour": "red"}, "unknown key 'colour'; accepted: name, inner, mode, flag, scale, sizes, items"),
        ({"origin": "file"}, "unknown key 'origin'; accepted:"),  # a field given by `extra`, not the file
        ({"inner": {"center": [1, 2, 3], "cnt": 2}}, "unknown key 'cnt' in [inner]; accepted: center, count"),
        ({"inner": {"count": 2}}, "missing key 'center' in [inner]"),
        ({"inner": 3}, "inner must be a table; got 3"),
        ({"inner": {"center": [1, 2]}}, "inner.center must have 3 entries; got 2"),
        ({"inner": {"center": 1.0}}, "inner.center must be a list; got 1.0"),
        ({"inner": {"center": [1, "2", 3]}}, "inner.center[1] must be a number; got '2'"),
        ({"inner": {"center": [1, True, 3]}}, "inner.center[1] must be a number; got True"),
        ({"inner": {"center": [1, float("nan"), 3]}}, "inner.center[1] must be a finite number; got nan"),
        ({"inner": {"center": [1, 2, 3], "count": True}}, "inner.count must be an integer; got True"),
        ({"inner": {"center": [1, 2, 3], "count": 2.0}}, "inner.count must be an integer; got 2.0"),
        ({"inner": {"center": [1, 2, 3], "count": 12}}, "[inner] count must be <= 9; got 12"),
        (
            {"items": [{"center": [1, 2, 3]}, {"center": [1, 2]}]},
            "items[1].center must have 3 entries; got 2",
        ),
        ({"items": [{"center": [0, 0, 0], "count": 10}]}, "[items[0]] count must be <= 9; got 10"),
        ({"sizes": [1, False]}, "sizes[1] must be an integer; got False"),
        ({"mode": "c"}, "mode = 'c'; accepted: 'a', 'b'"),
        ({"mode": 1}, "mode = 1; accepted: 'a', 'b'"),
        ({"flag": 1}, "flag must be true or false; got 1"),
        ({"name": 5}, "name must be a string; got 5"),
        ({"scale": "big"}, "scale must be a number; got 'big'"),
        ({"choice": 3}, "choice must be a table or a string; got 3"),
        ({"choice": {"center": [1, 2, 3], "x": 1}}, "unknown key 'x' in [choice]"),
        ({"maybe": "0.5"}, "maybe must be a number; got '0.5'"),
        ({"path": 3}, "path must be a path (a string); got 3"),
        ({"name": None}, "name must be a string; got None"),
    ],
)
def test_each_kind_of_bad_value_is_one_line_naming_the_file_and_the_key(change, message):
    with pytest.raises(InvalidConfig) as err:
        load_table(Outer, GOOD | change, source="cfg/my.toml", extra={"origin": "here"})
    text = str(err.value)
    assert text.startswith(f"cfg/my.toml: {message}"), text
    assert "\n" not in text


def test_missing_keys_come_from_the_fields_not_from_the_constructor():
    with pytest.raises(InvalidConfig) as err:
        load_table(Outer, {"mode": "b"}, source="my.toml")
    assert str(err.value) == "my.toml: missing keys 'name', 'inner'"
    assert (
        str(pytest.raises(InvalidConfig, load_table, Outer, [1, 2]).value)
        == "the file must be a table; got [1, 2]"
    )


def test_a_field_of_a_type_the_loader_does_not_know_is_a_programming_error():
    @dataclass(frozen=True)
    class Mapped:
        weights: dict[str, float] = dataclasses.field(default_factory=dict)

    with pytest.raises(TypeError, match=r"cannot load weights: its type dict\[str, float\]"):
        load_table(Mapped, {"weights": {"a": 1.0}})


@dataclass(frozen=True)
class Stats:
    mean: tuple[float, ...]


@dataclass(frozen=True)
class Tables:
    stats: Mapping[str, Stats]
    notes: Any = None


def test_a_mapping_field_takes_any_keys_read_only_and_an_any_field_keeps_the_value():
    tables = load_table(Tables, {"stats": {"a": {"mean": [1, 2]}}, "notes": {"free": [1, "x"]}})
    assert tables.stats["a"] == Stats((1.0, 2.0)) and tables.notes == {"free": [1, "x"]}
    with pytest.raises(TypeError):
        tables.stats["b"] = Stats(())  # type: ignore[index]
    for table, message in (
        ({"stats": [1]}, "x.json: stats must be a table; got [1]"),
        (
            {"stats": {"a": {"mean": [float("nan")]}}},
            "x.json: stats.a.mean[0] must be a finite number; got nan",
        ),
        ({"stats": {"a": {"mean": [1], "sd": 1}}}, "x.json: unknown key 'sd' in [stats.a]; accepted: mean"),
    ):
        assert str(pytest.raises(InvalidConfig, load_table, Tables, table, source="x.json").value) == message


def test_files_are_read_as_toml_with_an_optional_section(tmp_path):
    flat = tmp_path / "flat.toml"
    flat.write_text('name = "x"\n[inner]\ncenter = [1, 2, 3]\n')
    nested = tmp_path / "nested.toml"
    nested.write_text('[outer]\nname = "x"\nmode = "z"\n[outer.inner]\ncenter = [1, 2, 3]\n')
    assert (
        load_file(Outer, flat)
        == load_file(Outer, flat, section="outer")
        == Outer("x", Inner((1.0, 2.0, 3.0)))
    )
    with pytest.raises(InvalidConfig) as err:
        load_file(Outer, nested, section="outer")
    assert str(err.value) == f"{nested}: outer.mode = 'z'; accepted: 'a', 'b'"
    (tmp_path / "broken.toml").write_text("name = [")
    with pytest.raises(InvalidConfig, match=r"broken.toml: not valid TOML: ") as err:
        read_toml(tmp_path / "broken.toml")
    assert "\n" not in str(err.value)
    with pytest.raises(InvalidConfig, match=r"nope.toml: cannot read it: No such file"):
        read_toml(tmp_path / "nope.toml")


# -- each file kind ----------------------------------------------------------------------------------
def _one_line_naming(err: pytest.ExceptionInfo[InvalidConfig], path: Path, message: str) -> None:
    text = str(err.value)
    assert text.startswith(f"{path}: {message}"), text
    assert "\n" not in text


TASK = """
name = "MyReach"
episode_steps = 20

[goal]
map = "position(tcp)"

[goal.position]
center = [-0.49, -0.13, 0.42]
half_extent = [0.1, 0.1, 0.05]

[success]
reward = "-1/0"
"""


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            "episode_steps = 20",
            'episode_steps = 20\ncolour = "red"',
            "unknown key 'colour'; accepted: name, goal",
        ),
        ("[goal.position]\n", "[goal.position]\nradius = 1\n", "unknown key 'radius' in [goal.position]"),
        ('name = "MyReach"', "", "missing key 'name'"),
        ("center = [-0.49, -0.13, 0.42]", "", "missing key 'center' in [goal.position]"),
        ("episode_steps = 20", 'episode_steps = "20"', "episode_steps must be an integer; got '20'"),
        ("episode_steps = 20", "episode_steps = true", "episode_steps must be an integer; got True"),
        ("[0.1, 0.1, 0.05]", "[0.1, 0.1]", "goal.position.half_extent must have 3 entries; got 2"),
        (
            "[0.1, 0.1, 0.05]",
            "[0.1, false, 0.05]",
            "goal.position.half_extent[1] must be a number; got False",
        ),
        ('reward = "-1/0"', 'reward = "1/2"', "success.reward = '1/2'; accepted: '0/1', '-1/0'"),
        ("episode_steps = 20", 'episode_steps = 20\nobstacle = "box"', "obstacle must be a table; got 'box'"),
        ("episode_steps = 20", "episode_steps = 20\nobjects = 3", "objects must be a list; got 3"),
        ("episode_steps = 20", "action = 3", "action must be a table or a string; got 3"),
        (
            "[success]\n",
            '[[success.penalties]]\nmap = "accumulatedCollisions"\nabove = "0"\n[success]\n',
            None,
        ),
    ],
)
def test_task_files(tmp_path, old, new, message):
    from tsrl.envs import load_task

    path = tmp_path / "my_task.toml"
    assert TASK.count(old) == 1
    path.write_text(TASK.replace(old, new))
    with pytest.raises(InvalidConfig) as err:
        load_task(path)
    _one_line_naming(err, path, message or "success.penalties[0].above must be a number; got '0'")


def test_a_task_whose_scene_file_is_missing_names_the_file_and_the_key(tmp_path):
    from tsrl.envs import load_task
    from tsrl.envs.scenes import load_scene

    path = tmp_path / "my_task.toml"
    path.write_text(TASK.replace('name = "MyReach"', 'name = "MyReach"\nscene = "models/nope.xml"'))
    with pytest.raises(InvalidConfig) as err:
        load_scene(load_task(path))
    _one_line_naming(err, path, "scene = 'models/nope.xml': neither a built-in scene (ur5e, reach,")


ROBOT = """
name = "arm"
model = "ur5e"
joints = ["shoulder_pan", "shoulder_lift"]
tcp = "tcp"
actuators = ["shoulder_pan", "shoulder_lift"]
"""


@pytest.mark.parametrize("section", [False, True])
@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ('tcp = "tcp"', 'tpc = "tcp"', "unknown key 'tpc'{in_robot}; accepted: name, model, joints, tcp, home"),
        ('tcp = "tcp"', "", "missing key 'tcp'{in_robot}"),
        ('tcp = "tcp"', "tcp = 3", "{robot}tcp must be a string; got 3"),
        ('tcp = "tcp"', 'tcp = "tcp"\nservo_bandwidth = "fast"', "{robot}servo_bandwidth must be a number; got 'fast'"),
        ('tcp = "tcp"', 'tcp = "tcp"\ngravity_compensation = 1', "{robot}gravity_compensation must be true or false"),
        ('tcp = "tcp"', 'tcp = "tcp"\nhome = true', "{robot}home must be a string or a list; got True"),
        ('tcp = "tcp"', 'tcp = "tcp"\nhome = [0.1, "up"]', "{robot}home[1] must be a number; got 'up'"),
        ('joints = ["shoulder_pan", "shoulder_lift"]', 'joints = "shoulder_pan"', "{robot}joints must be a list"),
        ('actuators = ["shoulder_pan", "shoulder_lift"]', 'actuators = ["shoulder_pan"]',
         "{table}robot 'arm': 1 actuators for 2 joints"),
    ],
)  # fmt: skip
def test_robot_files(tmp_path, section, old, new, message):
    from tsrl.robots import load_robot

    path = tmp_path / "arm.toml"
    assert ROBOT.count(old) == 1
    text = ROBOT.replace(old, new)
    path.write_text("[robot]\n" + text if section else text)
    with pytest.raises(InvalidConfig) as err:
        load_robot(path)
    where = {"in_robot": " in [robot]", "robot": "robot.", "table": "[robot] "} if section else {}
    _one_line_naming(err, path, message.format_map({"in_robot": "", "robot": "", "table": ""} | where))


def test_a_robot_file_loads_with_its_model_relative_to_it(tmp_path):
    from tsrl.robots import load_robot

    (tmp_path / "arm.toml").write_text(ROBOT.replace('"ur5e"', '"arm.xml"') + "home = [0, 1.5]\n")
    robot = load_robot(tmp_path / "arm.toml")
    assert robot.model == str(tmp_path / "arm.xml") and robot.home == (0.0, 1.5)
    assert robot.joints == ("shoulder_pan", "shoulder_lift") and robot.actuators == robot.joints


def _write_run(tmp_path: Path, config: dict) -> Path:
    import json

    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "config.json").write_text(json.dumps(config))
    return run_dir


def test_a_run_config_json_round_trips_and_one_from_before_the_newer_keys_loads_with_their_defaults(tmp_path):
    from tsrl.agents.config import AgentConfig, HerConfig, TrainConfig
    from tsrl.agents.run_folder import load_config

    cfg = TrainConfig(
        obs="fs2", seed=3, agent=AgentConfig(algo="td3", net_arch=(64, 64), her=HerConfig("plain"))
    )
    (tmp_path / "new").mkdir()
    assert load_config(_write_run(tmp_path / "new", cfg.to_dict())) == cfg
    old = TrainConfig().to_dict()
    for key in ("policy_inputs", "demos"):  # keys that later versions added
        del old["agent"][key]
    assert load_config(_write_run(tmp_path, old)) == TrainConfig()


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        (
            ("agent", "lr"),
            0.1,
            "unknown key 'lr' in [agent]; accepted: algo, learner, layer_norm, utd, net_arch",
        ),
        (("seed",), "0", "seed must be an integer; got '0'"),
        (("total_timesteps",), True, "total_timesteps must be an integer; got True"),
        (("agent", "learning_rate"), True, "agent.learning_rate must be a number; got True"),
        (("agent", "net_arch"), 256, "agent.net_arch must be a list; got 256"),
        (("agent", "net_arch"), [256, 256.0], "agent.net_arch[1] must be an integer; got 256.0"),
        (("agent", "algo"), "ppo", "agent.algo = 'ppo'; accepted: 'ddpg', 'td3', 'sac'"),
        (("agent", "her", "strategy"), "past", "agent.her.strategy = 'past'; accepted: 'future'"),
        (("agent",), 3, "agent must be a table; got 3"),
        (("agent", "her"), [], "agent.her must be a table; got []"),
        (("agent", "demos", "path"), 1, "agent.demos.path must be a string; got 1"),
        (("agent", "gamma"), 2, "[agent] gamma must be in (0, 1]; got 2.0"),
    ],
)
def test_run_config_json(tmp_path, path, value, message):
    from tsrl.agents.config import TrainConfig
    from tsrl.agents.run_folder import load_config

    config = TrainConfig().to_dict()
    table = config
    for key in path[:-1]:
        table = table[key]
    table[path[-1]] = value
    run_dir = _write_run(tmp_path, config)
    with pytest.raises(InvalidConfig) as err:
        load_config(run_dir)
    _one_line_naming(err, run_dir / "config.json", message)


EXPERIMENT = """
obs = ["fs1", "baseline"]
seeds = [0, 1]

[agent]
learning_starts = 100

[[comparisons]]
a = "fs1"
b = "baseline"
"""


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("seeds = [0, 1]", "seed = [0, 1]", "unknown key 'seed'; accepted: description, env, obs, action, algo"),
        ("learning_starts = 100", "lr = 0.1", "unknown key 'lr' in [agent]; accepted: algo, learner, layer_norm, utd, net_arch"),
        ('b = "baseline"', 'b = "baseline"\nalpha = 0.1', "unknown key 'alpha' in [comparisons[0]]"),
        ('b = "baseline"', "", "missing key 'b' in [comparisons[0]]"),
        ("[agent]", "[demos]\nseed = 1\n[agent]", "missing key 'episodes' in [demos]"),
        ("seeds = [0, 1]", 'seeds = [0, "1"]', "seeds[1] must be an integer; got '1'"),
        ("seeds = [0, 1]", "seeds = [0, true]", "seeds[1] must be an integer; got True"),
        ("learning_starts = 100", "learning_starts = false", "agent.learning_starts must be an integer; got False"),
        ("seeds = [0, 1]", "seeds = [0, 1]\ntotal_timesteps = 1.5", "total_timesteps must be an integer; got 1.5"),
        ("learning_starts = 100", "net_arch = 256", "agent.net_arch must be a list; got 256"),
        ("seeds = [0, 1]", 'seeds = [0, 1]\nalgo = ["ppo"]', "algo[0] = 'ppo'; accepted: 'ddpg', 'td3', 'sac'"),
        ("[agent]", '[agent.her]\nstrategy = "past"\n[agent]', "agent.her.strategy = 'past'; accepted:"),
        ("[agent]\nlearning_starts = 100", "agent = 3", "agent must be a table; got 3"),
        ("[agent]", "[demos]\nepisodes = 0\n[agent]", "[demos] episodes must be an integer >= 1; got 0"),
    ],
)  # fmt: skip
def test_experiment_files(tmp_path, old, new, message):
    from tsrl.experiments.config import load_experiment

    path = tmp_path / "my-experiment.toml"
    assert EXPERIMENT.count(old) == 1
    path.write_text(EXPERIMENT.replace(old, new))
    with pytest.raises(InvalidConfig) as err:
        load_experiment(path, check_envs=False)
    _one_line_naming(err, path, message)
