"""Package data: our UR5e and Panda MJCF and the scenes built on them; `load_model` compiles them."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import mujoco

from ..exceptions import ModelLoadError, UnknownScene

#: Built-in scenes: name -> MJCF file under tsrl/assets.
SCENES: dict[str, str] = {
    "ur5e": "ur5e/ur5e.xml",
    "reach": "scenes/reach.xml",
    "pick_place": "scenes/pick_place.xml",
    "obstacle_reach": "scenes/obstacle_reach.xml",
    "panda": "panda/panda.xml",
    "panda_reach": "scenes/panda_reach.xml",
    "panda_pick_place": "scenes/panda_pick_place.xml",
    "panda_obstacle_reach": "scenes/panda_obstacle_reach.xml",
    "panda_gripper": "panda/panda_gripper.xml",
    "panda_gripper_reach": "scenes/panda_gripper_reach.xml",
    "panda_gripper_pick_place": "scenes/panda_gripper_pick_place.xml",
    "panda_gripper_stack": "scenes/panda_gripper_stack.xml",
    "panda_gripper_peg": "scenes/panda_gripper_peg.xml",
    "ur5e_gripper": "ur5e/ur5e_gripper.xml",
    "ur5e_gripper_peg": "scenes/ur5e_gripper_peg.xml",
}


def scene_path(name: str) -> Path:
    """Path of a built-in scene's MJCF file; raises UnknownScene listing the known ones."""
    if name not in SCENES:
        raise UnknownScene(name, SCENES)
    return Path(str(resources.files(__package__).joinpath(SCENES[name])))


def load_model(name: str | Path) -> mujoco.MjModel:
    """Compiles a built-in scene (a key of SCENES, e.g. `reach`, `panda_reach`) or an MJCF file by path.

    Raises:
        UnknownScene: `name` is not a built-in scene and no such .xml file exists.
        ModelLoadError: the file exists but MuJoCo cannot compile it (the message says why).
    """
    if isinstance(name, str) and name in SCENES:
        path = scene_path(name)
    else:
        path = Path(name)
        if path.suffix.lower() != ".xml" or not path.is_file():
            raise UnknownScene(str(name), SCENES)
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as err:
        reason = " ".join(str(err).split())
        raise ModelLoadError(f"could not load MJCF model {str(path)!r}: {reason}") from None
