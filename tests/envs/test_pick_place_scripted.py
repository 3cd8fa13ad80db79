"""Pick-and-place is solvable: a scripted controller on the public task-map API succeeds >= 95/100."""

import gymnasium as gym
import numpy as np

import tsrl  # noqa: F401
from tsrl.assets import load_model

#: The controller observes exactly what it needs, through a task-map spec.
SPEC = "position(tcp), position(box), position(target)"
BOX_HALF_SIZE = float(load_model("pick_place").geom("box").size[0])
HOVER = 0.10  # m above the box top before descending
GRIP_DEPTH = 0.004  # m the cup target goes below the box top, to press the cup onto it
CARRY_SPEED = 0.6  # fraction of the largest TCP step while the box hangs on the cup


class ScriptedPickPlace:
    """Above the box, descend, suction on, lift, carry, release (goals on the table) or hold (in the air)."""

    def __init__(self, max_step: float):
        self.max_step = max_step
        self.phase = "approach"

    def act(self, obs: dict[str, np.ndarray], slices: dict[str, slice]) -> np.ndarray:
        y = obs["observation"]
        tcp, box, goal = (y[slices[f"position({f})"]] for f in ("tcp", "box", "target"))
        box_top = box + [0.0, 0.0, BOX_HALF_SIZE]
        suction = -1.0
        if self.phase == "approach":
            target = box_top + [0.0, 0.0, HOVER]
            if np.linalg.norm(tcp - target) < 0.01:
                self.phase = "descend"
        if self.phase == "descend":
            target = box_top - [0.0, 0.0, GRIP_DEPTH]
            if tcp[2] < box_top[2] + 0.003:
                self.phase = "lift"
        if self.phase == "lift":
            suction = 1.0
            target = np.array([*box_top[:2], max(goal[2], BOX_HALF_SIZE) + BOX_HALF_SIZE + 0.08])
            if tcp[2] > target[2] - 0.02:
                self.phase = "carry"
        if self.phase == "carry":
            suction = 1.0
            target = goal + [0.0, 0.0, BOX_HALF_SIZE]
            on_table = goal[2] < 1.5 * BOX_HALF_SIZE
            if on_table and np.linalg.norm(box - goal) < 0.01:
                self.phase = "release"
        if self.phase == "release":
            target = goal + [0.0, 0.0, BOX_HALF_SIZE + 0.03]
        speed = CARRY_SPEED if self.phase in ("lift", "carry") else 1.0
        action = np.clip((target - tcp) / self.max_step, -speed, speed)
        return np.append(action, suction)


def test_scripted_controller_solves_pick_and_place():
    env = gym.make("tsrl/UR5ePickPlace-v0", obs=SPEC)
    slices = env.unwrapped.observation_structure
    max_step = env.unwrapped.task.action_spec.parts[0].step
    successes = 0
    for seed in range(100):
        obs, _ = env.reset(seed=seed)
        controller = ScriptedPickPlace(max_step)
        truncated = False
        while not truncated:
            obs, _, _, truncated, info = env.step(controller.act(obs, slices))
        successes += info["is_success"]
    assert successes >= 95, f"{successes}/100 episodes succeeded"
