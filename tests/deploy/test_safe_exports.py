"""Exports that cannot hurt: `--out` never replaces what an export did not write; a normaliser changed
since its checkpoint was written (its sha256) is not exported; an altered contract, unusable limits or
normaliser statistics, a bad `--goal` or `--log` are one line (exit 2) before
anything moves; a log cut anywhere replays its complete records and says that it ends early."""

from __future__ import annotations

import json
import pickle
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from training_helpers import tiny

from tsrl.cli import main
from tsrl.deploy.contract import CONTRACT, ContractError, contract_digest, read_contract


@pytest.fixture(scope="module")
def run_and_export(tmp_path_factory) -> tuple[Path, Path]:
    from tsrl.agents import train

    root = tmp_path_factory.mktemp("safe")
    run_dir = train(tiny("ddpg", total=200), root / "runs", progress_bar=False)
    assert main(["export", str(run_dir), "--out", str(root / "export")]) == 0
    return run_dir, root / "export"


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("tsrl: error: ") and "\n" not in err, err
    return err


def tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_export_refuses_a_run_folder_a_folder_of_runs_and_any_folder_it_did_not_write(
    run_and_export, tmp_path, capsys
):
    run_dir, export = run_and_export
    runs = run_dir.parent
    before = tree(runs)
    assert main(["export", str(run_dir), "--out", str(run_dir)]) == 2
    assert "holds the run" in one_error_line(capsys)
    assert main(["export", str(run_dir), "--out", str(runs)]) == 2
    assert "holds the run" in one_error_line(capsys)
    other = tmp_path / "other"
    shutil.copytree(run_dir, other / "a-run")  # a folder holding another run
    assert main(["export", str(run_dir), "--out", str(other)]) == 2
    assert "holds runs (a-run" in one_error_line(capsys)
    assert main(["export", str(run_dir), "--out", str(other / "a-run")]) == 2
    assert "is a run folder" in one_error_line(capsys)
    notes = tmp_path / "notes"
    notes.mkdir()
    (notes / "keep.txt").write_text("mine")
    assert main(["export", str(run_dir), "--out", str(notes)]) == 2
    assert "non-empty folder that `tsrl export` did not write" in one_error_line(capsys)
    stray = tmp_path / "stray"
    shutil.copytree(export, stray)
    (stray / "extra.txt").write_text("not the export's")
    assert main(["export", str(run_dir), "--out", str(stray)]) == 2
    assert "did not write" in one_error_line(capsys)
    assert tree(runs) == before and (notes / "keep.txt").read_text() == "mine"
    assert (stray / "extra.txt").exists()
    again = tmp_path / "again"
    shutil.copytree(export, again)  # an earlier export is replaced
    assert main(["export", str(run_dir), "--out", str(again)]) == 0
    read_contract(again)


def _edited(export: Path, tmp_path: Path, name: str, edit, rehash: bool) -> Path:
    folder = tmp_path / name
    shutil.copytree(export, folder)
    contract = json.loads((folder / CONTRACT).read_text())
    edit(contract)
    if rehash:  # an edit that also recomputes the contract's hash: the values themselves are checked
        contract["sha256"] = contract_digest(contract)
    (folder / CONTRACT).write_text(json.dumps(contract))
    return folder


def test_an_altered_contract_and_unusable_limits_are_refused_in_one_line(run_and_export, tmp_path, capsys):
    _, export = run_and_export

    def faster(c):
        c["robot"]["max_joint_speed"][0] = 9.14

    folder = _edited(export, tmp_path, "faster", faster, rehash=False)
    assert main(["deploy", str(folder), "--log", str(tmp_path / "x.jsonl")]) == 2
    assert "contract.json: altered since export" in one_error_line(capsys)
    cases = {
        "nan speed": (
            lambda c: c["robot"]["max_joint_speed"].__setitem__(1, float("nan")),
            "max_joint_speed",
        ),
        "negative": (
            lambda c: c["robot"]["max_joint_acceleration"].__setitem__(2, -1.0),
            "max_joint_acceleration",
        ),
        "inverted": (lambda c: c["robot"]["joint_limits"].__setitem__(0, [1.0, -1.0]), "joint_limits of"),
        "workspace": (lambda c: c["workspace"].__setitem__("low", [0.0, 0.0, 9.0]), "workspace is low"),
        "period": (lambda c: c["task"].__setitem__("control_period_s", 0.0), "task.control_period_s"),
        "mean": (
            lambda c: c["policy"]["normalizer"]["statistics"]["observation"]["mean"].__setitem__(0, -4.9e307),
            "normaliser mean of 'observation' holds -4.9e+307",
        ),
    }
    _each_refused(cases, export, tmp_path, capsys)
    older = _edited(export, tmp_path, "v1", lambda c: c.__setitem__("contract_version", 1), rehash=False)
    assert main(["deploy", str(older), "--log", str(tmp_path / "x.jsonl")]) == 2
    assert "contract_version 1; this tsrl reads 2 (export the run again)" in one_error_line(capsys)
    assert not (tmp_path / "x.jsonl").exists()


