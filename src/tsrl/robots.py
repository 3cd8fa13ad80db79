"""Robot descriptions: the names a task needs from an arm's model (controlled joints, TCP site, home
keyframe, position servos, suction), for a built-in arm or any MJCF or URDF file.

Kinematics, task maps and IK never read a `Robot`: they take the controlled joints as an argument
(`robot.joints`). This module is the one place that maps the built-in robot names to their assets.

From Python::

    robot = Robot(name="arm3", model="arm3.xml", joints=("j1", "j2", "j3"), tcp="tool")
    model = robot.load_model()  # compiles the file and checks every name against it

or from a few lines of TOML (`load_robot("arm3.toml")`; paths are relative to the TOML file)::

    name = "arm3"
    model = "arm3.xml"                  # MJCF (.xml) or URDF (.urdf)
    joints = ["j1", "j2", "j3"]
    tcp = "tool"                        # a site (or a body)
    home = "home"                       # optional keyframe
    actuators = ["a1", "a2", "a3"]      # optional position servos, one per joint
    reach_low = [0.2, -0.3, 0.05]       # optional: the box the `taskspace` presets keep the TCP in
    reach_high = [0.6, 0.3, 0.5]
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from .assets import SCENES, load_model, panda, ur5e
from .configs import load_file
from .exceptions import InvalidConfig, ModelLoadError, UnknownName
from .kinematics import arm_qpos_indices, as_slice, controlled_joints, joint_limits, name_to_id
from .model_files import is_package_path
from .taskmaps import resolve_frame

_TRN_JOINT = int(mujoco.mjtTrn.mjTRN_JOINT)


class UnknownRobot(UnknownName):
    """A robot that is neither a built-in name nor an existing .toml file."""

    def __init__(self, name: str, known: Iterable[str]):
        KeyError.__init__(
            self,
            f"unknown robot {name!r}; built-in robots: {', '.join(sorted(known))} (or a robot's .toml file)",
        )


_BIAS_AFFINE = int(mujoco.mjtBias.mjBIAS_AFFINE)
#: The keyframe a model gets where the robot's home is given as joint values (tsrl.robot_model).
HOME_KEY = "tsrl:home"


@dataclass(frozen=True)
class Robot:
    """The names of an arm in its model; `validate(model)` checks them (errors list what the model has)."""

    name: str
    """What the robot is called (a built-in name, or any label)."""
    model: str
    """A built-in scene (`tsrl.assets.SCENES`) or the path of an MJCF (.xml) or URDF (.urdf) file."""
    joints: tuple[str, ...]
    """Controlled hinge or slide joints, base to tip: the order of q, of jointState and of the IK."""
    tcp: str
    """Frame of the tool centre point: a site, else a body (a URDF file has bodies only)."""
    home: str | tuple[float, ...] | None = None
    """Home (rest) configuration: a keyframe's name, or the joints' values [rad or m] in `joints` order
    (for a model without a keyframe); None: the model's default pose (qpos0)."""
    actuators: tuple[str, ...] = ()
    """Position servos, one per joint in `joints` order (empty: the model's own servos on the joints if
    it has them, else tsrl adds them: tsrl.servos)."""
    suction: str | None = None
    """Suction (adhesion) actuator, if the arm has a suction cup."""
    servo_bandwidth: float | None = None
    """Bandwidth [Hz] at which the servos tsrl adds are critically damped (None: tsrl.servos'
    default); only for a model without servos on the joints."""
    gravity_compensation: bool | None = None
    """Gravity compensation of the arm's bodies (through the joints' actuators); None: on where tsrl
    adds the servos, the model as written where it has its own."""
    drop_equalities: tuple[str, ...] = ()
    """Equality constraints removed from the model (each by its name, or by a body or joint it
    connects); one left acting on the controlled joints is an error (it pins the arm)."""
    base: str | None = None
    """The robot's base body (`base` in task maps); None: the body the first joint's body hangs from
    (tsrl.robot_model.arm_base)."""
    gripper: str | None = None
    """Gripper servo, if the arm has a parallel-jaw gripper: a position actuator whose control is the
    target opening width [m] (in `panda_gripper` and `ur5e_gripper`, a fixed tendon over the two coupled finger joints,
    force-limited to the rated grasp force); `gripperWidth(<gripper>)` reads the width."""
    reach_low: tuple[float, ...] = ()
    """Lower corner [m, world] of the box the `taskspace` action presets keep the TCP's position target
    in (with `reach_high`); empty: `tsrl robot check`'s default reach box, +-0.15 m around the TCP at
    home (tsrl.taskspace_box)."""
    reach_high: tuple[float, ...] = ()
    """Upper corner [m, world] of that box."""

    def __post_init__(self) -> None:
        if self.actuators and len(self.actuators) != len(self.joints):
            raise InvalidConfig(
                f"robot {self.name!r}: {len(self.actuators)} actuators for {len(self.joints)} joints; "
                "give one position actuator per joint, in the joints' order, or none"
            )
        low, high = self.reach_low, self.reach_high
        if (low or high) and not (
            len(low) == len(high) == 3
            and all(math.isfinite(v) for v in (*low, *high))
            and all(a < b for a, b in zip(low, high))
        ):
            raise InvalidConfig(
                f"robot {self.name!r}: reach_low {list(low)}, reach_high {list(high)}; accepted: both or "
                "neither, 3 finite values each [m], low < high on every axis"
            )

    @classmethod
    def from_model(
        cls,
        model: mujoco.MjModel,
        *,
        tcp: str,
        joints: Sequence[str] | None = None,
        home: str | None = None,
        actuators: Sequence[str] | None = None,
        suction: str | None = None,
        name: str = "robot",
        source: str = "",
    ) -> Robot:
        """A validated description of the arm in `model`.

        `joints` None takes every hinge and slide joint of the model; `actuators` None takes the
        position servos that drive those joints, one each, if the model has them (else none).
        `source` is the model's scene name or file path (`Robot.model`).
        """
        joints = controlled_joints(model, joints)
        if actuators is None:
            actuators = _servos_of(model, joints)
        robot = cls(name, source, tuple(joints), tcp, home, tuple(actuators), suction)
        return robot.validate(model)

    def load_model(self) -> mujoco.MjModel:
        """Compiles `model` (built-in scene, MJCF or URDF file) and validates the names against it."""
        if self.model in SCENES or Path(self.model).suffix.lower() != ".urdf":
            model = load_model(self.model)
        else:
            path = Path(self.model)
            if not path.is_file():
                raise ModelLoadError(f"robot {self.name!r}: no URDF file {self.model!r}")
            try:
                model = mujoco.MjModel.from_xml_path(str(path))
            except ValueError as err:
                reason = " ".join(str(err).split())
                raise ModelLoadError(f"could not load URDF model {self.model!r}: {reason}") from None
        self.validate(model)
        return model

    def validate(self, model: mujoco.MjModel) -> Robot:
        """Checks every name against `model`; returns self.

        Raises:
            UnknownName: a joint, TCP frame, keyframe or actuator the model lacks (the message lists
                the model's names of that kind: sites and bodies for the TCP).
            InvalidConfig: a joint that is not a hinge or slide joint, or an actuator that is not a
                position servo of its joint.
        """
        controlled_joints(model, self.joints)
        resolve_frame(model, self.tcp)
        if isinstance(self.home, str):
            name_to_id(model, "key", self.home)
        elif self.home is not None and len(self.home) != len(self.joints):
            raise InvalidConfig(
                f"robot {self.name!r}: home has {len(self.home)} values for {len(self.joints)} joints; "
                "give a keyframe's name or one value per joint"
            )
        for actuator, joint in zip(self.actuators, self.joints):
            a = name_to_id(model, "actuator", actuator)
            j = name_to_id(model, "joint", joint)
            if int(model.actuator_trntype[a]) != _TRN_JOINT or int(model.actuator_trnid[a, 0]) != j:
                raise InvalidConfig(f"actuator {actuator!r} does not drive joint {joint!r}")
            if not _is_servo(model, a):
                raise InvalidConfig(f"actuator {actuator!r} is not a position servo (MJCF <position>)")
        if self.suction is not None:
            name_to_id(model, "actuator", self.suction)
        return self

    def home_q(self, model: mujoco.MjModel) -> np.ndarray:
        """Positions (n,) of the joints at home: its values, its keyframe's, or the model's qpos0."""
        if self.home is not None and not isinstance(self.home, str):
            return np.array(self.home, dtype=np.float64)
        qpos = model.qpos0 if self.home is None else model.key_qpos[name_to_id(model, "key", self.home)]
        return qpos[arm_qpos_indices(model, self.joints)].copy()

    def bind(self, model: mujoco.MjModel) -> BoundRobot:
        """The robot's indices in `model` (validated), as the environment and its samplers use them.

        Raises:
            InvalidConfig: the robot has no position servos.
        """
        self.validate(model)
        actuators = self.actuators or _servos_of(model, self.joints)  # or those tsrl added (tsrl.servos)
        if not actuators:
            raise InvalidConfig(f"robot {self.name!r} has no position servos (actuators); a task needs them")
        home_q = self.home_q(model)
        home = self.home if isinstance(self.home, str) else HOME_KEY  # joint values: tsrl's keyframe
        return BoundRobot(
            robot=self,
            qpos=as_slice(arm_qpos_indices(model, self.joints)),
            ctrl=as_slice([name_to_id(model, "actuator", n) for n in actuators]),
            joint_range=joint_limits(model, self.joints),
            home_key=name_to_id(model, "key", home) if self.home is not None else None,
            suction_ctrl=name_to_id(model, "actuator", self.suction) if self.suction is not None else None,
            gripper_ctrl=name_to_id(model, "actuator", self.gripper) if self.gripper is not None else None,
            # A redundant arm (more than six joints) keeps its elbow near home through the IK's
            # null-space posture term.
            posture=tuple(float(q) for q in home_q) if len(self.joints) > 6 else None,
        )


