"""An experiment's results folder: the run folders in it (`find_runs`) and the settings that tell its
configurations apart (`variants`); the report (tsrl.experiments.aggregate) and the evaluations
(tsrl.experiments.evaluations) both read runs through it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..agents.config import TrainConfig
from ..agents.run_folder import CONFIG_FILE
from ..exceptions import InvalidConfig


def find_runs(results_dir: Path) -> list[Path]:
    """Run folders (holding config.json) directly inside `results_dir`, sorted by name."""
    results_dir = Path(results_dir)
    if not results_dir.is_dir():
        raise InvalidConfig(f"results folder {results_dir} does not exist")
    runs = sorted(p for p in results_dir.iterdir() if (p / CONFIG_FILE).is_file())
    if not runs:
        raise InvalidConfig(
            f"no run folders in {results_dir} (a run folder holds {CONFIG_FILE}); pass an experiment's "
            "results folder, e.g. results/quick-reach"
        )
    return runs


#: Config fields that are grid axes, set per env ([[budgets]]), or that do not change what a run
#: learns: not part of a variant.
_NOT_VARIANT = {
    "env_id",
    "obs",
    "action",
    "agent.algo",
    "seed",
    "total_timesteps",
    "eval_freq",
    "checkpoint_freq",
    "torch_threads",
}


def variants(cfgs: list[TrainConfig]) -> list[str]:
    """Per config, the settings (beyond env, obs, action, algo, seed) that differ among `cfgs`, as
    `field=value, ...`; empty when all share them (as the runs of one experiment do)."""
    flat = [{k: v for k, v in _flatten(c.to_dict()).items() if k not in _NOT_VARIANT} for c in cfgs]
    for f, cfg in zip(flat, cfgs, strict=True):  # an experiment's [demos] records one file per
        del f["agent.demos.path"]  # (env, obs, action): on or off is the variant (sha256: demos.json)
        f["agent.demos"] = cfg.agent.demos.active
        f["init_from"] = cfg.init_from is not None  # each seed its own source: started from one or not
    fields = sorted({k for f in flat for k in f if len({repr(g.get(k)) for g in flat}) > 1})
    return [", ".join(f"{k}={f.get(k)}" for k in fields) for f in flat]


def _flatten(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out |= _flatten(v, f"{prefix}{k}.")
        else:
            out[prefix + k] = v
    return out
