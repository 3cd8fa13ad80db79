"""The keys of a goal environment's observation dict (Gymnasium's GoalEnv contract), in the order tsrl
stores, normalises and records them."""

OBS_KEYS: tuple[str, ...] = ("observation", "achieved_goal", "desired_goal")
