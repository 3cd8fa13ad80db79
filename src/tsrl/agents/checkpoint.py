"""Checkpoints of a run: model, replay buffer, normaliser statistics, counters and RNG states.

A checkpoint is a folder `checkpoints/step_<env steps>/` (tsrl.agents.run_folder), written whole into a
temporary folder and renamed into place (atomic), so a run killed at any moment (SIGKILL included)
leaves only complete checkpoints. The last two complete ones are kept. Before a checkpoint is used it
is verified: the model archive opens and its counters agree with state.json, the normaliser's sha256
is the one recorded when it was written (sha256.json), the pickles load and hold what they should. A damaged checkpoint is skipped with a one-line warning naming the damaged file, and
the previous one is used; if none is usable, NoUsableCheckpoint names every damaged file. Checkpoints
are only taken between updates, at an episode boundary, so a resumed run starts a fresh episode with
nothing half-stored.
"""

from __future__ import annotations

import hashlib
import json
import pickle
import random
import shutil
import sys
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import VecEnv, VecNormalize
from stable_baselines3.her import HerReplayBuffer

from ..files import replacing
from .run_folder import (
    CHECKPOINTS,
    KEEP_CHECKPOINTS,
    MODEL,
    NORMALIZER,
    REPLAY_BUFFER,
    RNG,
    SHA256S,
    STATE,
    DamagedCheckpoint,
    NoUsableCheckpoint,
    RunState,
    checkpoint_dirs,
    checkpoint_path,
    read_state,
)

_RNG_KEYS = frozenset({"python", "numpy", "torch", "action_space"})
#: rng.pkl's entry of a run with resets to demonstration states: the curriculum's state
#: (DemoResets.curriculum_state), absent from other runs' checkpoints and from older ones.
DEMO_RESETS = "demo_resets"


@dataclass(frozen=True)
class Checkpoint:
    """A verified checkpoint, with the parts that were loaded to verify it (None where not asked for)."""

    path: Path
    state: RunState
    normalizer: VecNormalize | None
    replay_buffer: ReplayBuffer | None = None
    rng: dict[str, Any] | None = None


def save_checkpoint(
    run_dir: Path, model: OffPolicyAlgorithm, normalizer: VecNormalize | None, state: RunState
) -> Path:
    """Writes a checkpoint atomically and removes all but the last KEEP_CHECKPOINTS; returns its folder."""
    root = run_dir / CHECKPOINTS
    root.mkdir(parents=True, exist_ok=True)
    final = checkpoint_path(run_dir, state.clock)
    if (final / STATE).is_file():  # this very state is already saved (e.g. a stop right after resuming)
        return final
    with replacing(final) as tmp:  # a folder without state.json (a damaged one) is replaced
        tmp.mkdir()
        model.save(tmp / MODEL)
        with open(tmp / REPLAY_BUFFER, "wb") as f:
            pickle.dump(model.replay_buffer, f, protocol=pickle.HIGHEST_PROTOCOL)
        if normalizer is not None:
            with open(tmp / NORMALIZER, "wb") as f:
                pickle.dump(normalizer, f, protocol=pickle.HIGHEST_PROTOCOL)
            (tmp / SHA256S).write_text(json.dumps({NORMALIZER: _sha256(tmp / NORMALIZER)}, indent=2) + "\n")
        with open(tmp / RNG, "wb") as f:
            pickle.dump(_rng_state(model), f, protocol=pickle.HIGHEST_PROTOCOL)
        (tmp / STATE).write_text(json.dumps(state.__dict__, indent=2) + "\n")  # last: marks it complete
    keep = set(checkpoint_dirs(run_dir)[-KEEP_CHECKPOINTS:]) | {final}
    for old in root.iterdir():  # older checkpoints, and temporaries (".step_...") of killed writers
        if old not in keep and old.name.lstrip(".").startswith("step_"):
            shutil.rmtree(old, ignore_errors=True)
    return final