def _each_refused(cases: dict, export, tmp_path, capsys) -> None:
    """Each case's edit (rehashed) is refused by read_contract and by `tsrl deploy` (exit 2) in one line
    holding its words."""
    for name, (edit, words) in cases.items():
        folder = _edited(export, tmp_path, name.replace(" ", "_"), edit, rehash=True)
        with pytest.raises(ContractError, match=re.escape(words)):
            read_contract(folder)
        assert main(["deploy", str(folder), "--log", str(tmp_path / "x.jsonl")]) == 2
        assert words in one_error_line(capsys), name


def test_a_contract_whose_keys_or_types_the_record_does_not_take_is_refused_in_one_line(
    run_and_export, tmp_path, capsys
):
    _, export = run_and_export
    cases = {  # each rehashed: the typed record (tsrl.configs' loader) refuses it, naming file and key
        "joint name": (
            lambda c: c["robot"]["joints"].__setitem__(0, 5),
            "contract.json: robot.joints[0] must be a string; got 5 (export the run again)",
        ),
        "steps": (
            lambda c: c["task"].__setitem__("episode_steps", 50.5),
            "contract.json: task.episode_steps must be an integer; got 50.5",
        ),
        "tool kind": (
            lambda c: c["action"].__setitem__(
                "tool", {"column": 3, "actuator": "g", "kind": "vacuum", "rule": ""}
            ),
            "contract.json: action.tool.kind = 'vacuum'; accepted: 'suction', 'gripper'",
        ),
        "unknown key": (
            lambda c: c["robot"].__setitem__("max_joint_sped", [1.0] * 6),
            "contract.json: unknown key 'max_joint_sped' in [robot]; accepted: name, joints,",
        ),
        "missing key": (
            lambda c: c["task"].pop("scene"),
            "contract.json: missing key 'scene' in [task]",
        ),
    }
    _each_refused(cases, export, tmp_path, capsys)
    assert not (tmp_path / "x.jsonl").exists()


def test_a_normaliser_changed_after_its_checkpoint_was_written_is_refused_at_export(
    run_and_export, tmp_path, capsys
):
    run_dir, _ = run_and_export
    copy = tmp_path / "runs" / run_dir.name
    shutil.copytree(run_dir, copy)
    pkls = sorted(copy.glob("checkpoints/*/vecnormalize.pkl"))
    assert len(pkls) == 2 and all((p.parent / "sha256.json").is_file() for p in pkls)

    def flip(pkl: Path) -> None:  # the lowest bit of the first mean: finite, plausible, unpickles
        data = pkl.read_bytes()
        mean = pickle.loads(data).obs_rms["observation"].mean
        flipped = mean.copy()
        flipped.view(np.uint64)[0] ^= 1
        assert data.count(mean.tobytes()) == 1 and np.isfinite(flipped).all()
        pkl.write_bytes(data.replace(mean.tobytes(), flipped.tobytes()))

    flip(pkls[1])  # the newest: skipped with a warning naming it, the older checkpoint exported
    assert main(["export", str(copy), "--out", str(tmp_path / "older")]) == 0
    warning = capsys.readouterr().err.strip()
    assert (
        "\n" not in warning and f"{pkls[1]}: sha256 " in warning and f"using {pkls[0].parent.name}" in warning
    )
    assert json.loads((tmp_path / "older" / CONTRACT).read_text())["run"]["checkpoint"] == pkls[0].parent.name
    flip(pkls[0])  # every checkpoint's: refused in one line, nothing written
    assert main(["export", str(copy), "--out", str(tmp_path / "export")]) == 2
    err = one_error_line(capsys)
    assert "no usable checkpoint" in err and f"{pkls[0]}: sha256 " in err and "recorded in sha256.json" in err
    assert not (tmp_path / "export").exists()


