"""Resets to demonstration states (Nair et al. 2018): a training episode starts, with a probability,
from a state a demonstration passed through, restored exactly.

A demonstration file (tsrl.agents.demo_files) holds each episode's seed and actions, and the
environments are deterministic: `replay_states` replays every episode once on a fresh copy of the
run's environment, keeps its state (`TaskEnv.get_state`: MuJoCo's full integration state,
mjSTATE_INTEGRATION: time, qpos, qvel, act, warm start, ctrl, applied forces, equality flags, mocap
poses, user data; and the previous actions a task observes) after the reset and after each step,
and checks that the replay reproduces the file's observations bit for bit (a file the environment
does not reproduce is one DemoFileError naming the episode and step). So every file,
old ones included, can be reset to; the files need no state arrays.

`DemoResets` wraps the training environment (not the evaluation ones): after the task's own reset,
with probability `prob` it restores a demonstration state (a uniform episode and step, or with a
reverse curriculum a step among the demonstration's last ones, a window widened by env steps or, paced
by success, whenever the last demonstration-started episodes succeeded) and returns that state's
observation.
Its draws come from its own generator, seeded from the run's seed. A resumed run continues the
curriculum where its checkpoint left it (`continue_from`: the env steps done, the success-paced
window and outcomes from the checkpoint; the generator reseeded from the seed and the episodes done,
as the environment is).

`restore_state` writes a state into the environment through `TaskEnv.restore_state` (MuJoCo's
`mj_setState` / `mj_forward` and the previous actions, then the task's observation of it).
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np

from ..envs.base import TaskEnv
from ..envs.keys import OBS_KEYS
from .demo_files import DemoFileError, Demonstrations


def first_successes(demos: Demonstrations) -> np.ndarray:
    """(N,) each demonstration's first successful state: the index, in replay_states' (N, T + 1)
    states, after the first step whose is_success is set (the reverse curriculum's first frontier)."""
    return np.argmax(demos.is_success, axis=1) + 1


def restore_state(base: TaskEnv, state: np.ndarray) -> dict[str, np.ndarray]:
    """Writes `state` (from TaskEnv.get_state) into the task env `base` and returns its observation."""
    return base.restore_state(state)


def replay_states(env: gym.Env, demos: Demonstrations, path: str) -> np.ndarray:
    """(N, T + 1, n) states of the N demonstrations of `demos` (file `path`) replayed on `env` (a
    fresh environment of the run, made with gym.make); each observation checked bit for bit."""
    base = env.unwrapped
    assert isinstance(base, TaskEnv)
    if base.task.randomize.active:
        raise DemoFileError(path, "resets to demonstration states need a task without [randomize]")
    t_steps = demos.episode_steps
    states = np.empty((demos.n_episodes, t_steps + 1, base.get_state().size))
    for i in range(demos.n_episodes):
        obs, _ = env.reset(seed=int(demos.seeds[i]))
        for t in range(t_steps + 1):
            if t > 0:
                obs = env.step(demos.actions[i, t - 1])[0]
            for key in OBS_KEYS:
                if not np.array_equal(obs[key], getattr(demos, key)[i, t]):
                    raise DemoFileError(
                        path,
                        f"replaying episode {i} (seed {int(demos.seeds[i])}) does not reproduce its "
                        f"{key} at step {t}: recorded on another version of the task? Resets to "
                        "demonstration states need a file this environment reproduces",
                    )
            states[i, t] = base.get_state()
    return states


#: The per-demonstration frontier (DemoConfig.reset_frontier_k, RFCL, Tao et al. 2024): steps a
#: frontier moves back after k of k successes from it (and the width of the window starts are drawn
#: from, ending at the frontier); the time limit of an episode started at step t of a T-step
#: demonstration: FRONTIER_TIME x (T - t) steps, at least FRONTIER_MIN_STEPS (never more than T).
FRONTIER_STRIDE = 3
FRONTIER_TIME = 2
FRONTIER_MIN_STEPS = 10

#: The success-paced curriculum (DemoConfig.reset_curriculum_success): the number of last
#: demonstration-started episodes it judges a window by, and the window's growth (a fraction of T).
PACE_EPISODES = 20
PACE_STRIDE = 0.1


DEMO_RESET = "demo_reset"
"""The info key of a demonstration-started episode's reset and last step: (demonstration, step)."""


class DemoResets(gym.Wrapper):
    """Starts an episode from a demonstration state with probability `prob` (module docstring).

    Args:
        env: the training environment (gym.make's, unwrapped a tsrl TaskEnv).
        states: (N, T + 1, n) from replay_states.
        prob: probability of a demonstration reset, in (0, 1].
        curriculum_steps: 0: the step is uniform in [0, T - 1]; N > 0: uniform in [T - w, T - 1] with
            w = ceil(T * min(1, env steps / N)) (at least 1), the window growing with the env steps.
        seed: seed of the wrapper's own generator.
        curriculum_success: 0: off; s > 0: the step is uniform in [T - w, T - 1] with w starting at 1
            and growing by ceil(PACE_STRIDE * T) (up to T) whenever the last PACE_EPISODES
            demonstration-started episodes since it last grew succeeded at a rate >= s.
        frontier_k: 0: off; k > 0: RFCL's reverse curriculum per demonstration. Demonstration i has a
            frontier f_i, first its first successful state (`first_success[i]`); an episode started
            from it begins at a step uniform in [f_i - FRONTIER_STRIDE + 1, f_i] (at least 0), is
            truncated after FRONTIER_TIME x (T - step) steps (at least FRONTIER_MIN_STEPS), and f_i
            moves FRONTIER_STRIDE steps back once k episodes in a row started from demonstration i
            succeed; a failure starts the count again.
        first_success: (N,) the state index of each demonstration's first success (frontier_k > 0).
    """

    def __init__(
        self,
        env: gym.Env,
        states: np.ndarray,
        prob: float,
        curriculum_steps: int,
        seed: int,
        curriculum_success: float = 0.0,
        frontier_k: int = 0,
        first_success: np.ndarray | None = None,
    ):
        super().__init__(env)
        self.frontier_k = frontier_k
        self.frontier = [int(f) for f in first_success] if first_success is not None else []
        self.frontier_outcomes: list[list[bool]] = [[] for _ in self.frontier]
        self.steps_left: int | None = None  # the frontier episode's own time limit
        self.states = states
        self.prob = prob
        self.curriculum_steps = curriculum_steps
        self.curriculum_success = curriculum_success
        self.seed = seed
        self.rng = np.random.default_rng([seed, 0xDE30])  # its own stream: the env's draws are unchanged
        self.env_steps = 0
        self.last_reset: tuple[int, int] | None = None
        self.window = 1  # the success-paced window [steps]
        self.outcomes: list[bool] = []  # the last demonstration-started episodes since it last grew

    def curriculum_state(self) -> dict[str, Any]:
        """The success-paced curriculum's state, for a checkpoint (continue_from takes it back)."""
        state: dict[str, Any] = {"window": self.window, "outcomes": list(self.outcomes)}
        if self.frontier_k:
            state |= {
                "frontier": list(self.frontier),
                "frontier_outcomes": [list(o) for o in self.frontier_outcomes],
            }
        return state

    def continue_from(self, env_steps: int, episodes: int, curriculum: dict[str, Any] | None = None) -> None:
        """A resumed run's wrapper: the curriculum at `env_steps` (the checkpoint's) and, paced by
        success, at its saved `curriculum` state; its draws from a generator seeded from (seed,
        `episodes` done), as the resumed environment's are."""
        self.env_steps = env_steps
        self.rng = np.random.default_rng([self.seed, 0xDE30, episodes])
        if curriculum is not None:
            self.window, self.outcomes = int(curriculum["window"]), list(curriculum["outcomes"])
            if "frontier" in curriculum:
                self.frontier = [int(f) for f in curriculum["frontier"]]
                self.frontier_outcomes = [list(o) for o in curriculum["frontier_outcomes"]]

    def frontier_step(self, episode: int) -> int:
        """The step of demonstration `episode` a reset restores with the frontier curriculum (drawn
        from the FRONTIER_STRIDE steps ending at its frontier)."""
        front = self.frontier[episode]
        return int(self.rng.integers(max(0, front - FRONTIER_STRIDE + 1), front + 1))

    def start_step(self) -> int:
        """The demonstration step the next demonstration reset restores (drawn)."""
        t_steps = self.states.shape[1] - 1
        if self.curriculum_success:
            return int(self.rng.integers(t_steps - self.window, t_steps))
        if self.curriculum_steps == 0:
            return int(self.rng.integers(t_steps))
        window = max(1, math.ceil(t_steps * min(1.0, self.env_steps / self.curriculum_steps)))
        return int(self.rng.integers(t_steps - window, t_steps))

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        self.last_reset = None
        self.steps_left = None
        if self.rng.random() >= self.prob:
            return obs, info
        episode = int(self.rng.integers(self.states.shape[0]))
        step = self.frontier_step(episode) if self.frontier_k else self.start_step()
        if self.frontier_k:
            t_steps = self.states.shape[1] - 1
            self.steps_left = min(t_steps, max(FRONTIER_MIN_STEPS, FRONTIER_TIME * (t_steps - step)))
        base = self.env.unwrapped
        assert isinstance(base, TaskEnv)
        obs = restore_state(base, self.states[episode, step])
        _, outcome = base.goal.outcome(obs["achieved_goal"], obs["desired_goal"])
        self.last_reset = (episode, step)
        return obs, info | outcome | {DEMO_RESET: (episode, step)}

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        self.env_steps += 1
        obs, reward, terminated, truncated, info = self.env.step(action)
        if self.steps_left is not None:
            self.steps_left -= 1
            if self.steps_left <= 0 and not terminated and not truncated:
                truncated = True  # the frontier episode's own, shorter time limit
                info = info | {"TimeLimit.truncated": True}
        if self.last_reset is not None and (terminated or truncated):
            info = info | {DEMO_RESET: self.last_reset}  # the episode's end says where it started
            if self.curriculum_success:
                self._pace(bool(info["is_success"]))
            if self.frontier_k:
                self.advance_frontier(self.last_reset[0], bool(info["is_success"]))
            self.steps_left = None
        return obs, reward, terminated, truncated, info

    def advance_frontier(self, episode: int, success: bool) -> None:
        """Counts an outcome of an episode started from demonstration `episode`: k successes in a row
        move its frontier FRONTIER_STRIDE steps back (not below 0); a failure restarts the count."""
        outcomes = [*self.frontier_outcomes[episode], success] if success else []
        if len(outcomes) >= self.frontier_k:
            self.frontier[episode] = max(0, self.frontier[episode] - FRONTIER_STRIDE)
            outcomes = []
        self.frontier_outcomes[episode] = outcomes

    def _pace(self, success: bool) -> None:
        """Counts a demonstration-started episode's outcome; widens the window when they succeed."""
        self.outcomes = [*self.outcomes, success][-PACE_EPISODES:]
        if len(self.outcomes) == PACE_EPISODES and np.mean(self.outcomes) >= self.curriculum_success:
            t_steps = self.states.shape[1] - 1
            self.window = min(t_steps, self.window + math.ceil(PACE_STRIDE * t_steps))
            self.outcomes = []