@dataclass(frozen=True, eq=False)
class BoundRobot:
    """A robot's indices in one model (`Robot.bind`).

    Attributes:
        robot: the description; qpos, ctrl: the arm joints' qpos and servos' ctrl indices (slices
        where contiguous); joint_range: (n, 2) joint limits [rad or m]; home_key: the home keyframe's
        id, or None (the model's default state); suction_ctrl, gripper_ctrl: the suction actuator's
        and the gripper servo's ctrl index, or None; posture: the IK's null-space posture (home) on a
        redundant arm, else None.
    """

    robot: Robot
    qpos: slice | np.ndarray
    ctrl: slice | np.ndarray
    joint_range: np.ndarray
    home_key: int | None
    suction_ctrl: int | None
    gripper_ctrl: int | None
    posture: tuple[float, ...] | None

    @property
    def joints(self) -> tuple[str, ...]:
        return self.robot.joints

    def reset_to_home(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """The home keyframe (the model's default state where the robot names none), at rest."""
        reset_to_key(model, data, self.home_key)


def reset_to_key(model: mujoco.MjModel, data: mujoco.MjData, key: int | None) -> None:
    """`data` reset to keyframe `key`, or to the model's default state (qpos0, at rest) for None."""
    if key is None:
        mujoco.mj_resetData(model, data)
    else:
        mujoco.mj_resetDataKeyframe(model, data, key)


def _is_servo(model: mujoco.MjModel, a: int) -> bool:
    """Whether actuator a is a position servo: force kp (ctrl - q) (- kv qdot), MJCF's <position>."""
    kp = model.actuator_gainprm[a, 0]
    return int(model.actuator_biastype[a]) == _BIAS_AFFINE and kp > 0 and model.actuator_biasprm[a, 1] == -kp


def _servos_of(model: mujoco.MjModel, joints: Sequence[str]) -> tuple[str, ...]:
    """The position servos of the joints, one per joint in order; () unless every joint has one."""
    found = []
    for joint in joints:
        j = name_to_id(model, "joint", joint)
        servos = [
            a
            for a in range(model.nu)
            if int(model.actuator_trntype[a]) == _TRN_JOINT
            and int(model.actuator_trnid[a, 0]) == j
            and _is_servo(model, a)
            and model.actuator(a).name
        ]
        if len(servos) != 1:
            return ()
        found.append(model.actuator(servos[0]).name)
    return tuple(found)


#: The built-in arms' `taskspace` box [m, world]: above the built-in scenes' table, in front of the
#: base at the origin. A clip box, not a reach guarantee: its far corners lie beyond the arms' reach
#: (the IK stops short there), which `tsrl robot check`'s default box around home does not test.
TABLE_REACH_LOW = (-0.9, -0.55, 0.02)
TABLE_REACH_HIGH = (-0.15, 0.3, 0.7)

#: Built-in robots by name.
ROBOTS: dict[str, Robot] = {
    "ur5e": Robot(
        name="ur5e",
        model="ur5e",
        joints=ur5e.JOINT_NAMES,
        tcp=ur5e.TCP_SITE,
        home=ur5e.HOME_KEY,
        actuators=ur5e.JOINT_NAMES,  # each joint's servo carries the joint's name
        suction=ur5e.SUCTION_ACTUATOR,
        reach_low=TABLE_REACH_LOW,
        reach_high=TABLE_REACH_HIGH,
    ),
    "panda": Robot(
        name="panda",
        model="panda",
        joints=panda.JOINT_NAMES,
        tcp=panda.TCP_SITE,
        home=panda.HOME_KEY,
        actuators=panda.JOINT_NAMES,
        suction=panda.SUCTION_ACTUATOR,
        reach_low=TABLE_REACH_LOW,
        reach_high=TABLE_REACH_HIGH,
    ),
    "panda_gripper": Robot(
        name="panda_gripper",
        model="panda_gripper",
        joints=panda.JOINT_NAMES,
        tcp=panda.TCP_SITE,
        home=panda.HOME_KEY,
        actuators=panda.JOINT_NAMES,
        gripper=panda.GRIPPER_ACTUATOR,
        reach_low=TABLE_REACH_LOW,
        reach_high=TABLE_REACH_HIGH,
    ),
    "ur5e_gripper": Robot(
        name="ur5e_gripper",
        model="ur5e_gripper",
        joints=ur5e.JOINT_NAMES,
        tcp=ur5e.TCP_SITE,
        home=ur5e.HOME_KEY,
        actuators=ur5e.JOINT_NAMES,
        gripper=panda.GRIPPER_ACTUATOR,  # the Franka Hand's servo (tsrl.assets.panda)
        reach_low=TABLE_REACH_LOW,
        reach_high=TABLE_REACH_HIGH,
    ),
}


def load_robot(robot: str | Path | Robot) -> Robot:
    """A built-in robot by name (`ROBOTS`), a description from a TOML file, or `robot` itself.

    Raises:
        UnknownRobot: neither a built-in name nor an existing .toml file (the message lists the
            built-in robots); an `UnknownName`.
        InvalidConfig: a file with an unknown or missing key or a value of the wrong type (one line
            naming the file and the key; tsrl.configs). Its keys may sit under a `[robot]` table.
    """
    if isinstance(robot, Robot):
        return robot
    if isinstance(robot, str) and robot in ROBOTS:
        return ROBOTS[robot]
    path = Path(robot)
    if path.suffix.lower() != ".toml" or not path.is_file():
        raise UnknownRobot(str(robot), ROBOTS)
    loaded = load_file(Robot, path, section="robot")
    if loaded.model in SCENES or is_package_path(loaded.model) or Path(loaded.model).is_absolute():
        return loaded
    return dataclasses.replace(loaded, model=str(path.parent / loaded.model))  # relative to the file