def test_a_damaged_normaliser_is_refused_at_export(run_and_export, tmp_path, capsys):
    run_dir, _ = run_and_export
    copy = tmp_path / "runs" / run_dir.name
    shutil.copytree(run_dir, copy)
    for record in copy.glob("checkpoints/*/sha256.json"):
        record.unlink()  # checkpoints written before the normaliser's sha256 was recorded: its statistics
    for pkl in copy.glob("checkpoints/*/vecnormalize.pkl"):
        data = pkl.read_bytes()
        mean = pickle.loads(data).obs_rms["observation"].mean
        damaged = mean.copy()
        damaged[3] = -4.9e307  # what a flipped exponent byte gives
        assert data.count(mean.tobytes()) == 1
        pkl.write_bytes(data.replace(mean.tobytes(), damaged.tobytes()))
    assert main(["export", str(copy), "--out", str(tmp_path / "export")]) == 2
    err = one_error_line(capsys)
    assert "vecnormalize.pkl: normaliser mean of 'observation' holds -4.9e+307" in err
    assert not (tmp_path / "export").exists()


def test_a_goal_not_finite_or_outside_the_workspace_and_a_log_folder_are_refused_before_connecting(
    run_and_export, tmp_path, capsys, monkeypatch
):
    _, export = run_and_export
    monkeypatch.chdir(tmp_path)
    assert main(["deploy", str(export), "--goal", "nan,0,0.3"]) == 2
    assert "is not finite" in one_error_line(capsys)
    assert main(["deploy", str(export), "--goal", "5,0,0.3"]) == 2
    assert "outside the contract's workspace" in one_error_line(capsys)
    folder = tmp_path / "logs"
    folder.mkdir()
    assert main(["deploy", str(export), "--log", str(folder)]) == 2
    assert "--log" in (err := one_error_line(capsys)) and "is a folder" in err
    # ur-rtde is absent here: had the log been checked after connecting, this would name ur-rtde
    assert (
        main(["deploy", str(export), "--backend", "ur", "--address", "192.0.2.1", "--log", str(folder)]) == 2
    )
    assert "is a folder" in one_error_line(capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["logs"] and not any(folder.iterdir())


def test_a_log_cut_anywhere_replays_its_complete_records_and_says_it_ends_early(
    run_and_export, tmp_path, capsys
):
    _, export = run_and_export
    log = tmp_path / "deploy.jsonl"
    assert main(["deploy", str(export), "--episodes", "2", "--log", str(log)]) == 0
    capsys.readouterr()
    lines = log.read_text().splitlines(keepends=True)
    assert (
        main(["deploy", "--replay", str(log), "--video-every", "50", "--video", str(tmp_path / "a.gif")]) == 0
    )
    assert "ends early" not in capsys.readouterr().out
    at_boundary = tmp_path / "boundary.jsonl"
    at_boundary.write_text("".join(lines[:70]))  # the second episode's start and some of its steps
    assert (
        main(
            [
                "deploy",
                "--replay",
                str(at_boundary),
                "--video-every",
                "50",
                "--video",
                str(tmp_path / "b.gif"),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "replayed 66 policy steps" in out and "episode 1 has no end record" in out
    mid_line = tmp_path / "mid.jsonl"
    mid_line.write_text("".join(lines[:40]) + lines[40][: len(lines[40]) // 2])
    assert (
        main(["deploy", "--replay", str(mid_line), "--video-every", "50", "--video", str(tmp_path / "c.gif")])
        == 0
    )
    out = capsys.readouterr().out
    assert "replayed 38 policy steps" in out and "last line (41) is cut short" in out
    assert "joint target 0 rad" in out
    broken = tmp_path / "broken.jsonl"
    broken.write_text("".join(lines[:10]) + "{not json\n" + "".join(lines[10:20]))
    assert main(["deploy", "--replay", str(broken)]) == 2
    assert "line 11 is not a JSON record" in one_error_line(capsys)
