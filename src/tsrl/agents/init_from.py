"""`tsrl train --init-from RUN`: a new run that starts from another run's networks and normaliser.

The source is a run of the same algorithm, network sizes, policy inputs and normalisation, on a task
of the same layout (tsrl.envs.layout: typically the same task on another arm). What comes over from
its newest usable checkpoint: the policy's parameters (actor, critic and their target networks,
bit for bit) and the observation normaliser's running statistics. What does not: the optimiser
states, the replay buffer (it starts empty; demonstrations may be added), the counters (env steps
start at 0). The run folder records the source (init_from.json: its folder, checkpoint and the
sha256 of its model file); a run restarted from scratch loads the same checkpoint again, or stops.

check_init_from imports no torch, so the CLI refuses a bad source (one line, exit 2) before anything
loads or is written.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import TYPE_CHECKING

from ..exceptions import InvalidConfig
from .config import TrainConfig
from .run_folder import MODEL, NotARunFolder, latest_checkpoint, load_config, write_json_atomic
from .transfer import check_run_layouts

if TYPE_CHECKING:
    from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
    from stable_baselines3.common.vec_env import VecNormalize

#: The record of a run's source, in its run folder.
INIT_FROM_RECORD = "init_from.json"
#: Settings that shape the networks or what they read: the source must have the run's.
_SAME = ("algo", "net_arch", "policy_inputs", "normalize")


def check_init_from(cfg: TrainConfig) -> TrainConfig | None:
    """The source run's config, None without init_from; InvalidConfig (one line naming what differs
    and what is accepted) for a source that is not a run with a checkpoint, of another algorithm,
    network size, policy inputs or normalisation, or of another layout."""
    if cfg.init_from is None:
        return None
    source = Path(cfg.init_from)
    try:
        src = load_config(source)
    except NotARunFolder as err:
        raise InvalidConfig(f"--init-from: {err}") from None
    if latest_checkpoint(source) is None:
        raise InvalidConfig(f"--init-from {source}: the run has no checkpoint yet")
    for name in _SAME:
        theirs, ours = getattr(src.agent, name), getattr(cfg.agent, name)
        if theirs != ours:
            raise InvalidConfig(
                f"--init-from {source}: {name} is {_show(theirs)} there, {_show(ours)} here; "
                f"a run starts only from a run of the same {', '.join(_SAME)}"
            )
    try:
        check_run_layouts(src, cfg)
    except InvalidConfig as err:
        raise InvalidConfig(f"--init-from {source}: {err}") from None
    return src


def load_init(
    cfg: TrainConfig, run_dir: Path, model: OffPolicyAlgorithm, normalizer: VecNormalize | None
) -> None:
    """Copies the source's policy parameters into `model` and its normaliser statistics into
    `normalizer`, and writes (or checks, on a restart from scratch) init_from.json."""
    from .checkpoint import load_policy, usable_checkpoint
    from .factory import ALGO_CLASSES

    assert cfg.init_from is not None
    source = Path(cfg.init_from)
    src = load_config(source)
    checkpoint = usable_checkpoint(source, src.agent.normalize, for_training=False)
    if checkpoint is None:
        raise InvalidConfig(f"--init-from {source}: the run has no usable checkpoint")
    digest = hashlib.sha256((checkpoint.path / MODEL).read_bytes()).hexdigest()
    record_path = run_dir / INIT_FROM_RECORD
    record = {"run": str(source), "checkpoint": str(checkpoint.path), "env_steps": checkpoint.state.env_steps}
    record["model_sha256"] = digest
    if record_path.is_file():
        before = json.loads(record_path.read_text())
        if before.get("model_sha256") != digest:
            raise InvalidConfig(
                f"{run_dir} started from {before.get('checkpoint')} (sha256 {before.get('model_sha256')}); "
                f"{source}'s newest checkpoint is now {checkpoint.path} (sha256 {digest}); restore it or "
                "start a new run"
            )
    src_model, src_normalizer = load_policy(checkpoint, ALGO_CLASSES[src.agent.algo])
    model.policy.load_state_dict(src_model.policy.state_dict())
    if normalizer is not None and src_normalizer is not None:
        normalizer.obs_rms = src_normalizer.obs_rms  # unpickled for this run alone
    write_json_atomic(record_path, record)


def _show(value: object) -> str:
    return " ".join(map(str, value)) if isinstance(value, tuple) else repr(value)