def verify_checkpoint(path: Path, normalized: bool, for_training: bool) -> Checkpoint:
    """Checks every file of the checkpoint at `path` that is about to be used; raises DamagedCheckpoint
    naming the first bad file.

    The model archive must open (every member's CRC) and its env steps and episodes agree with
    state.json; the normaliser (when `normalized`) must have the sha256 recorded with it (sha256.json;
    a checkpoint written before tsrl recorded it has none) and unpickle to a VecNormalize. With
    `for_training`, the replay buffer must unpickle to a buffer holding state.json's env steps, and the
    RNG states to the four generators a resumed run restores.
    """
    state = read_state(path)
    _verify_model(path / MODEL, state)
    if normalized:
        _verify_sha256(path, NORMALIZER)
    normalizer = _load_pickle(path / NORMALIZER, VecNormalize) if normalized else None
    if not for_training:
        return Checkpoint(path, state, normalizer)
    buffer = _load_pickle(path / REPLAY_BUFFER, ReplayBuffer)
    stored = buffer.buffer_size if buffer.full else buffer.pos
    if stored != min(state.env_steps, buffer.buffer_size):
        raise DamagedCheckpoint(
            path / REPLAY_BUFFER, f"holds {stored} transitions, state.json counts {state.env_steps} env steps"
        )
    rng = _load_pickle(path / RNG, dict)
    if set(rng) - {DEMO_RESETS} != _RNG_KEYS:
        raise DamagedCheckpoint(path / RNG, f"expected RNG states {sorted(_RNG_KEYS)}; got {sorted(rng)}")
    if DEMO_RESETS in rng and not _is_curriculum_state(rng[DEMO_RESETS]):
        raise DamagedCheckpoint(
            path / RNG,
            f"{DEMO_RESETS!r} is not a curriculum state {{'window': int >= 1, 'outcomes': [bool, ...]}}; "
            f"got {rng[DEMO_RESETS]!r:.80}",
        )
    return Checkpoint(path, state, normalizer, buffer, rng)


_CURRICULUM = ("window", "outcomes")
_FRONTIER = ("frontier", "frontier_outcomes")


def _is_frontier_state(frontier: object, outcomes: object) -> bool:
    """Whether the per-demonstration frontier's state has its form: a list of int >= 0, and as many
    lists of bool."""
    return (
        isinstance(frontier, list)
        and all(isinstance(f, int) and not isinstance(f, bool) and f >= 0 for f in frontier)
        and isinstance(outcomes, list)
        and len(outcomes) == len(frontier)
        and all(isinstance(o, list) and all(isinstance(b, bool) for b in o) for o in outcomes)
    )


def _is_curriculum_state(value: object) -> bool:
    """Whether `value` has the form of DemoResets.curriculum_state: {"window": int >= 1, "outcomes":
    list of bool}."""
    if not isinstance(value, dict) or set(value) not in ({"window", "outcomes"}, {*_CURRICULUM, *_FRONTIER}):
        return False
    if "frontier" in value and not _is_frontier_state(value["frontier"], value["frontier_outcomes"]):
        return False
    window, outcomes = value["window"], value["outcomes"]
    return (
        isinstance(window, int)
        and not isinstance(window, bool)
        and window >= 1
        and isinstance(outcomes, list)
        and all(isinstance(o, bool) for o in outcomes)
    )


def usable_checkpoint(run_dir: Path, normalized: bool, for_training: bool) -> Checkpoint | None:
    """The newest checkpoint that passes verify_checkpoint, None if the run has no checkpoint yet.

    Each damaged one is skipped with a one-line warning on stderr naming the damaged file; when every
    checkpoint is damaged, NoUsableCheckpoint names each damaged file. Nothing is written or removed.
    """
    damaged: list[DamagedCheckpoint] = []
    for path in reversed(checkpoint_dirs(run_dir)):
        try:
            checkpoint = verify_checkpoint(path, normalized, for_training)
        except DamagedCheckpoint as err:
            damaged.append(err)
            continue
        for skipped in damaged:
            print(f"tsrl: warning: damaged checkpoint skipped, {skipped}; using {path.name}", file=sys.stderr)
        return checkpoint
    if damaged:
        raise NoUsableCheckpoint(run_dir, damaged)
    return None


def load_checkpoint(
    checkpoint: Checkpoint,
    algo_class: type[OffPolicyAlgorithm],
    env: VecEnv,
    normalizer: VecNormalize | None,
) -> OffPolicyAlgorithm:
    """The model of a verified `checkpoint` on `env`, with its replay buffer, normaliser statistics and
    RNG states, and its counters."""
    assert checkpoint.replay_buffer is not None and checkpoint.rng is not None, "verified for_training"
    model = algo_class.load(checkpoint.path / MODEL, env=env, device="cpu")
    buffer = checkpoint.replay_buffer
    if isinstance(buffer, HerReplayBuffer):
        loaded_env = model.get_env()
        assert loaded_env is not None  # loaded with env=
        buffer.set_env(loaded_env)
    buffer.device = model.device
    model.replay_buffer = buffer
    if normalizer is not None and checkpoint.normalizer is not None:
        normalizer.obs_rms = checkpoint.normalizer.obs_rms
        normalizer.ret_rms = checkpoint.normalizer.ret_rms
    _set_rng_state(model, checkpoint.rng)
    model.num_timesteps = checkpoint.state.env_steps
    model._episode_num = checkpoint.state.episodes
    return model


def load_policy(
    checkpoint: Checkpoint, algo_class: type[OffPolicyAlgorithm]
) -> tuple[Any, VecNormalize | None]:
    """Model (without env or replay buffer) and normaliser of a verified checkpoint, for evaluation and
    rendering."""
    # No env and a token replay buffer: HER's buffer needs an env, and evaluation needs no buffer.
    no_buffer: dict[str, Any] = {"replay_buffer_class": None, "replay_buffer_kwargs": {}, "buffer_size": 1}
    model = algo_class.load(checkpoint.path / MODEL, device="cpu", custom_objects=no_buffer)
    normalizer = checkpoint.normalizer
    if normalizer is not None:
        normalizer.training = False
    return model, normalizer


def _verify_model(path: Path, state: RunState) -> None:
    try:
        with zipfile.ZipFile(path) as archive:
            bad = archive.testzip()
            if bad is not None:
                raise DamagedCheckpoint(path, f"member {bad} fails its CRC check")
            data = json.loads(archive.read("data"))
            names = set(archive.namelist())
    except (OSError, zipfile.BadZipFile, KeyError, EOFError, json.JSONDecodeError, UnicodeDecodeError) as err:
        raise DamagedCheckpoint(path, f"not a readable model archive ({type(err).__name__}: {err})") from None
    if "policy.pth" not in names:
        raise DamagedCheckpoint(path, "the model archive has no policy.pth")
    counters = (data.get("num_timesteps"), data.get("_episode_num"))
    if counters != (state.env_steps, state.episodes):
        raise DamagedCheckpoint(
            path,
            f"env steps and episodes {counters} disagree with state.json's ({state.env_steps}, {state.episodes})",
        )


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _verify_sha256(checkpoint: Path, name: str) -> None:
    """Raises DamagedCheckpoint unless the checkpoint's file `name` has the sha256 its sha256.json
    records (nothing to check where the checkpoint has no sha256.json or it does not list the file)."""
    record = checkpoint / SHA256S
    if not record.is_file():
        return
    try:
        hashes = json.loads(record.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise DamagedCheckpoint(record, f"unreadable ({type(err).__name__}: {err})") from None
    expected = hashes.get(name) if isinstance(hashes, dict) else None
    if expected is None:
        return
    try:
        actual = _sha256(checkpoint / name)
    except OSError as err:
        raise DamagedCheckpoint(checkpoint / name, f"unreadable ({err.strerror})") from None
    if actual != expected:
        raise DamagedCheckpoint(
            checkpoint / name,
            f"sha256 {actual} differs from {expected}, recorded in {SHA256S} when it was written (changed since)",
        )


def _load_pickle(path: Path, expected: type) -> Any:
    try:
        with open(path, "rb") as f:
            obj = pickle.load(f)
    except Exception as err:  # noqa: BLE001  (unpickling a damaged file can raise almost anything)
        raise DamagedCheckpoint(path, f"does not load ({type(err).__name__}: {err})") from None
    if not isinstance(obj, expected):
        raise DamagedCheckpoint(path, f"holds a {type(obj).__name__}, expected a {expected.__name__}")
    return obj


def _rng_state(model: OffPolicyAlgorithm) -> dict[str, Any]:
    state = {
        "python": random.getstate(),
        "numpy": np.random.get_state(),
        "torch": th.get_rng_state(),
        "action_space": model.action_space.np_random.bit_generator.state,
    }
    env = model.get_env()
    if env is not None and env.has_attr("curriculum_state"):  # tsrl.agents.demo_resets.DemoResets
        state[DEMO_RESETS] = env.env_method("curriculum_state")[0]
    return state


def _set_rng_state(model: OffPolicyAlgorithm, state: dict[str, Any]) -> None:
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])
    th.set_rng_state(state["torch"])
    model.action_space.np_random.bit_generator.state = state["action_space"]
